"""`rssmc fmt`: format specifications in place with the canonical formatter."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rssm_dsl.commands.common import EXIT_ERRORS, EXIT_OK, EXIT_USAGE, guarded

if TYPE_CHECKING:
    from rssm_dsl.source import SourceFile


def _files(paths: list[Path]) -> list[Path] | None:
    out: list[Path] = []
    for p in paths:
        if p.is_dir():
            out.extend(sorted(p.rglob("*.rssm")))
        elif p.is_file():
            out.append(p)
        else:
            typer.echo(f"rssmc fmt: no such file or folder: {p}", err=True)
            return None
    return out


def _lines_of(source: SourceFile) -> Callable[[str, int], str]:
    def line(file: str, n: int) -> str:
        return source.line_text(n)

    return line


def fmt(
    files: Annotated[list[Path], typer.Argument(help="The .rssm files (or folders) to format.",
                                                show_default=False)],
    check: Annotated[bool, typer.Option("--check", help="Write nothing; exit 1 if a file "
                                        "would change.")] = False,
) -> None:
    """Format specifications with the canonical layout (comments are kept). Files are
    rewritten in place; with --check, nothing is written and the exit code tells."""

    def run() -> int:
        from rssm_dsl.diagnostics import DiagnosticBag
        from rssm_dsl.diagnostics.render import render_text
        from rssm_dsl.semantics.loader import display_path, read_source
        from rssm_dsl.source import Span
        from rssm_dsl.syntax.format import format_text

        found = _files(files)
        if found is None:
            return EXIT_USAGE
        code = EXIT_OK
        for path in found:
            bag = DiagnosticBag()
            source = read_source(path, bag, Span(str(path), 1, 1, 1, 1))
            if source is None:
                typer.echo(render_text(bag.sorted(), lambda f, n: ""), err=True)
                code = EXIT_ERRORS
                continue
            result = format_text(source.text, source.path)
            if result.text is None:
                typer.echo(render_text(result.diagnostics, _lines_of(source)), err=True)
                typer.echo(f"{display_path(path)}: not formatted (syntax errors)", err=True)
                code = EXIT_ERRORS
                continue
            if result.text == source.text:
                continue
            if check:
                typer.echo(f"{display_path(path)}: would be reformatted", err=True)
                code = EXIT_ERRORS
            else:
                path.write_text(result.text, encoding="utf-8")
                typer.echo(f"{display_path(path)}: formatted", err=True)
        return code

    guarded(run)


def register(app: typer.Typer) -> None:
    app.command("fmt")(fmt)
