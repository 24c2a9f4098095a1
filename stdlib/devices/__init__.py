"""Scripted devices for simulations and tests (see rssm_dsl.interp.device for the interface):
`constant` (fixed measurements), `echo` (measurements repeat the last commands) and
`replay` (measurements read from a CSV file)."""
