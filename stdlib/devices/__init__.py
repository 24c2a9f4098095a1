"""Scripted devices for simulations and tests (see rssm_dsl.interp.device for the interface):
`constant` (fixed measurements), `echo` (measurements repeat the last commands),
`replay` (measurements read from a CSV file) and `random_values` (measurements drawn at
random from their types, as `rssmc verify`'s random runs use them)."""
