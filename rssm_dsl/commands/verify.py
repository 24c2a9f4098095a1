"""`rssmc verify`: safeness, deadlocks, progress and place invariants of the flattened HPN,
with counterexamples in the specification's words.

Exit codes: 0 verified (safe, deadlock-free, no loss of progress); 1 a property is violated;
2 usage error or a specification that does not compile; 3 inconclusive (a limit was reached,
or a property was not decided); 4 safe and deadlock-free, progress not checked
(--no-progress-check); 130 interrupted by Ctrl-C (the partial report is printed; 1 if a
violation was found before); 70 internal error.

Limits (``rssm_dsl.verify.budget``): one budget per run, from the command's start: the
deadline (``--timeout``), the memory limit (``--max-memory``, checked against the resident
size; ``RLIMIT_DATA`` a margin above it as a backstop) and Ctrl-C. Long loops check it and the
run ends within a second or two of a limit with the partial report. A watchdog
(``rssm_dsl.verify.watchdog``) makes the limits bind in the phases that do not check (the
compilation, the flattening): 2 s after a limit it interrupts the phase (the partial report
of ``rssm_dsl.verify.partial``), 2 s later it prints that report and ends the process.
Progress is shown on stderr once a run takes over 2 s, in every phase: one line refreshed on
a terminal, a line every 2 s with ``--progress`` elsewhere.
"""

from __future__ import annotations

import contextlib
import dataclasses
import gc
import math
import os
import signal
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Annotated, Any

import typer

from rssm_dsl.commands.common import (
    BAD_OPTION_VALUE,
    EXIT_INTERRUPTED,
    EXIT_USAGE,
    FileArg,
    Format,
    guarded,
    one_shot,
    report,
    usage_error,
)

if TYPE_CHECKING:
    from rssm_dsl.falsify import FalsifyOptions
    from rssm_dsl.verify.budget import Budget, Status, Stop
    from rssm_dsl.verify.watchdog import Watchdog

EXIT_BAD_INPUT = EXIT_USAGE         # a usage error or a specification that does not compile
EXIT_INCONCLUSIVE = 3               # = rssm_dsl.verify.report.EXIT_INCONCLUSIVE


