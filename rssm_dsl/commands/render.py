"""`rssmc render`: one SVG figure per page (Graphviz), an index, and the HTML explorer."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rssm_dsl.commands.common import (
    EXIT_ERRORS,
    EXIT_OK,
    EXIT_USAGE,
    OUTPUT_METAVAR,
    FileArg,
    Format,
    FormatOpt,
    QuietOpt,
    guarded,
    output_folder,
    report,
    usage_error,
)
from rssm_dsl.render import MAX_STEPS, MAX_STEPS_LIMIT

if TYPE_CHECKING:
    from rssm_dsl.diagnostics import DiagnosticBag
    from rssm_dsl.hpn.flat import FlatNet
    from rssm_dsl.render.playback import Playback, Window
    from rssm_dsl.render.series import SeriesPanel
    from rssm_dsl.render.svg import PageProblem
    from rssm_dsl.source import Span


def render_cmd(
    file: FileArg,
    output: Annotated[str | None, typer.Option(
        "--output", "-o", metavar=OUTPUT_METAVAR,
        help="Output folder (default: out/<file name>/render).")] = None,
    html: Annotated[bool, typer.Option(
        "--html", help="Also write <system>.html, a self-contained explorer of the hierarchy "
        "with token-game playback.")] = False,
    svg: Annotated[bool, typer.Option(
        "--svg/--no-svg", help="Draw one SVG per page with Graphviz dot.")] = True,
    trace: Annotated[Path | None, typer.Option(
        "--trace", help="A trace of `rssmc simulate` (JSON lines) or a verifier counterexample "
        "(JSON) to play back in the explorer; implies --html.", show_default=False)] = None,
    max_steps: Annotated[int, typer.Option(
        "--max-steps", min=0, max=MAX_STEPS_LIMIT,
        help="Embed at most this many firings of the trace (a window of it).")] = MAX_STEPS,
    from_step: Annotated[int | None, typer.Option(
        "--from-step", min=0, help="The window of the trace starts at this step (the marking "
        "after that many firings; 0: the initial marking).", show_default=False)] = None,
    from_time: Annotated[float | None, typer.Option(
        "--from-time", min=0.0, help="The window of the trace starts at its first firing at "
        "or after this time (seconds).", show_default=False)] = None,
    series: Annotated[Path | None, typer.Option(
        "--series", help="A series file of `rssmc simulate --series` (.npz) to draw as "
        "charts in the explorer, with a cursor at the time of the playback's step; implies "
        "--html.", show_default=False)] = None,
    select: Annotated[list[str] | None, typer.Option(
        "--select", help="Draw only these series (names or shell patterns, e.g. 'a1.c.*'), "
        "as for `rssmc plot`; repeatable.", show_default=False)] = None,
    format: FormatOpt = Format.text,
    quiet: QuietOpt = False,
) -> None:
    """Draw each page of the HPN as the paper draws it: fig-H.svg, fig-P_1.svg,
    fig-PB_1_lwr_move.svg, ... and index.html listing them (page id -> file). If Graphviz is
    not installed the explorer is written instead. Nothing is written when the specification
    or the trace has errors. A trace longer than --max-steps is shown as a window of it
    (--from-step, --from-time); --series adds the charts of a run's series."""

    def run() -> int:
        from dataclasses import replace

        from rssm_dsl.diagnostics import DiagnosticBag
        from rssm_dsl.emit.write import write_outputs
        from rssm_dsl.filenames import file_name
        from rssm_dsl.hpn.flatten import flatten
        from rssm_dsl.pipeline import compile_file
        from rssm_dsl.render.html import render_explorer, render_index
        from rssm_dsl.render.names import figure_files
        from rssm_dsl.render.playback import Window, WindowError
        from rssm_dsl.render.series import load_series
        from rssm_dsl.render.svg import draw_figures, find_dot

        usage = _usage(trace, series, select, from_step, from_time)
        if usage is not None:
            return usage_error(usage, "'rssmc render --help' lists the options")
        target = output_folder(output, Path("out") / file.stem / "render")
        if target is None:
            return EXIT_USAGE
        comp = compile_file(file)
        if not comp.ok or comp.hpn is None:
            report(comp, format, quiet)
            return EXIT_ERRORS
        hpn = comp.hpn
        bag = DiagnosticBag()
        at = hpn.pages[hpn.root].span
        net = flatten(hpn)
        window = Window(from_step or 0, from_time, max_steps)
        try:
            playback = _playback(trace, net, bag, window) if trace is not None else None
        except WindowError as e:
            return usage_error(str(e), "give --from-step or --from-time within the trace")
        panel = load_series(series, hpn.system, bag, select) if series is not None else None
        if bag.has_errors:
            report(replace(comp, diagnostics=comp.diagnostics + tuple(bag.sorted())), format)
            return EXIT_ERRORS

        want_html = html or trace is not None or series is not None
        files: dict[str, str] = {}
        figures: dict[str, str] = {}
        missing: str | None = "not asked for (--no-svg)" if not svg else None
        if svg:
            dot = find_dot()
            if dot is None:
                missing = "Graphviz `dot` is not installed"
                bag.warn("W850", "Graphviz `dot` is not installed: no SVG figures were drawn",
                         at, "install Graphviz (Debian: apt-get install graphviz); the HTML "
                         "explorer, which needs nothing installed, was written instead")
                want_html = True
            else:
                names = figure_files(hpn)
                drawn, problems = draw_figures(hpn, names, dot)
                if problems and all(not p.drawn for p in problems) and len(problems) == len(names):
                    first = problems[0]
                    missing = f"Graphviz failed on page {first.page}"
                    bag.error("E851", f"Graphviz `dot` failed on every page, first on "
                              f"{first.page}: {first.message}", at,
                              "the HTML explorer was written instead")
                    want_html = True
                else:
                    files.update(drawn)
                    figures = names
                    want_html = _page_problems(problems, bag, at) or want_html
        explorer = file_name(hpn.system, ".html") if want_html else None
        spec = str(file)
        if explorer is not None:
            files[explorer] = render_explorer(hpn, net, comp.program, spec, figures, playback,
                                              panel)
        files["index.html"] = render_index(hpn, spec, figures, explorer, missing)
        write_outputs(target, files)
        full = replace(comp, diagnostics=comp.diagnostics + tuple(bag.sorted()))
        report(full, format, quiet)
        if not quiet and format is Format.text:
            what = [f"{len(figures)} figures" if figures else "no figures", "index.html"]
            if explorer is not None:
                what.append(explorer + _contents(playback, panel))
            typer.echo(f"wrote {', '.join(what)} to {target}", err=True)
        return EXIT_ERRORS if bag.has_errors else EXIT_OK

    guarded(run)


