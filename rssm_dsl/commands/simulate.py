"""`rssmc simulate`: run the system's HPN with its operations (docs/simulate.md)."""

from __future__ import annotations

import contextlib
import json
import sys
from fnmatch import fnmatchcase
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from rssm_dsl.commands.common import (
    EXIT_ERRORS,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_STUCK,
    EXIT_USAGE,
    FileArg,
    Format,
    guarded,
    output_file_problem,
    report,
    usage_error,
)
from rssm_dsl.interp.watchdog import STALL_PERIODS

DEFAULT_UNTIL = 60.0    # seconds: the bound of a run given none (a system may never end)

if TYPE_CHECKING:
    from collections.abc import Callable

    from rssm_dsl.diagnostics import Diagnostic
    from rssm_dsl.hpn.flat import FlatNet
    from rssm_dsl.interp import RunConfig
    from rssm_dsl.interp.program import Runtime
    from rssm_dsl.interp.replay import (
        Counterexample,
        PropertyWatch,
        ReplayVerdict,
        ValueChoices,
    )
    from rssm_dsl.interp.sampler import Sampler
    from rssm_dsl.interp.scheduler import RunResult
    from rssm_dsl.interp.summary import Snapshot
    from rssm_dsl.pipeline import Compilation
    from rssm_dsl.semantics.model import System




def _quoted(text: str) -> str:
    """A user's option value in a message: quoted, control characters escaped, cut short."""
    from rssm_dsl.diagnostics.diagnostic import bound_text

    return f"'{bound_text(text)}'"


def _pairs(values: list[str], what: str, sep: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for v in values:
        key, ok, value = v.partition(sep)
        if not ok or not key.strip() or not value.strip():
            raise typer.BadParameter(f"{_quoted(v)} is not {what}")
        out[key.strip()] = value.strip()
    return out


def _device_options(values: list[str]) -> dict[str, dict[str, str]]:
    out: dict[str, dict[str, str]] = {}
    for v in values:
        target, ok, setting = v.partition(":")
        key, ok2, value = setting.partition("=")
        if not (ok and ok2 and target and key):
            raise typer.BadParameter(f"{_quoted(v)} is not ID:KEY=VALUE (e.g. "
                                     "a1.R.cam:file=cam.csv)")
        out.setdefault(target.strip(), {})[key.strip()] = value
    return out


class _Live:
    """Redraws the summary in place on a terminal (stderr)."""

    def __init__(self) -> None:
        self.lines = 0

    def __call__(self, snap: Snapshot) -> None:
        from rssm_dsl.interp.summary import render

        text = render(snap)
        up = f"\x1b[{self.lines}F\x1b[J" if self.lines else ""
        sys.stderr.write(up + text + "\n")
        sys.stderr.flush()
        self.lines = text.count("\n") + 1

    def clear(self) -> None:
        if self.lines:
            sys.stderr.write(f"\x1b[{self.lines}F\x1b[J")
            sys.stderr.flush()
            self.lines = 0


class _Preparing:
    """The live line before the run: what is being prepared (compiling, building the
    interpreter) and for how long, shown from FIRST_AFTER seconds on and redrawn in place
    until the run's own summary (``_Live``) takes over; nothing on a quick start."""

    FIRST_AFTER = 1.0
    EVERY = 0.5

    def __init__(self) -> None:
        import threading

        self.phase = "compiling"
        self.shown = False
        self._start = 0.0
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._tick, name="rssmc-preparing", daemon=True)

    def __enter__(self) -> _Preparing:
        import time

        self._start = time.monotonic()
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._done.set()
        self._thread.join()
        with self._lock:
            if self.shown:
                sys.stderr.write("\r\x1b[K")
                sys.stderr.flush()

    def _tick(self) -> None:
        import time

        if self._done.wait(self.FIRST_AFTER):
            return
        while True:
            with self._lock:
                if self._done.is_set():
                    return
                sys.stderr.write(f"\rrssmc simulate: {self.phase} "
                                 f"({time.monotonic() - self._start:.0f} s)\x1b[K")
                sys.stderr.flush()
                self.shown = True
            if self._done.wait(self.EVERY):
                return