def verify_cmd(
    file: FileArg,
    max_states: Annotated[int, typer.Option("--max-states", min=1,
                          help="Give up (inconclusive) after exploring this many states.")]
    = 5_000_000,
    timeout: Annotated[float, typer.Option("--timeout", min=0.1,
                       help="Stop (inconclusive) after this many seconds, counted from the "
                            "start of the command, in every phase (compilation included); "
                            "inf: no time limit.")] = 300.0,
    max_memory: Annotated[str | None, typer.Option(
        "--max-memory", metavar="SIZE",
        help="Stop (inconclusive) when the resident memory reaches SIZE: 8G, 500M, 40% (of "
             "the physical memory); a bare number is in GB. Default: 60% of the physical "
             "memory, at most 90% of what is available at the start.",
        show_default=False)] = None,
    format: Annotated[Format, typer.Option("--format", "-f", help="text or json")] = Format.text,
    reduction: Annotated[str, typer.Option(
        help="auto (full exploration; when it does not fit, each group of subsystems "
             "that wait on each other verified on its own and its violations replayed in "
             "the whole net; else the compositional check, then stubborn sets), off (full "
             "exploration of the whole net only), on (stubborn sets only), compositional "
             "(page by page, reduced modulo branching bisimulation)")]
    = "auto",
    invariants: Annotated[bool, typer.Option(help="Compute the minimal P-invariants.")] = True,
    progress_check: Annotated[bool, typer.Option("--progress-check/--no-progress-check",
                              help="Look for subsystems that can get stuck while the rest "
                                   "keeps running (off: exit 4 instead of 0).")] = True,
    fairness: Annotated[str, typer.Option(
        help="What progress assumes of the schedule: strong (a move possible infinitely "
             "often is taken; every engine) or weak (only a move enabled for good must be "
             "taken, so starvation by a schedule that passes over a move enabled now and "
             "then is reported; needs the full state space).")] = "strong",
    cross_check: Annotated[bool, typer.Option(
        "--cross-check", help="Also run SPIN (deadlock, safeness), 4ti2 (P-semiflows) and, on "
                              "small nets, cpncheck (the hierarchical .cpn) when installed, "
                              "and compare their verdicts with ours.")] = False,
    promela: Annotated[Path | None, typer.Option(help="Write the net as Promela to this file.")]
    = None,
    show_invariants: Annotated[bool, typer.Option(
        "--show-invariants", help="List every place invariant (in the specification's words).")]
    = False,
    progress: Annotated[bool, typer.Option(
        "--progress", help="Show progress on stderr (phase, states, states/s, memory) even "
                           "when stderr is not a terminal: a line every 2 s.")] = False,
    simulation: Annotated[bool, typer.Option(
        "--simulation/--no-simulation",
        help="Seeded random runs of the interpreter beside the exhaustive engines (device "
             "values drawn at random): a deadlock or stall they find, confirmed in the net, "
             "is reported as a violation with its trace.")] = True,
    seed: Annotated[int, typer.Option("--seed", help="Seed of the random runs.")] = 0,
    device_option: Annotated[list[str] | None, typer.Option(
        "--device-option", help="ID:values=JSON: the values a device's outputs are drawn from "
                                "in the random runs, e.g. 'arm.R.cam:values={\"ok\": [true, "
                                "false]}' (repeatable; ID may be a pattern).")] = None,
) -> None:
    """Prove the system's HPN safe and deadlock-free (and that no subsystem loses progress),
    or print a counterexample as a firing sequence of your behaviours and channels.

    It stops within a few seconds of --timeout, --max-memory or Ctrl-C, in any phase
    (compilation included), with what was proved.

    Exit codes:
      0    verified: safe, deadlock-free, no loss of progress
      1    a property is violated (counterexample printed)
      2    usage error, or the specification does not compile
      3    inconclusive: a limit was reached, or a property was not decided
      4    safe and deadlock-free, progress not checked (--no-progress-check)
      130  interrupted by Ctrl-C: partial report (1 if a violation was found)
      70   internal error
    """
    started = time.monotonic()

    def run() -> int:
        from rssm_dsl.diagnostics.diagnostic import bound_text
        from rssm_dsl.verify.budget import Budget, default_max_memory, parse_size
        from rssm_dsl.verify.watchdog import Watchdog

        # no teardown at exit: freeing a large spec's objects one by one takes seconds after
        # the report (10 s for synth.lean_ring_system(2000) stopped in the flattening);
        # the engines make cyclic garbage, so the collector stays on
        one_shot(collector=True)

        if reduction not in ("auto", "on", "off", "compositional"):
            return usage_error(f"--reduction must be auto, on, off or compositional, not "
                               f"{reduction!r}", "leave it out for auto (docs/verify.md, "
                               "\"How: --reduction\")")
        if fairness not in ("strong", "weak"):
            return usage_error(f"--fairness must be strong or weak, not "
                               f"{fairness!r}",
                               "leave it out for strong fairness (docs/verify.md)")
        if math.isnan(timeout):     # rssm_dsl.cli reads the options: only when called directly
            typer.echo(f"rssmc: error[{BAD_OPTION_VALUE}]: --timeout nan: give a number of "
                       "seconds (at least 0.1), or inf for no time limit", err=True)
            return EXIT_BAD_INPUT
        falsifier = _falsifier(simulation, seed, device_option or [])
        if isinstance(falsifier, str):
            typer.echo(falsifier, err=True)
            return EXIT_BAD_INPUT
        try:
            if max_memory is not None and ("_" in max_memory or not max_memory.isascii()):
                raise ValueError("not a number with an optional unit (K, M, G, T) or %")
            memory = parse_size(max_memory) if max_memory is not None else default_max_memory()
        except ValueError as e:
            typer.echo(f"rssmc: error[{BAD_OPTION_VALUE}]: --max-memory "
                       f"{bound_text(repr(max_memory))}: {e}", err=True)
            return EXIT_BAD_INPUT
        tty = sys.stderr.isatty()
        live = _Live(tty) if tty or progress else None
        budget = Budget(None if math.isinf(timeout) else timeout, memory, start=started,
                        on_status=live)
        spec: list[Any] = []        # the system once compiled: its properties, if stopped
        watch = Watchdog(budget, _give_up(budget, live, file, format, progress_check, spec))
        try:
            with _limited(budget), watch:
                code = _verify(budget, watch, live, file, format, reduction, max_states,
                               invariants, progress_check, cross_check, promela,
                               show_invariants, fairness, falsifier, spec)
        except KeyboardInterrupt:               # a second Ctrl-C: quit at once
            code = EXIT_INTERRUPTED
            typer.echo("rssmc: interrupted", err=True)
        except MemoryError:
            stop = budget.out_of_memory()
            typer.echo(f"rssmc: {stop.message}", err=True)
            code = EXIT_INTERRUPTED if stop.kind == "interrupt" else EXIT_INCONCLUSIVE
        finally:
            if live is not None:
                live.clear()
        return code

    guarded(run)


