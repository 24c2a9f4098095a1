"""Drawings of the HPN: one SVG per page laid out by Graphviz (`svg`), and a self-contained
HTML explorer of the page hierarchy with token-game playback (`html`, `playback`)."""
