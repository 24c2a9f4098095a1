"""Simulation as a falsifier for `rssmc verify` (docs/verify.md, "Simulation as a
falsifier"): seeded random runs of the interpreter, their devices' measurements drawn at
random from their types, and what a run ends in (a deadlock, an unsafe firing, a subsystem
stalled while the rest runs on, E809) confirmed in the flat net and reported as the
verifier's own counterexamples.

Modules: runs (one random run, its firing sequence recorded), confirm (a run's end confirmed
in the net: a deadlock, an unsafe firing, a loss of progress with its lasso), falsifier (the
runs, seed by seed, within a time slice), merge (the finding in the verifier's report),
orchestrate (the exhaustive engines and the runs under one budget, for the command).

This package sits beside ``rssm_dsl.interp`` and ``rssm_dsl.verify`` and imports both; they
import neither each other nor it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rssm_dsl.lazy import lazy_names

if TYPE_CHECKING:
    from rssm_dsl.falsify.falsifier import Falsification, FalsifyOptions, falsify
    from rssm_dsl.falsify.orchestrate import verify_with_simulation

__all__ = ["Falsification", "FalsifyOptions", "falsify", "verify_with_simulation"]
_MODULE = {"Falsification": "falsifier", "FalsifyOptions": "falsifier", "falsify": "falsifier",
           "verify_with_simulation": "orchestrate"}

__getattr__ = lazy_names(__name__, _MODULE)