def _verify(budget: Budget, watch: Watchdog, live: _Live | None, file: Path, format: Format,
            reduction: str, max_states: int, invariants: bool, progress_check: bool,
            cross_check: bool, promela: Path | None, show_invariants: bool,
            fairness: str = "strong", falsifier: FalsifyOptions | None = None,
            spec: list[Any] | None = None) -> int:
    """Compile, verify, print; the exit code. Every phase runs named in the budget, under
    the watchdog: a limit ends any of them (``_stopped``: the partial report, with the
    properties of the system ``spec`` receives once compiled)."""
    from rssm_dsl.hpn.flatten import flatten
    from rssm_dsl.pipeline import compile_file
    from rssm_dsl.verify import VerifyOptions, render_text, verify
    from rssm_dsl.verify.budget import LimitReached
    from rssm_dsl.verify.dataplan import value_plan
    from rssm_dsl.verify.report import Verdict

    system = file.stem
    try:
        with _collector_paused():
            with budget.running("the compilation"):
                comp = compile_file(file)
            if not comp.ok or comp.hpn is None:
                watch.finish()
                report(comp, format)
                return EXIT_BAD_INPUT
            unknown = _unknown_device_option(comp, falsifier)
            if unknown is not None:     # as `rssmc simulate` says it
                watch.finish()
                typer.echo(unknown, err=True)
                return EXIT_BAD_INPUT
            if spec is not None and comp.system is not None:
                spec.append(comp.system)
            budget.check()          # a limit reached while compiling: no further phase
            with budget.running("the flattening"):
                net = flatten(comp.hpn)
            system = net.system
            budget.check()
            with budget.running("the value plan"):
                values = value_plan(comp, net)
        if promela is not None:
            from rssm_dsl.emit.write import write_outputs
            from rssm_dsl.verify.promela import to_promela

            with budget.running("the Promela export"):
                write_outputs(promela.parent if str(promela.parent) else Path("."),
                              {promela.name: to_promela(net, values)})
        options = VerifyOptions(max_states=max_states, reduction=reduction,
                                invariants=invariants, check_progress=progress_check,
                                budget=budget, values=values, fairness=fairness)
        with budget.running("the verification"):
            if falsifier is None:
                result = verify(net, options)
            else:
                from rssm_dsl.falsify import verify_with_simulation

                result = verify_with_simulation(net, comp, options, falsifier)
        extra: dict[str, Any] = {}
        text_extra: list[str] = []
        if cross_check:
            try:
                with budget.running("the cross-checks"):
                    extra, text_extra = _cross_check(net, result, comp.hpn, budget, values)
            except LimitReached as e:   # the watchdog stopped one: the verdict stands
                watch.finish()
                extra = {"stopped": e.stop.message}
                text_extra = ["", f"independent cross-checks: stopped ({e.stop.message})"]
        watch.finish()      # the verdict is in: the report is written whatever the clock says
    except (LimitReached, MemoryError) as e:
        watch.finish()
        stop = e.stop if isinstance(e, LimitReached) else budget.out_of_memory()
        return _stopped(budget, live, stop, watch.interrupted, system, file, format,
                        progress_check, spec)
    if live is not None:
        live.clear()
    # the peak of the whole run: the properties, the falsifier and the cross-checks came
    # after the engines' report was made
    result = dataclasses.replace(result, peak_memory=max(result.peak_memory,
                                                         budget.peak_resident()))
    if format is Format.json:
        import json

        data = result.to_json()
        if extra:
            data["cross_check"] = extra
        typer.echo(json.dumps(data, indent=2, ensure_ascii=False))
    else:
        typer.echo(render_text(result, max_invariants=10_000 if show_invariants else 0))
        for line in text_extra:
            typer.echo(line)
    # Ctrl-C during the cross-checks: the run was interrupted all the same
    if (budget.stop is not None and budget.stop.kind == "interrupt"
            and result.verdict is not Verdict.VIOLATED):
        return EXIT_INTERRUPTED
    return int(result.exit_code)


def _not_decided(spec: list[Any] | None, stop: Stop) -> tuple[Any, ...]:
    """The properties of the compiled system (``spec``), each not decided by ``stop``."""
    if not spec:
        return ()
    from rssm_dsl.verify.userprops import not_decided

    return not_decided(spec[0], stop.message)


