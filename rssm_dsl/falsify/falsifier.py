"""The falsifier: seeded random runs of the interpreter, what they end in confirmed in the
net (confirm.py). Run ``r`` of seed ``s`` uses the interpreter's seed ``1000 * s + r`` (its
choices among the enabled transitions and its devices' draws), so the same seed gives the same
runs and the same counterexample; how many runs fit in the time given depends on the machine,
the first ones do not.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import field

from rssm_core.records import dataclass
from rssm_dsl.falsify.confirm import (
    Finding,
    NotConfirmed,
    confirm_deadlock,
    confirm_stall,
    confirm_unsafe,
)
from rssm_dsl.falsify.runs import RunOutcome, RunSetupError, random_run
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.pipeline import Compilation
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.netbits import NetBits

SEEDS_PER_SEED = 1000
MIN_RUN = 0.2          # seconds: a run may fire for this long at least


@dataclass(frozen=True)
class FalsifyOptions:
    seed: int = 0
    seconds: float = 2.0              # wall-clock time for the runs (the budget's deadline too)
    max_runs: int = 12
    steps_per_run: int = 1_000_000    # firings per run at most
    until: float = 60.0               # simulated seconds per run at most
    run_share: float = 1 / 2          # of ``seconds``: a run's wall-clock time at most
    check_progress: bool = True       # look for stalls (E809) too
    confirm_states: int = 50_000      # markings explored at most to confirm a stall
    confirm_seconds: float = 2.0      # ... and the time it may take
    device_options: dict[str, dict[str, str]] = field(default_factory=dict)


@dataclass(frozen=True)
class Falsification:
    """What the random runs did and found: a violation confirmed in the net (``finding``,
    from run ``found_by``), or none; what they saw that the net does not confirm."""

    seed: int
    runs: int = 0
    firings: int = 0
    seconds: float = 0.0
    finding: Finding | None = None
    found_by: RunOutcome | None = None
    unconfirmed: tuple[str, ...] = ()
    skipped: str | None = None        # why no run was made
    caveats: tuple[str, ...] = ()     # what the confirmation of the finding did not show

    def text(self) -> str:
        """One line: what the simulation did and found."""
        if self.skipped is not None:
            return f"not run ({self.skipped})"
        did = (f"{self.runs} random run(s) (seed {self.seed}), {self.firings:,} firings in "
               f"{self.seconds:.1f} s")
        if self.finding is None or self.found_by is None:
            return did + ": found nothing" + (
                f" ({len(self.unconfirmed)} stop(s) not confirmed in the net)"
                if self.unconfirmed else "")
        run = self.found_by
        what = {"deadlock": "a deadlock", "unsafe": "an unsafe firing",
                "progress": f"a loss of progress of {self.finding.subsystem}"}[self.finding.kind]
        return (f"{did}: found {what} (run seed {run.seed}, after {run.steps:,} firings, "
                f"t = {run.time:g} s simulated), confirmed in the net")


def run_seed(seed: int, run: int) -> int:
    return SEEDS_PER_SEED * seed + run


def _indices(net: FlatNet, out: RunOutcome) -> list[int]:
    """The run's firings as transition indices of ``net`` (by name, should the two
    flattenings ever number them differently)."""
    if len(out.names) == len(net.transitions) and all(
            t.name == n for t, n in zip(net.transitions, out.names, strict=True)):
        return list(out.sequence)
    index = {t.name: t.index for t in net.transitions}
    return [index[out.names[t]] for t in out.sequence]


def _confirm(nb: NetBits, out: RunOutcome, seq: Sequence[int], budget: Budget,
             options: FalsifyOptions, caveats: list[str]) -> Finding | None:
    """The violation the run ended in, confirmed; None when it ended in none."""
    if out.reason == "deadlock":
        return confirm_deadlock(nb, seq)
    if out.reason == "error" and "E807" in out.codes:
        return confirm_unsafe(nb, seq)
    if out.reason != "stalled" or not options.check_progress:
        return None
    why: list[str] = []
    for s in out.stalled:
        with budget.capped(options.confirm_seconds):
            try:
                finding, caveat = confirm_stall(nb, seq, s, budget, options.confirm_states)
            except NotConfirmed as e:
                why.append(str(e))
                continue
        if caveat is not None:
            caveats.append(caveat)
        return finding
    raise NotConfirmed("; ".join(why) or "no stalled subsystem named")


def falsify(comp: Compilation, net: FlatNet, budget: Budget,
            options: FalsifyOptions | None = None) -> Falsification:
    """Random runs for ``options.seconds`` at most from the first firing (and within the
    budget), until one ends in a violation confirmed in ``net``."""
    opts = options or FalsifyOptions()
    start = time.monotonic()
    first: list[float] = []         # when the first run began to fire (its set-up done)

    def deadline() -> float:
        """``seconds`` after the first run's set-up (which compiles the firing code once),
        and within the budget."""
        if not first:
            first.append(time.monotonic())
        end = first[0] + opts.seconds
        return end if budget.deadline is None else min(end, budget.deadline)

    nb = NetBits.of(net)
    runs, firings = 0, 0
    unconfirmed: list[str] = []
    caveats: list[str] = []

    def stop_requested() -> bool:
        return budget.cancelled

    def result(finding: Finding | None = None, by: RunOutcome | None = None,
               skipped: str | None = None) -> Falsification:
        return Falsification(opts.seed, runs, firings, time.monotonic() - start, finding, by,
                             tuple(unconfirmed), skipped, tuple(caveats))

    with budget.running("the random simulation"):
        for r in range(opts.max_runs):
            if ((first and time.monotonic() >= deadline()) or budget.cancelled
                    or budget.stop is not None):
                break
            try:
                out = random_run(comp, run_seed(opts.seed, r), opts.steps_per_run, opts.until,
                                 max(MIN_RUN, opts.run_share * opts.seconds), deadline,
                                 stop_requested, opts.device_options)
            except RunSetupError as e:
                return result(skipped=f"the specification cannot run: {e}")
            except Exception as e:     # a bug of the interpreter must not stop the proof
                return result(skipped=f"the interpreter failed: {type(e).__name__}: {e}")
            runs += 1
            firings += out.steps
            try:
                finding = _confirm(nb, out, _indices(net, out), budget, opts, caveats)
            except NotConfirmed as e:
                unconfirmed.append(f"run seed {out.seed} ({out.reason}: {out.message}): {e}")
                continue
            except LimitReached:
                break
            if finding is not None:
                return result(finding, out)
    return result()
