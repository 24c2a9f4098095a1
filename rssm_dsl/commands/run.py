"""`rssmc run`: the paper's section V experiment on the simulated LWR4+, or the joint-space
run of an arm of stdlib/robots (docs/run.md)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rssm_dsl.commands.common import (
    EXIT_ERRORS,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    Format,
    guarded,
    report,
    usage_error,
)

if TYPE_CHECKING:
    from rssm_dsl.diagnostics import Diagnostic
    from rssm_dsl.pipeline import Compilation
    from rssm_dsl.run import Experiment
    from rssm_dsl.run.viewer import Viewer

DAMPING = ("velocity-error", "paper")

FileArg = Annotated[Path, typer.Argument(help="The .rssm file of the system (e.g. "
                                         "examples/lwr4_circle.rssm).", show_default=False)]


def run_cmd(
    file: FileArg,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", help="Output folder (default: out/<file name>-run).")] = None,
    until: Annotated[float, typer.Option(
        "--until", min=0.0, help="Stop at this simulated time (s) if the control subsystem "
        "has not switched behaviours --switches times by then.")] = 30.0,
    switches: Annotated[int, typer.Option(
        "--switches", min=0, help="Stop after this many behaviour switches of the control "
        "subsystem (2: cw -> ccw -> cw, one circle each way; of the first arm's in a "
        "joint-space run of several arms); 0: run until --until.")] = 2,
    damping: Annotated[str | None, typer.Option(
        "--damping", help="velocity-error: F = K dP + D (dP_des/dt - dP/dt); paper: the "
        "paper's F = K dP - D dP/dt (default: the specification's "
        "damp_velocity_error parameter).", show_default=False)] = None,
    viewer: Annotated[bool, typer.Option(
        "--viewer", help="Show the run in MuJoCo's viewer at real speed (needs a display; "
        "without one the run goes on headless).")] = False,
    video: Annotated[Path | None, typer.Option(
        "--video", help="Also render the run offscreen to this MP4 file (EGL without a "
        "display).", show_default=False)] = None,
    trace: Annotated[Path | None, typer.Option(
        "--trace", help="Write the interpreter's trace (JSON lines; every firing, send, "
        "receive and switch; makes the run several times slower).", show_default=False)]
    = None,
    seed: Annotated[int, typer.Option(help="Seed of the choice among enabled "
                                      "transitions.")] = 0,
    format: Annotated[Format, typer.Option(
        "--format", "-f", help="text: a summary; json: summary.json on stdout.")] = Format.text,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print only problems.")] = False,
) -> None:
    """Run the paper's experiment (section V) on a KUKA LWR4+ simulated by MuJoCo: the
    control subsystem's circles, clockwise then counter-clockwise, tracked by the virtual
    effector's impedance control, executed by the HPN interpreter on simulated time. Writes
    trajectory.csv, fig19.png (the paper's Fig. 19) and summary.json, and prints the
    duration, real-time factor, tracking error and behaviour switches. A system with an arm of
    the standard library's robots module tracking joint set points instead is run in joint
    space (trajectory.csv, joints.png, summary.json; with several such arms, one trajectory
    per arm). Exit 0 when the experiment ran, 1 on
    errors in the specification or the run, 2 on usage errors."""

    def run() -> int:
        if damping is not None and damping not in DAMPING:
            return usage_error(f"--damping must be {' or '.join(DAMPING)}, not "
                               f"{damping}", "leave it out for the paper's damping")
        if video is not None and video.suffix.lower() != ".mp4":
            return usage_error(f"--video writes an MP4 file: {video} does not "
                               "end in .mp4", "name the file NAME.mp4")
        return _run(file, output, until, switches, damping, viewer, video, trace, seed,
                    format, quiet)

    guarded(run)


def _show(comp: Compilation, diags: list[Diagnostic], fmt: Format) -> None:
    from rssm_dsl.diagnostics.render import render_text

    if diags and fmt is Format.text:
        typer.echo(render_text(diags, comp.program.line), err=True)


def _run(file: Path, output: Path | None, until: float, switches: int, damping: str | None,
         viewer: bool, video: Path | None, trace: Path | None, seed: int, fmt: Format,
         quiet: bool) -> int:
    from rssm_dsl.diagnostics import Diagnostic
    from rssm_dsl.emit.write import write_outputs
    from rssm_dsl.extras import missing_message
    from rssm_dsl.pipeline import compile_file
    from rssm_dsl.run import RunError, RunOptions, output_files, run_experiment
    from rssm_dsl.run.video import choose_backend

    absent = missing_message("rssmc run", "run")
    if absent is not None:
        typer.echo(absent, err=True)
        return EXIT_USAGE
    if video is not None:
        choose_backend()                  # before anything imports mujoco
    comp = compile_file(file)
    if not comp.ok or comp.system is None:
        report(comp, fmt)
        return EXIT_ERRORS
    if comp.diagnostics and fmt is Format.text and not quiet:
        report(comp, fmt)
    if _joint_space(comp):
        return _run_joints(comp, file, output, until, switches,
                           damping is not None or viewer or video is not None, trace, seed,
                           fmt, quiet)
    warnings: list[Diagnostic] = []
    show = _open_viewer(comp, warnings, fmt) if viewer else None
    options = RunOptions(until=until, switches=switches, damping=damping, seed=seed,
                         trace=trace, keep_q=video is not None,
                         observers=(show,) if show is not None else ())
    try:
        exp = run_experiment(comp, options)
    except RunError as e:
        _show(comp, e.diagnostics, fmt)
        if fmt is Format.json:
            typer.echo(json.dumps({"reason": "setup", "diagnostics":
                                   [d.to_json() for d in e.diagnostics]}, indent=2))
        return EXIT_USAGE if e.usage else EXIT_ERRORS
    finally:
        if show is not None:
            show.close()
    if show is not None and show.problem is not None:
        _warn(comp, warnings, Diagnostic("W872", show.problem, comp.system.span), fmt)
    _show(comp, list(exp.diagnostics), fmt)

    target = output if output is not None else Path("out") / f"{file.stem}-run"
    written = write_outputs(target, output_files(exp))
    video_note = _write_video(comp, exp, video, warnings, fmt) if video is not None else ""
    _print_result(exp, written, target, video if video_note else None, video_note, trace,
                  warnings, fmt, quiet)
    if exp.reason == "interrupted":
        return EXIT_INTERRUPTED
    if not exp.ok:
        if fmt is Format.text:
            typer.echo(f"{file}: {exp.message}", err=True)
        return EXIT_ERRORS
    return EXIT_OK


def _joint_space(comp: Compilation) -> bool:
    """No LWR4+ experiment, but arms of stdlib/robots (the joint-space run says what it
    misses: E870)."""
    from rssm_dsl.diagnostics import Diagnostic
    from rssm_dsl.run.joints import ARM_BINDING
    from rssm_dsl.run.rig import find_rig

    assert comp.system is not None
    return (isinstance(find_rig(comp.system), Diagnostic)
            and any(d.binding == ARM_BINDING for d in comp.system.devices()))


def _run_joints(comp: Compilation, file: Path, output: Path | None, until: float,
                switches: int, lwr4_only: bool, trace: Path | None, seed: int, fmt: Format,
                quiet: bool) -> int:
    """The joint-space run of the arms of stdlib/robots (docs/run.md, "Other robots")."""
    from rssm_dsl.emit.write import write_outputs
    from rssm_dsl.run.joints import JointRunError, run_arms_tracking
    from rssm_dsl.run.joints_report import (
        arms_output_files,
        arms_summary_dict,
        arms_summary_text,
    )

    assert comp.system is not None
    if lwr4_only:
        typer.echo("rssmc: --damping, --viewer and --video apply to the LWR4+ experiment "
                   f"only, not to {file} (a joint-space run)", err=True)
        return EXIT_USAGE
    try:
        runs = run_arms_tracking(comp, until, seed, switches, trace)
    except JointRunError as e:
        _show(comp, e.diagnostics, fmt)
        if fmt is Format.json:
            typer.echo(json.dumps({"reason": "setup", "diagnostics":
                                   [d.to_json() for d in e.diagnostics]}, indent=2))
        return EXIT_ERRORS
    r = runs[0]
    _show(comp, list(r.diagnostics), fmt)
    target = output if output is not None else Path("out") / f"{file.stem}-run"
    written = write_outputs(target, arms_output_files(runs))
    if fmt is Format.json:
        data = arms_summary_dict(runs)
        data["outputs"] = [str(p) for p in written]
        typer.echo(json.dumps(data, indent=2))
    elif not quiet:
        typer.echo(arms_summary_text(runs, comp.system.name))
        typer.echo(f"  wrote      {', '.join(p.name for p in written)} to {target}")
        if trace is not None:
            typer.echo(f"  trace      {trace}")
    if r.reason == "interrupted":
        return EXIT_INTERRUPTED
    if not r.ok:
        if fmt is Format.text:
            typer.echo(f"{file}: {r.message}", err=True)
        return EXIT_ERRORS
    return EXIT_OK


def _warn(comp: Compilation, warnings: list[Diagnostic], warning: Diagnostic,
          fmt: Format) -> None:
    """Keep a warning for the JSON summary and print it now (text)."""
    warnings.append(warning)
    _show(comp, [warning], fmt)


def _open_viewer(comp: Compilation, warnings: list[Diagnostic], fmt: Format) -> Viewer | None:
    """MuJoCo's viewer, or None (with a W872 warning) when there is no display."""
    from rssm_dsl.diagnostics import Diagnostic
    from rssm_dsl.run.viewer import Viewer, display_problem

    assert comp.system is not None
    problem = display_problem()
    if problem is not None:
        _warn(comp, warnings, Diagnostic("W872", problem, comp.system.span), fmt)
        return None
    return Viewer()


def _write_video(comp: Compilation, exp: Experiment, video: Path, warnings: list[Diagnostic],
                 fmt: Format) -> str:
    """Render the run to `video`; the note for the summary ('' with a W873 warning if the
    video could not be written)."""
    from rssm_dsl.diagnostics import Diagnostic
    from rssm_dsl.run.video import write_video

    assert comp.system is not None
    result = write_video(exp, video)
    if result.problem is not None:
        _warn(comp, warnings, Diagnostic("W873", result.problem, comp.system.span), fmt)
        return ""
    return f", {result.frames} frames to {video}"


def _print_result(exp: Experiment, written: list[Path], target: Path, video: Path | None,
                  video_note: str, trace: Path | None, warnings: list[Diagnostic], fmt: Format,
                  quiet: bool) -> None:
    """The summary: summary.json on stdout (json), or the text summary."""
    from rssm_dsl.run import summary_text
    from rssm_dsl.run.report import summary_dict

    if fmt is Format.json:
        data = summary_dict(exp)
        data["outputs"] = [str(p) for p in written]
        data["video"] = str(video) if video is not None else None
        data["warnings"] = [d.to_json() for d in warnings]
        typer.echo(json.dumps(data, indent=2))
    elif not quiet:
        typer.echo(summary_text(exp))
        typer.echo(f"  wrote      {', '.join(p.name for p in written)} to {target}"
                   f"{video_note}")
        if trace is not None:
            typer.echo(f"  trace      {trace}")


def register(app: typer.Typer) -> None:
    app.command("run")(run_cmd)