def _stopped(budget: Budget, live: _Live | None, stop: Stop, interrupted: str | None,
             system: str, file: Path, format: Format, progress_check: bool,
             spec: list[Any] | None = None) -> int:
    """A limit stopped a phase that does not return a report (the front end), or the
    watchdog interrupted one: the partial report of what was done (every property not
    decided); its exit code."""
    from rssm_dsl.verify.partial import PartialReport

    partial = PartialReport.of(budget, stop, system, str(file), interrupted, progress_check,
                               _not_decided(spec, stop))
    if live is not None:
        live.clear()
    typer.echo(partial.render(format is Format.json), nl=False)
    return partial.exit_code


def _give_up(budget: Budget, live: _Live | None, file: Path, format: Format,
             progress_check: bool, spec: list[Any] | None = None,
             ) -> Callable[[Stop, str], None]:
    """What the watchdog does when the main thread does not return after a limit (it is
    inside C code): print the partial report straight to the file descriptors and end the
    process with its exit code, without the interpreter's teardown."""
    from rssm_dsl.verify.partial import PartialReport

    def give_up(stop: Stop, phase: str) -> None:
        partial = PartialReport.of(budget, stop, file.stem, str(file), phase, progress_check,
                                   _not_decided(spec, stop))
        text = partial.render(format is Format.json)
        with contextlib.suppress(OSError, ValueError):
            sys.stdout.flush()
        clear = "\r\x1b[K" if live is not None and live.shown else ""
        _write_all(2, f"{clear}rssmc: {phase} did not stop within "
                      f"{time.monotonic() - budget.start - stop.at:.1f} s of the limit; "
                      "ending the process\n")
        _write_all(1, text)
        os._exit(partial.exit_code)

    return give_up


def _write_all(fd: int, text: str) -> None:
    data = text.encode("utf-8", errors="replace")
    with contextlib.suppress(OSError):
        while data:
            data = data[os.write(fd, data):]


def _unknown_device_option(comp: Any, falsifier: FalsifyOptions | None) -> str | None:
    """The usage error for a --device-option that names no device of the system."""
    if falsifier is None or not falsifier.device_options:
        return None
    from rssm_dsl.commands.simulate import _unknown_device

    return _unknown_device(comp.system, list(falsifier.device_options))


def _falsifier(on: bool, seed: int, device_options: list[str]) -> FalsifyOptions | str | None:
    """The random runs' options (None: --no-simulation), or the usage error."""
    if not on:
        return None
    from rssm_dsl.commands.simulate import _device_options
    from rssm_dsl.falsify import FalsifyOptions

    try:
        return FalsifyOptions(seed=seed, device_options=_device_options(device_options))
    except typer.BadParameter as e:
        return f"rssmc: --device-option: {e.message}"


