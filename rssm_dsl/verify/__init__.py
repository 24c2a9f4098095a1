"""Behavioural verification of the flat HPN: invariants, state space, progress, cross-checks.

``verify(net, options) -> VerifyReport`` is the entry point; ``render_text`` / ``render_json``
print a report and ``exit_code`` maps its verdict to 0 (verified), 1 (violated), 3
(inconclusive) or 4 (verified without the progress check); ``VerifyReport.exit_code`` is 130
for a run interrupted by Ctrl-C. One ``Budget`` (``budget``: deadline, memory limit, Ctrl-C)
bounds a run. SPIN (``promela``) and 4ti2 (``fourtitwo``) are independent cross-checks.

The names are imported when first used, so that a module of the package (the interpreter
uses ``invariants``) can be imported without loading the whole verifier.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rssm_dsl.lazy import lazy_names

if TYPE_CHECKING:
    from rssm_dsl.verify.budget import Budget, LimitReached, Stop
    from rssm_dsl.verify.report import (
        Counterexample,
        Verdict,
        VerifyReport,
        exit_code,
        render_json,
        render_text,
        step_text,
    )
    from rssm_dsl.verify.verifier import VerifyOptions, verify

__all__ = [
    "Budget",
    "Counterexample",
    "LimitReached",
    "Stop",
    "Verdict",
    "VerifyOptions",
    "VerifyReport",
    "exit_code",
    "render_json",
    "render_text",
    "step_text",
    "verify",
]

_MODULES = {"Budget": "budget", "LimitReached": "budget", "Stop": "budget",
            "Counterexample": "report", "Verdict": "report", "VerifyReport": "report",
            "exit_code": "report", "render_json": "report", "render_text": "report",
            "step_text": "report", "VerifyOptions": "verifier", "verify": "verifier"}

__getattr__ = lazy_names(__name__, _MODULES)
