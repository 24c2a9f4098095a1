"""`rssmc plot`: draw the series a run recorded (`rssmc simulate --series`) against time."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rssm_dsl.commands.common import EXIT_ERRORS, EXIT_OK, EXIT_USAGE, guarded, usage_error


def plot(
    file: Annotated[Path, typer.Argument(help="A series file (.npz) of `rssmc simulate "
                                              "--series`.", show_default=False)],
    output: Annotated[Path, typer.Option("--output", "-o",
                      help="The figure: .png or .svg.")] = Path("series.png"),
    select: Annotated[list[str] | None, typer.Option(
        "--select", help="Draw only these series (names or shell patterns, e.g. 'a1.c.*'); "
                         "repeatable.")] = None,
) -> None:
    """Draw recorded series against time: a row per variable (vector and record
    components together), a row per behaviour or enum. Exit 1 when there is nothing to
    draw, 2 on usage errors."""

    def run() -> int:
        from rssm_core.series import SeriesFormatError, read_series, select_series
        from rssm_dsl.extras import missing_message

        absent = missing_message("rssmc plot", "run")
        if absent is not None:
            typer.echo(absent, err=True)
            return EXIT_USAGE
        from rssm_dsl.run.series_plot import PlotError, draw

        if output.suffix.lower() not in (".png", ".svg"):
            return usage_error(f"-o {output}: the figure is written as .png "
                               "or .svg", "name the file NAME.png or NAME.svg")

        try:
            system, series = read_series(file)
        except SeriesFormatError as e:      # the code render --series gives it too
            typer.echo(f"rssmc: error[E856]: {file}: {e}", err=True)
            return EXIT_USAGE
        if select:
            chosen, unmatched = select_series(series, select)
            if unmatched:
                names = ", ".join(s.name for s in series[:12])
                return usage_error(
                    f"--select {unmatched[0]} names no series of "
                    f"{file}",
                    f"its series: {names}{', ...' if len(series) > 12 else ''}")
            series = chosen
        try:
            draw(system, series, output)
        except PlotError as e:
            typer.echo(f"rssmc: {e}", err=True)
            return EXIT_ERRORS
        typer.echo(f"plot: {output}", err=True)
        return EXIT_OK

    guarded(run)


def register(app: typer.Typer) -> None:
    app.command("plot")(plot)