def simulate(
    file: FileArg,
    steps: Annotated[int | None, typer.Option("--steps", min=0,
                     help="Stop after this many transition firings.")] = None,
    until: Annotated[float | None, typer.Option("--until", min=0.0,
                     help="Stop at this time (seconds; simulated, or wall-clock in "
                          "concurrent mode).")] = None,
    mode: Annotated[str, typer.Option(
        "--mode", help="deterministic (seeded, simulated time) or concurrent (operations in "
                       "worker threads, wall-clock pacing).")] = "deterministic",
    seed: Annotated[int, typer.Option(help="Seed of the choice among enabled transitions.")] = 0,
    trace: Annotated[Path | None, typer.Option("--trace",
                     help="Write the trace (JSON lines) to this file.")] = None,
    replay: Annotated[Path | None, typer.Option(
        "--replay", help="Replay a counterexample of `rssmc verify` (JSON) or a trace, "
                         "forcing its firings.")] = None,
    device: Annotated[list[str] | None, typer.Option(
        "--device", help="Bind a device to a class: ID=module:Class (repeatable; ID may be a "
                         "pattern such as '*.E.*'), e.g. "
                         "a1.E.lwr=rssm_stdlib.devices.constant:ConstantDevice.")] = None,
    device_option: Annotated[list[str] | None, typer.Option(
        "--device-option", help="An option of a device: ID:KEY=VALUE (repeatable; ID may be "
                                "a pattern).")] = None,
    workers: Annotated[int, typer.Option(min=1, help="Worker threads (concurrent mode).")] = 4,
    select: Annotated[list[str] | None, typer.Option(
        "--select", help="A series to record for --series/--plot: SUBSYSTEM.VARIABLE (a "
                         "memory variable, parameter or buffer; .field and [k] for a "
                         "component) or SUBSYSTEM.behaviour; shell patterns allowed; "
                         "repeatable. Default: every behaviour and numeric memory "
                         "variable.")] = None,
    series: Annotated[Path | None, typer.Option(
        "--series", help="Write the selected series to this .npz file (rssmc plot draws "
                         "it).")] = None,
    plot: Annotated[Path | None, typer.Option(
        "--plot", help="Draw the selected series against time to this .png or .svg "
                       "(needs the 'run' extra).")] = None,
    stall_periods: Annotated[int, typer.Option(
        "--stall-periods", min=0,
        help="Stop (E809, exit 3) when a subsystem completes no iteration for this many "
             "periods of the slowest paced subsystem or device while the rest runs on (at "
             "least 2: the slowest completes an iteration at its next tick); 0: "
             "never.")] = STALL_PERIODS,
    all_interleavings: Annotated[bool, typer.Option(
        "--all-interleavings", help="Deterministic mode: let the seeded choice pick among "
                                    "every enabled transition, local steps included "
                                    "(slower; see docs/simulate.md).")] = False,
    live: Annotated[bool | None, typer.Option(
        "--live/--no-live", help="Redraw the summary while running (default: on a "
                                 "terminal).")] = None,
    format: Annotated[Format, typer.Option("--format", "-f",
                      help="How to print diagnostics and the result.")] = Format.text,
    quiet: Annotated[bool, typer.Option("--quiet", "-q",
                     help="Print only problems.")] = False,
) -> None:
    """Execute the system's HPN: tokens move as the paper's scheduler moves them, behaviours
    switch on their conditions, data flows through the buffers. Prints a summary at the end.
    Without --until, --steps or --replay the run stops at t = 60 s at the latest.
    Exit 0 when the run stops normally, 1 on errors or a reproduced counterexample, 2 on
    usage errors, 3 when the run cannot go on: a deadlock (E805) or a subsystem stalled
    while the rest runs (E809), 130 on Ctrl-C."""

    def run() -> int:
        if mode not in ("deterministic", "concurrent"):
            return usage_error(f"--mode must be deterministic or concurrent, not "
                               f"{mode}", "leave it out for deterministic")
        try:
            devices = _pairs(device or [], "ID=module:Class", "=")
            options = _device_options(device_option or [])
        except typer.BadParameter as e:
            return usage_error(e.message, "'rssmc simulate --help' shows the form of "
                               "--device and --device-option")
        if plot is not None:
            from rssm_dsl.extras import missing_message

            absent = missing_message("rssmc simulate --plot", "run")
            if absent is not None:
                typer.echo(absent, err=True)
                return EXIT_USAGE
            if plot.suffix.lower() not in (".png", ".svg"):
                return usage_error(f"--plot {plot}: the figure is written "
                                   "as .png or .svg", "name the file NAME.png or NAME.svg")
        if stall_periods == 1:
            # the slowest paced subsystem completes each iteration at its next tick, when the
            # watch looks too: one period cannot tell a stall from its rhythm
            typer.echo("rssmc: error[E890]: --stall-periods 1: give 0 (never stop) or 2 or "
                       "more periods", err=True)
            typer.echo("  help: a subsystem at the slowest rate completes an iteration only at "
                       "its next tick, so one period would see every such subsystem stalled",
                       err=True)
            return EXIT_USAGE
        for path, option in ((trace, "--trace"), (series, "--series"), (plot, "--plot")):
            if path is not None and output_file_problem(path, option, (file,)):
                return EXIT_USAGE
        return _simulate(file, steps, until, mode, seed, trace, replay, devices, options,
                         workers, live, format, quiet, not all_interleavings, stall_periods,
                         _Record(select, series, plot))

    guarded(run)


