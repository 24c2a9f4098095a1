"""Behavioural verification of the flat HPN: invariants, state space, progress, cross-checks.

``verify(net, options) -> VerifyReport`` is the entry point; ``render_text`` / ``render_json``
print a report and ``exit_code`` maps its verdict to 0 (verified), 1 (violated) or 2
(inconclusive). SPIN (``promela``) and 4ti2 (``fourtitwo``) are independent cross-checks.
"""

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
    "Counterexample",
    "Verdict",
    "VerifyOptions",
    "VerifyReport",
    "exit_code",
    "render_json",
    "render_text",
    "step_text",
    "verify",
]