@contextlib.contextmanager
def _collector_paused() -> Iterator[None]:
    """The front end (compilation, flattening, value plan) without the cyclic garbage
    collector, and what it built frozen afterwards (``gc.freeze``): it lives until the
    command ends, and every full collection would scan it again. On a large spec such a
    collection holds the GIL for seconds (7 s on the flattening of
    ``synth.lean_ring_system(2000)`` on a loaded machine), when neither the watchdog's
    thread nor its exception can run. The objects are unfrozen when the command ends."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()
        if enabled:
            gc.enable()


@contextlib.contextmanager
def _limited(budget: Budget) -> Iterator[None]:
    """Ctrl-C asks the budget to stop (a second one quits at once) and the data segment is
    capped a margin above the memory limit; both undone on the way out."""
    from rssm_dsl.verify.budget import limit_data_segment

    def interrupted(signum: int, frame: FrameType | None) -> None:
        if budget.cancelled:
            raise KeyboardInterrupt
        budget.cancel()
        os.write(2, b"\nrssmc: interrupted: stopping at the next check to print what was "
                    b"proved (Ctrl-C again to quit at once)\n")

    old_handler: Any = None
    try:
        if signal.getsignal(signal.SIGINT) is not signal.SIG_IGN:   # e.g. nohup: keep it
            old_handler = signal.signal(signal.SIGINT, interrupted)
    except ValueError:                  # not the main thread: no handler
        pass
    restore = (limit_data_segment(budget.max_memory) if budget.max_memory is not None
               else None)
    try:
        yield
    finally:
        gc.unfreeze()           # what _collector_paused froze
        if restore is not None:
            restore()
        if old_handler is not None:
            signal.signal(signal.SIGINT, old_handler)


class _Live:
    """The progress line on stderr, from the budget's status reports (the phases' own and
    the watchdog's): nothing in the first 2 s; then on a terminal one line refreshed in
    place, elsewhere a line every ``EVERY`` seconds."""

    EVERY = 2.0

    def __init__(self, tty: bool) -> None:
        self.tty = tty
        self.shown = False
        self.last = -1e9

    def __call__(self, status: Status) -> None:
        from rssm_dsl.verify.budget import format_size

        if status.elapsed < 2.0 or (not self.tty and status.elapsed - self.last < self.EVERY):
            return
        self.last = status.elapsed
        states = (f", {status.states:,} states ({status.rate:,.0f}/s)" if status.states
                  else "")
        text = (f"rssmc verify: {status.elapsed:.0f} s, {status.phase}{states}, "
                f"{format_size(status.resident)} resident")
        if self.tty:
            sys.stderr.write("\r" + text + "\x1b[K")
            self.shown = True
        else:
            sys.stderr.write(text + "\n")
        sys.stderr.flush()

    def clear(self) -> None:
        if self.shown:
            sys.stderr.write("\r\x1b[K")
            sys.stderr.flush()
            self.shown = False


CPNCHECK_MAX_STATES = 5_000


def _cross_check(net: Any, result: Any, hpn: Any = None, budget: Budget | None = None,
                 values: Any = None) -> tuple[dict[str, Any], list[str]]:
    """SPIN and 4ti2 on the same flat net, cpncheck on the unflattened HPN (small nets
    only); their answers beside ours. Each runs under the run's budget (killed at its
    deadline, its memory counted), and not at all once a limit was reached."""
    out: dict[str, Any] = {}
    lines = ["", "independent cross-checks:"]
    for name, check in (("SPIN", _spin), ("SPIN on the slices", _spin_slices),
                        ("SPIN on the progress lassos", _spin_lassos),
                        ("4ti2", _fourtitwo), ("cpncheck", _cpncheck)):
        if budget is not None and budget.stop is not None:
            line, data = f": not run ({budget.stop.message})", {"ran": False,
                                                               "message": budget.stop.message}
        else:
            line, data = check(net, result, hpn, budget, values)
        lines.append(f"  {name}{line}")
        out[name.lower().replace(" ", "_")] = data
    return out, lines


def _spin(net: Any, result: Any, hpn: Any, budget: Budget | None, values: Any = None,
          ) -> tuple[str, dict[str, Any]]:
    from rssm_dsl.verify.promela import run_spin

    spin = run_spin(net, separate=True, budget=budget, values=values)     # stopped at the run's deadline
    if not spin.available or not spin.ran:
        return f": not run ({spin.message})", {"ran": False, "message": spin.message}
    # a violation SPIN found is definite; "none found" only counts after a complete search
    found = bool(spin.deadlock or spin.unsafe)
    agree = (spin.deadlock == (result.deadlock_free is False)
             and spin.unsafe == (result.safe is False)) if spin.complete or found else None
    word = {True: "agrees", False: "DISAGREES", None: "incomplete search"}[agree]
    return (f": deadlock={spin.deadlock} unsafe={spin.unsafe}, {spin.states_stored:,} states "
            f"in {spin.total_seconds:.2f} s: {word}",
            {"ran": True, "deadlock": spin.deadlock, "unsafe": spin.unsafe,
             "states": spin.states_stored, "complete": spin.complete,
             "seconds": round(spin.total_seconds, 3), "agrees": agree})


def _spin_slices(net: Any, result: Any, hpn: Any, budget: Budget | None, values: Any = None,
                 ) -> tuple[str, dict[str, Any]]:
    """SPIN on each blocking group's slice (verify/slicing.py): a reachable deadlock of
    the slice (its group stuck for good) against ours."""
    from rssm_dsl.verify.promela import run_spin
    from rssm_dsl.verify.slicing import slice_net

    if not result.groups:
        why = "the verification was not sliced"
        return f": not run ({why})", {"ran": False, "message": why}
    rows = []
    for group, stuck in result.groups:
        spin = run_spin(slice_net(net, group).net, budget=budget, values=values)
        decided = spin.ran and (spin.complete or bool(spin.deadlock))
        agree = (spin.deadlock == stuck) if decided and stuck is not None else None
        rows.append({"subsystems": list(group), "ours": stuck,
                     "spin": spin.deadlock if decided else None, "agrees": agree,
                     "states": spin.states_stored})
    counts = {word: sum(1 for r in rows if r["agrees"] is value)
              for word, value in (("agree", True), ("DISAGREE", False), ("undecided", None))}
    text = ", ".join(f"{n} {word}" for word, n in counts.items() if n)
    return (f": {len(rows)} slice(s), stuck or not: {text}",
            {"ran": True, "slices": rows, "agrees": counts["DISAGREE"] == 0})


def _spin_lassos(net: Any, result: Any, hpn: Any, budget: Budget | None, values: Any = None,
                 ) -> tuple[str, dict[str, Any]]:
    """SPIN from each loss of progress's point of no return: no iteration of the subsystem
    and no deadlock reachable from there (promela.check_lasso)."""
    from rssm_dsl.verify.promela import check_lasso

    lassos = [c for c in result.progress if c.subsystem is not None]
    if not lassos:
        why = "no loss of progress with a firing sequence to check"
        return f": not run ({why})", {"ran": False, "message": why}
    rows = []
    for c in lassos:
        check = check_lasso(net, c.steps, c.subsystem, values, budget=budget)
        rows.append({"subsystem": c.subsystem, "confirmed": check.confirmed,
                     "iterates": check.iterates, "deadlock": check.deadlock,
                     "states": check.states, "message": check.message})
    counts = {word: sum(1 for r in rows if r["confirmed"] is value)
              for word, value in (("confirmed", True), ("REFUTED", False),
                                  ("undecided", None))}
    text = ", ".join(f"{n} {word}" for word, n in counts.items() if n)
    return (f": {len(rows)} lasso(s) from their point of no return: {text}",
            {"ran": True, "lassos": rows, "agrees": counts["REFUTED"] == 0})


def _fourtitwo(net: Any, result: Any, hpn: Any, budget: Budget | None, values: Any = None,
               ) -> tuple[str, dict[str, Any]]:
    from rssm_dsl.verify.fourtitwo import semiflows_4ti2

    fti = semiflows_4ti2(net, budget=budget, values=values)
    if not fti.available or not fti.message.endswith("P-semiflows"):   # missing, failed
        return f": not run ({fti.message})", {"ran": False, "message": fti.message}
    return (f": {len(fti.semiflows)} minimal P-semiflows (ours: {len(result.invariants)}) in "
            f"{fti.seconds:.2f} s",
            {"ran": True, "semiflows": len(fti.semiflows), "ours": len(result.invariants),
             "seconds": round(fti.seconds, 3)})


def _cpncheck(net: Any, result: Any, hpn: Any, budget: Budget | None, values: Any = None,
              ) -> tuple[str, dict[str, Any]]:
    """cpncheck expands the hierarchy of the .cpn export itself: it confirms our flattening
    (on nets under CPNCHECK_MAX_STATES states, so it needs no budget)."""
    if result.tracked_values:
        why = "values are tracked (cpncheck explores them as free choices)"
        return f": not run ({why})", {"ran": False, "message": why}
    if hpn is None or result.method != "full" or not result.complete:
        why = "no full exploration of ours to compare with" if hpn is not None else "no HPN"
        return f": not run ({why})", {"ran": False, "message": why}
    if result.states >= CPNCHECK_MAX_STATES:
        return (f": not run (too large: {result.states:,} states, limit "
                f"{CPNCHECK_MAX_STATES:,})", {"ran": False, "message": "too large"})
    from rssm_dsl.verify.cpncheck_oracle import run_cpncheck

    cpn = run_cpncheck(hpn, max_states=2 * CPNCHECK_MAX_STATES)
    if not cpn.ran:
        return f": not run ({cpn.message})", {"ran": False, "message": cpn.message}
    agree = (cpn.complete and cpn.states == result.states
             and cpn.deadlock_free == result.deadlock_free
             and cpn.unsafe == (result.safe is False))
    return (f" (hierarchical .cpn): {cpn.states:,} states, {cpn.deadlocks} deadlock(s), "
            f"unsafe={cpn.unsafe} in {cpn.seconds:.2f} s: {'agrees' if agree else 'DISAGREES'}",
            {"ran": True, "states": cpn.states, "deadlocks": cpn.deadlocks,
             "unsafe": cpn.unsafe, "complete": cpn.complete,
             "seconds": round(cpn.seconds, 3), "agrees": agree})


def register(app: typer.Typer) -> None:
    app.command("verify")(verify_cmd)
