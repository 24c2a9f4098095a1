"""Drawings of the HPN: one SVG per page laid out by Graphviz (`svg`), and a self-contained
HTML explorer of the page hierarchy with token-game playback (`html`, `playback`)."""

# the firings of a trace the explorer plays at most (each embeds a marking, about 90 bytes
# for the LWR4+ example); here so that the CLI reads it without importing the renderer
MAX_STEPS = 20_000
