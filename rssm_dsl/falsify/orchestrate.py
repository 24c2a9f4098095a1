"""`rssmc verify` with the random runs beside the exhaustive engines, under one budget:

1. the exhaustive engines first, for ``FIRST_TRY`` seconds at most (``SHARE`` of the time
   limit if that is less): most specifications are decided there, and then the random runs
   only check, for ``CHECK`` seconds, that they find nothing the engines proved impossible
   (a violation the engines found is reported as it is, without runs);
2. else the random runs, for ``SLICE`` seconds at most (``SHARE`` of the time limit if that is
   less). A violation they find and the net confirms is the verdict (VIOLATED with its
   counterexample); the exhaustive engines then run again for ``AFTER_FOUND`` seconds at
   most, for the rest of the picture (the shortest counterexamples, the other properties),
   and the properties they leave open ``PROPERTIES_AFTER`` seconds (half the time left at
   most) more;
3. else the exhaustive engines again, with the rest of the budget.

So a specification the engines decide in their first second costs ``CHECK`` seconds more,
one they do not decide at most ``FIRST_TRY + SLICE`` more (and the confirmation of what a run
found, ``FalsifyOptions.confirm_seconds`` at most), and a violation the runs find is reported
within ``FIRST_TRY + SLICE + AFTER_FOUND`` seconds and the confirmation.
"""

from __future__ import annotations

import dataclasses

from rssm_dsl.falsify.falsifier import FalsifyOptions, falsify
from rssm_dsl.falsify.merge import apply, not_run
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.pipeline import Compilation
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.report import Verdict, VerifyReport
from rssm_dsl.verify.verifier import properties_again

FIRST_TRY = 1.0       # seconds of the exhaustive engines before the random runs
SLICE = 1.0           # seconds of random runs when the first try decided nothing
CHECK = 0.25          # seconds of random runs after a proof (the consistency check)
AFTER_FOUND = 10.0    # seconds of the engines again once the runs found a violation
PROPERTIES_AFTER = 30.0   # ... and then of the properties they left open (half the time left)
SHARE = 0.05          # of the time limit, at most, for each of the above


def verify_with_simulation(net: FlatNet, comp: Compilation, options: VerifyOptions,
                           falsifier: FalsifyOptions | None = None) -> VerifyReport:
    """The verifier's report on ``net`` with what the random runs of ``comp`` found (see
    the module docstring); ``options.budget`` is the run's budget."""
    budget = options.budget
    assert budget is not None, "the command's budget"
    fopts = falsifier or FalsifyOptions()
    fopts = dataclasses.replace(fopts, check_progress=fopts.check_progress
                                and options.check_progress)
    limit = budget.time_limit

    def share(seconds: float) -> float:
        return seconds if limit is None else min(seconds, SHARE * limit)

    first_try = share(FIRST_TRY)
    with budget.capped(first_try) as cap:
        first = verify(net, options)
    if budget.stop is not None:
        return not_run(first, budget.stop.short, fopts.seed)
    if first.verdict is Verdict.VIOLATED:
        return not_run(first, "the exhaustive engines found a violation first", fopts.seed)
    if first.verdict is not Verdict.INCONCLUSIVE and not cap.hit:
        return apply(first, net, falsify(comp, net, budget, dataclasses.replace(
            fopts, seconds=share(CHECK))))
    found = falsify(comp, net, budget, dataclasses.replace(fopts, seconds=share(SLICE)))
    # The first try's whole-net exploration (``slice_after_seconds``, less than the try) did
    # not decide, or the try would have returned: the engines go on without it.
    again_options = dataclasses.replace(options, slice_after_seconds=0.0)
    if found.finding is None:
        if not cap.hit:     # the engines' own limits (--max-states) left it open
            return apply(first, net, found)
        return apply(verify(net, again_options), net, found)
    if not cap.hit:
        return apply(first, net, found)
    # a violation is known: the engines get AFTER_FOUND seconds more for the rest of the
    # picture (the shortest counterexamples, the other properties)
    with budget.capped(AFTER_FOUND) as again:
        second = verify(net, again_options)
    if again.hit and budget.stop is None:
        second = _cut(second, f"the {AFTER_FOUND:g} s the exhaustive engines were given once "
                              "the random runs had found a violation")
    if budget.stop is None and any(p.holds is None for p in second.user_properties):
        # the properties those seconds left open: a share of the time left, their own
        left = budget.run_remaining()
        with budget.capped(PROPERTIES_AFTER if left is None
                           else min(PROPERTIES_AFTER, left / 2)):
            second = properties_again(net, again_options, second)
    return apply(second, net, found)


def _cut(report: VerifyReport, given: str) -> VerifyReport:
    """A report of engines that the falsifier's schedule stopped (not the run's limits):
    that is why what they did not decide is not decided."""
    return dataclasses.replace(report, stop=None, why_undecided=f"not decided within {given}",
                               notes=tuple(f"within {given}: {n}" for n in report.notes))