def _simulate(file: Path, steps: int | None, until: float | None, mode: str, seed: int,
              trace: Path | None, replay: Path | None, devices: dict[str, str],
              options: dict[str, dict[str, str]], workers: int, live: bool | None,
              fmt: Format, quiet: bool, eager: bool = True,
              stall_periods: int = STALL_PERIODS, record: _Record | None = None) -> int:
    from rssm_dsl.interp import RunConfig, SimOptions, Simulator
    from rssm_dsl.interp.replay import ValueChoices, chain, judge
    from rssm_dsl.interp.trace import TraceWriter

    show_live = (sys.stderr.isatty() if live is None else live) and not quiet \
        and fmt is Format.text
    comp, rt = _prepare(file, lambda: RunConfig(
        base_dir=file.resolve().parent, devices=devices, device_options=options,
        wall_clock=mode == "concurrent"), show_live)
    if not comp.ok or comp.system is None:
        report(comp, fmt)
        return EXIT_ERRORS
    if comp.diagnostics and fmt is Format.text and not quiet:
        report(comp, fmt)
    unknown = _unknown_device(comp.system, [*devices, *options])
    if unknown is not None:
        typer.echo(unknown, err=True)
        return EXIT_USAGE
    if isinstance(rt, _SetupFailed):
        rt.show(comp, fmt)
        return EXIT_ERRORS
    assert rt is not None

    cx, forced, watch = None, None, None
    values: ValueChoices | None = None
    if replay is not None:
        loaded = _load_replay(comp, rt, replay, mode, fmt)
        if isinstance(loaded, int):
            rt.close_devices()
            return loaded
        cx, forced, watch = loaded
        values = ValueChoices(rt, cx) if cx.values else None

    sampler = record.attach(rt) if record is not None else None
    if isinstance(sampler, str):
        typer.echo(sampler, err=True)
        rt.close_devices()
        return EXIT_USAGE
    tracer = TraceWriter(trace) if trace is not None else None
    rt.tracer = tracer
    painter = _Live() if show_live else None
    bounded = steps is not None or until is not None or replay is not None
    if not bounded:
        until = DEFAULT_UNTIL
    opts = SimOptions(mode=mode, seed=seed, max_steps=steps, until=until, workers=workers,
                      stall_periods=stall_periods,
                      forced=forced, record_markings=cx is not None and cx.kind == "progress",
                      progress=painter, eager=eager,
                      observe=chain(values.observe if values is not None else None,
                                    watch.observe if watch is not None else None),
                      trace_info={"spec": str(file),
                                  "replay": str(replay) if replay is not None else None})
    sim = Simulator(rt, opts)
    if watch is not None:
        watch.chosen = values
        watch.attach(sim)
    try:
        result = sim.run()
    finally:
        if painter is not None:
            painter.clear()
        if tracer is not None:
            tracer.close()

    verdict = judge(cx, forced or [], result, sim, watch, values) if cx is not None else None
    diags = list(result.diagnostics)
    if verdict is not None:
        diags = [d for d in verdict.diagnostics if d not in diags] + diags
    if sampler is not None and record is not None:
        failed = record.save(comp.system.name, sampler.series(), quiet)
        if failed is not None:
            typer.echo(failed, err=True)
            return EXIT_ERRORS
    return _report_run(file, comp, rt.net, result, diags, verdict, cx, bounded, fmt, quiet,
                       tracer.count if tracer is not None else None, trace)


def _report_run(file: Path, comp: Compilation, net: FlatNet, result: RunResult,
                diags: list[Diagnostic],
                verdict: ReplayVerdict | None, cx: Counterexample | None, bounded: bool,
                fmt: Format, quiet: bool, traced: int | None, trace: Path | None) -> int:
    """Print the result of a run; its exit code."""
    if not bounded and result.reason == "until":
        result.message += (" (the default bound: pass --until or --steps to run longer or "
                           "shorter)")
    if fmt is Format.json:
        _print_json(net, result, diags, verdict)
    else:
        _show(comp, diags, fmt)
        _print_text(file, net, result, verdict, quiet)
        if traced is not None and not quiet:
            typer.echo(f"trace: {traced} events written to {trace}", err=True)
    return _exit_code(result, cx, verdict)


