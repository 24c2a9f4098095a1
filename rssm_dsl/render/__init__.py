"""Drawings of the HPN: one SVG per page laid out by Graphviz (`svg`), and a self-contained
HTML explorer of the page hierarchy with token-game playback (`html`, `playback`) and the
series of a run drawn as charts (`series`)."""

# the firings of a trace the explorer embeds by default (a window of the trace; each is a
# transition index, about 4 bytes), and at most (--max-steps cannot go beyond it, so the page
# stays bounded for any trace); here so that the CLI reads them without importing the renderer
MAX_STEPS = 100_000
MAX_STEPS_LIMIT = 1_000_000
# every this many steps of the window the marking is embedded whole: the explorer seeks to a
# step by firing from the checkpoint before it (at most this many firings)
CHECKPOINT_EVERY = 500
