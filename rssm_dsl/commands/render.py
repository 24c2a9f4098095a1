"""`rssmc render`: one SVG figure per page (Graphviz), an index, and the HTML explorer."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rssm_dsl.commands.common import EXIT_ERRORS, EXIT_OK, FileArg, Format, FormatOpt, QuietOpt, guarded, report
from rssm_dsl.render import MAX_STEPS


def render_cmd(
    file: FileArg,
    output: Annotated[Path | None, typer.Option(
        "--output", "-o", help="Output folder (default: out/<file name>/render).")] = None,
    html: Annotated[bool, typer.Option(
        "--html", help="Also write <system>.html, a self-contained explorer of the hierarchy "
        "with token-game playback.")] = False,
    svg: Annotated[bool, typer.Option(
        "--svg/--no-svg", help="Draw one SVG per page with Graphviz dot.")] = True,
    trace: Annotated[Path | None, typer.Option(
        "--trace", help="A trace of `rssmc simulate` (JSON lines) or a verifier counterexample "
        "(JSON) to play back in the explorer; implies --html.", show_default=False)] = None,
    max_steps: Annotated[int, typer.Option(
        "--max-steps", min=0, help="Play at most this many firings of the trace.")] = MAX_STEPS,
    format: FormatOpt = Format.text,
    quiet: QuietOpt = False,
) -> None:
    """Draw each page of the HPN as the paper draws it: fig-H.svg, fig-P_1.svg,
    fig-PB_1_lwr_move.svg, ... and index.html listing them (page id -> file). If Graphviz is
    not installed the explorer is written instead. Nothing is written when the specification
    or the trace has errors."""

    def run() -> int:
        from dataclasses import replace

        from rssm_dsl.diagnostics import DiagnosticBag
        from rssm_dsl.emit.write import write_outputs
        from rssm_dsl.filenames import file_name
        from rssm_dsl.hpn.flatten import flatten
        from rssm_dsl.pipeline import compile_file
        from rssm_dsl.render.html import render_explorer, render_index
        from rssm_dsl.render.names import figure_files
        from rssm_dsl.render.playback import load_playback
        from rssm_dsl.render.svg import GraphvizError, find_dot, render_svgs

        comp = compile_file(file)
        if not comp.ok or comp.hpn is None:
            report(comp, format, quiet)
            return EXIT_ERRORS
        hpn = comp.hpn
        bag = DiagnosticBag()
        at = hpn.pages[hpn.root].span
        net = flatten(hpn)
        playback = load_playback(trace, net, bag, max_steps) if trace is not None else None
        if bag.has_errors:
            report(replace(comp, diagnostics=comp.diagnostics + tuple(bag.sorted())), format)
            return EXIT_ERRORS

        want_html = html or trace is not None
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
                try:
                    files.update(render_svgs(hpn, names, dot))
                    figures = names
                except GraphvizError as e:
                    missing = f"Graphviz failed on page {e.page}"
                    bag.error("E851", f"Graphviz `dot` failed on page {e.page}: {e.message}",
                              at, "the HTML explorer was written instead")
                    want_html = True
        explorer = file_name(hpn.system, ".html") if want_html else None
        spec = str(file)
        if explorer is not None:
            files[explorer] = render_explorer(hpn, net, comp.program, spec, figures, playback)
        files["index.html"] = render_index(hpn, spec, figures, explorer, missing)
        target = output if output is not None else Path("out") / file.stem / "render"
        write_outputs(target, files)
        full = replace(comp, diagnostics=comp.diagnostics + tuple(bag.sorted()))
        report(full, format, quiet)
        if not quiet and format is Format.text:
            what = [f"{len(figures)} figures" if figures else "no figures", "index.html"]
            if explorer is not None:
                what.append(explorer)
                if playback is not None:
                    what[-1] += f" (playback: {len(playback.steps)} firings)"
            typer.echo(f"wrote {', '.join(what)} to {target}", err=True)
        return EXIT_ERRORS if bag.has_errors else EXIT_OK

    guarded(run)


def register(app: typer.Typer) -> None:
    app.command("render")(render_cmd)