class _SetupFailed:
    """The problems that kept the runtime from being set up, to print after the live line."""

    def __init__(self, diagnostics: tuple[Diagnostic, ...] | list[Diagnostic]) -> None:
        self.diagnostics = list(diagnostics)

    def show(self, comp: Compilation, fmt: Format) -> None:
        _show(comp, self.diagnostics, fmt)
        if fmt is Format.json:
            typer.echo(json.dumps({"reason": "setup", "diagnostics":
                                   [d.to_json() for d in self.diagnostics]}, indent=2))


def _prepare(file: Path, configure: Callable[[], RunConfig],
             live: bool) -> tuple[Compilation, Runtime | _SetupFailed | None]:
    """The compilation and, if it is fit to run, the run's runtime (or the problems that
    kept it from being set up, to print); with ``live``, the line that says what is being
    prepared on a slow start (``_Preparing``). The run's configuration is made only for a
    spec that compiled (its folder is looked up then: a root spec that is a symbolic link
    loop is the compiler's E001)."""
    from rssm_dsl.interp import build_runtime
    from rssm_dsl.interp.errors import SetupError
    from rssm_dsl.pipeline import compile_file

    with _Preparing() if live else contextlib.nullcontext() as preparing:
        comp = compile_file(file)
        if not comp.ok or comp.system is None:
            return comp, None
        config = configure()
        if not comp.ok or comp.system is None or _unknown_device(
                comp.system, [*config.devices, *config.device_options]) is not None:
            return comp, None
        if preparing is not None:
            preparing.phase = "building the interpreter"
        try:
            return comp, build_runtime(comp, config)
        except SetupError as e:
            return comp, _SetupFailed(e.diagnostics)


class _Record:
    """What to record of a run (--select) and where to put it (--series, --plot)."""

    def __init__(self, select: list[str] | None, series: Path | None,
                 plot: Path | None) -> None:
        self.select = select or None
        self.series = series
        self.plot = plot

    def attach(self, rt: Runtime) -> Sampler | str | None:
        """The sampler of the run (before its Simulator is made), None when nothing is
        recorded, or the usage error of --select."""
        if self.series is None and self.plot is None:
            return None
        from rssm_dsl.interp.sampler import Sampler, SelectionError

        try:
            sampler = Sampler(rt, self.select)
        except SelectionError as e:
            return f"rssmc: {e}"
        sampler.attach()
        return sampler

    def save(self, system: str, series: list[Any], quiet: bool) -> str | None:
        """Write the series file and the figure; the problem, or None."""
        from rssm_core.series import encode_series
        from rssm_dsl.emit.write import write_outputs

        if self.series is not None:
            write_outputs(self.series.parent,
                          {self.series.name: encode_series(system, series)})
            if not quiet:
                typer.echo(f"series: {len(series)} written to {self.series}", err=True)
        if self.plot is not None:
            from rssm_dsl.run.series_plot import PlotError, draw

            try:
                draw(system, series, self.plot)
            except PlotError as e:
                return f"rssmc: --plot: {e}"
            if not quiet:
                typer.echo(f"plot: {self.plot}", err=True)
        return None


def _show(comp: Compilation, diags: list[Diagnostic], fmt: Format) -> None:
    from rssm_dsl.diagnostics.render import render_text

    if diags and fmt is Format.text:
        typer.echo(render_text(diags, comp.program.line), err=True)


def _unknown_device(system: System, targets: list[str]) -> str | None:
    """The usage error for a --device or --device-option that matches no device."""
    known = {d.id for d in system.devices()}
    for target in targets:
        if not any(fnmatchcase(k, target) for k in known):
            return (f"rssmc: no device {target} in system {system.name} (devices: "
                    f"{', '.join(sorted(known)) or 'none'})")
    return None