PAGE_PROBLEMS_SHOWN = 10      # W849 per page up to this many, then one for the rest


def _page_problems(problems: list[PageProblem], bag: DiagnosticBag, at: Span) -> bool:
    """W849 for the pages whose first layout failed (bounded); True when a page was not
    drawn at all, so the explorer is written to show it."""
    for p in problems[:PAGE_PROBLEMS_SHOWN]:
        if p.drawn:
            bag.warn("W849", f"page {p.page} was drawn with the quick layout (straight edges): "
                     f"{p.message}", at, "the figure is complete, only less tidy; a smaller "
                     "page (fewer buffers or behaviours in one subsystem) lays out faster")
        else:
            bag.warn("W849", f"page {p.page} was not drawn: {p.message}", at,
                     "its figure says so; the HTML explorer, written beside it, shows the page")
    rest = problems[PAGE_PROBLEMS_SHOWN:]
    if rest:
        undrawn = sum(not p.drawn for p in rest)
        bag.warn("W849", f"{len(rest)} more pages were drawn with the quick layout or not at all "
                 f"({undrawn} not drawn), first {rest[0].page}", at,
                 "the HTML explorer shows every page")
    return any(not p.drawn for p in problems)


def _playback(trace: Path, net: FlatNet, bag: DiagnosticBag, window: Window) -> Playback | None:
    """The playback of the trace file, or None with its problem in ``bag`` (E852). The file
    is checked first, within bounds (rssm_dsl/interp/trace.py): a regular file whose lines
    are each at most MAX_FILE_BYTES, so the reader never blocks on a FIFO nor reads
    /dev/zero without end; a JSON value nested too deeply for the decoder, or an integer of
    more digits than Python converts, is E852 too (json_problem)."""
    from rssm_dsl.gcpause import collector_paused
    from rssm_dsl.interp.trace import TraceFileError, json_problem, scan_trace_file
    from rssm_dsl.render.playback import load_playback
    from rssm_dsl.source import Span

    source = str(trace)
    hint = ("give a trace of `rssmc simulate --trace` (JSON lines) or a report of "
            "`rssmc verify --format json`")
    try:
        scan_trace_file(trace)
    except TraceFileError as e:
        bag.error("E852", e.message, Span(source, e.line, 1, e.line, 1), e.hint or hint)
        return None
    try:
        with collector_paused():
            return load_playback(trace, net, bag, window)
    except (ValueError, RecursionError) as e:   # from the JSON decoder (a WindowError is not)
        problem = json_problem(e)
        if problem is None:
            raise
        bag.error("E852", f"the trace holds {problem}", Span(source, 1, 1, 1, 1), hint)
        return None


def _usage(trace: Path | None, series: Path | None, select: list[str] | None,
           from_step: int | None, from_time: float | None) -> str | None:
    """The usage error of the options, or None."""
    if from_step is not None and from_time is not None:
        return "--from-step and --from-time both choose where the window starts: give one"
    if trace is None and (from_step is not None or from_time is not None):
        return "--from-step and --from-time choose a window of the trace: give --trace"
    if select and series is None:
        return "--select chooses series of the file given with --series"
    return None


def _contents(playback: Playback | None, panel: SeriesPanel | None) -> str:
    """What the explorer holds, for the summary line."""
    parts = []
    if playback is not None:
        if playback.whole:
            parts.append(f"playback: {len(playback.fired)} firings")
        else:
            parts.append(f"playback: steps {playback.first} to {playback.last} of "
                         f"{playback.total} firings")
    if panel is not None:
        parts.append(f"{panel.series} series in {len(panel.charts)} charts")
    return f" ({'; '.join(parts)})" if parts else ""


def register(app: typer.Typer) -> None:
    app.command("render")(render_cmd)