def _load_replay(comp: Compilation, rt: Runtime, replay: Path, mode: str, fmt: Format
                 ) -> tuple[Counterexample, list[int], PropertyWatch | None] | int:
    """The counterexample to replay, its transitions and (a property's) the watch that
    judges it, or the exit code when it cannot be replayed (the problem printed)."""
    from rssm_dsl.interp.replay import (
        PropertyWatch,
        ReplayFileError,
        load_counterexample,
        resolve_steps,
    )
    from rssm_dsl.semantics.properties import PropertyError

    try:
        cx = load_counterexample(replay)
    except ReplayFileError as e:
        text = str(e)       # every problem of the file is E852 (the reader's own words)
        typer.echo(f"rssmc: --replay: {text if text.startswith('error[') else f'error[E852]: {text}'}",
                   err=True)
        return EXIT_USAGE
    forced, bad = resolve_steps(rt.net, cx.sequence(), str(replay))
    if bad:                 # E806: not a replay of this net, so nothing is reproduced
        _show(comp, bad, fmt)
        return EXIT_USAGE
    if mode != "deterministic":
        return usage_error("--replay runs in deterministic mode",
                           "leave --mode out (or give --mode deterministic) with --replay")
    if cx.kind != "property":
        return cx, forced, None
    assert comp.system is not None
    prop = next((p for p in comp.system.properties if p.name == cx.subsystem), None)
    if prop is None:
        names = ", ".join(p.name for p in comp.system.properties) or "none"
        typer.echo(f"rssmc: --replay: the counterexample is of property '{cx.subsystem}', "
                   f"which system {comp.system.name} does not state (its properties: "
                   f"{names})", err=True)
        return EXIT_USAGE
    try:
        watch = PropertyWatch(rt, prop, cx)
    except PropertyError as e:
        typer.echo(f"rssmc: --replay: property {prop.name} cannot be evaluated: {e}",
                   err=True)
        return EXIT_USAGE
    return cx, forced, watch


def _print_json(net: FlatNet, result: RunResult, diags: list[Diagnostic],
                verdict: ReplayVerdict | None) -> None:
    out: dict[str, Any] = {
        "reason": result.reason, "message": result.message, "steps": result.steps,
        "time": result.time, "wall": round(result.wall, 3),
        "diagnostics": [d.to_json() for d in diags],
        "marking": result.marking,
        "waiting": [{"subsystem": b.owner, "place": b.place, "label": b.label}
                    for b in result.blocked if any(m for _, m in b.needs)],
        "summary": result.summary.to_json() if result.summary else None,
    }
    if verdict is not None:
        out["replay"] = {"reproduced": verdict.reproduced, "message": verdict.message,
                         "forced": result.forced, "forced_firings": forced_firings(net, result)}
    typer.echo(json.dumps(out, indent=2))


def _print_text(file: Path, net: FlatNet, result: RunResult, verdict: ReplayVerdict | None,
                quiet: bool) -> None:
    from rssm_dsl.interp.summary import render

    if result.summary is not None and not quiet:
        typer.echo(render(result.summary, result.wall))
    if not quiet or not result.ok:
        typer.echo(f"{file}: {result.message}", err=True)
    if verdict is not None:
        extra = (f" ({result.forced} firing(s) forced against the data)"
                 if result.forced else "")
        typer.echo(f"replay: {verdict.message}{extra}", err=True)
        for f in forced_firings(net, result)[:FORCED_SHOWN]:
            typer.echo(f"  forced at step {f['step']}: {f['transition']} "
                       f"[{f['condition']}] did not hold in the simulated data ({f['span']})",
                       err=True)
        if result.forced > FORCED_SHOWN:
            typer.echo(f"  ... and {result.forced - FORCED_SHOWN} more (the trace marks each "
                       "with \"forced\": true)", err=True)


FORCED_SHOWN = 5     # forced firings named in the text report


def forced_firings(net: FlatNet, result: RunResult) -> list[dict[str, Any]]:
    """The replayed firings whose condition did not hold in the simulated data: the step,
    the transition, its condition's words and where the user wrote it. The verifier chose
    such a condition freely (a value it does not track, such as a device's reading); the
    run shows whether the data could make it hold."""
    words = {c.transition: c.text for c in net.conditions}
    out = []
    for step, t in result.forced_at:
        ft = net.transitions[t]
        out.append({"step": step, "transition": ft.name, "condition": words.get(t, ""),
                    "span": str(ft.span)})
    return out


def _exit_code(result: RunResult, cx: Counterexample | None,
               verdict: ReplayVerdict | None) -> int:
    if result.reason == "interrupted":
        return EXIT_INTERRUPTED
    if cx is not None and any(d.code == "E806" for d in result.diagnostics):
        return EXIT_USAGE           # the replay diverged: nothing is reproduced
    if verdict is None and result.reason in ("deadlock", "stalled"):
        return EXIT_STUCK
    if verdict is not None:
        if cx is not None and cx.kind in ("deadlock", "unsafe", "progress", "property"):
            return EXIT_ERRORS if verdict.reproduced else EXIT_USAGE
        return EXIT_OK if verdict.reproduced else EXIT_ERRORS
    return EXIT_OK if result.ok else EXIT_ERRORS


def register(app: typer.Typer) -> None:
    app.command("simulate")(simulate)
