"""`rssmc fmt`: format specifications in place with the canonical formatter."""

from __future__ import annotations

import contextlib
import difflib
import io
import os
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from rssm_dsl.commands.common import EXIT_ERRORS, EXIT_OK, EXIT_USAGE, guarded

if TYPE_CHECKING:
    from rssm_dsl.source import SourceFile


PATH_CODES = frozenset({"E001", "E002"})     # the path names nothing that can be read


def _is_dir(path: Path) -> bool:
    try:
        return path.is_dir()
    except (OSError, ValueError):   # a path too long, a NUL: read_source says why
        return False


def _files(paths: list[Path]) -> list[Path]:
    """The files to format: each path given, or the .rssm files under a folder given. A path
    that is no folder is kept whatever it is: reading it (read_source, the one place spec
    files are read) reports what is wrong (E001 missing or unreadable, E002 not a regular
    file, such as a FIFO)."""
    out: list[Path] = []
    for p in paths:
        if _is_dir(p):
            out.extend(sorted(p.rglob("*.rssm")))
        else:
            out.append(p)
    return out


def _write_whole(path: Path, text: str) -> None:
    """Replace the file's text all or nothing: written beside it, then renamed over it (the
    file a symbolic link names, keeping the link; its permissions kept), so that a failure
    (a full disk, Ctrl-C) leaves the file as it was."""
    real = Path(os.path.realpath(path))
    fd, temp = tempfile.mkstemp(prefix=".rssmc-fmt-", suffix=".rssm", dir=real.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(temp, stat.S_IMODE(real.stat().st_mode))
        os.replace(temp, real)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(temp)
        raise


def _lines_of(source: SourceFile) -> Callable[[str, int], str]:
    def line(file: str, n: int) -> str:
        return source.line_text(n)

    return line


def fmt(
    files: Annotated[list[Path], typer.Argument(help="The .rssm files (or folders) to format.",
                                                show_default=False)],
    check: Annotated[bool, typer.Option("--check", help="Write nothing; exit 1 if a file "
                                        "would change.")] = False,
    diff: Annotated[bool, typer.Option("--diff", help="Write nothing; print what would "
                                       "change as a unified diff on stdout (exit 1 if a file "
                                       "would change, as --check).")] = False,
) -> None:
    """Format specifications with the canonical layout (comments are kept). Files are
    rewritten in place; with --check or --diff, nothing is written and the exit code
    tells (--diff also shows the changes)."""

    def run() -> int:
        from rssm_dsl.diagnostics import DiagnosticBag
        from rssm_dsl.diagnostics.render import render_text
        from rssm_dsl.semantics.loader import display_path, read_source
        from rssm_dsl.source import Span
        from rssm_dsl.syntax.format import format_text

        code = EXIT_OK
        for path in _files(files):  # each path in turn: a wrong one does not stop the rest
            bag = DiagnosticBag()
            source = read_source(path, bag, Span(str(path), 1, 1, 1, 1))
            if source is None:
                diags = bag.sorted()
                typer.echo(render_text(diags, lambda f, n: ""), err=True)
                # a path that names no readable file (E001, E002) is a usage error, as it
                # always was for `fmt`; a file that is no text or too large (E003, E004) an error
                wrong_path = any(d.code in PATH_CODES for d in diags)
                code = EXIT_USAGE if wrong_path else max(code, EXIT_ERRORS)
                continue
            result = format_text(source.text, source.path)
            if result.text is None:
                typer.echo(render_text(result.diagnostics, _lines_of(source)), err=True)
                typer.echo(f"{display_path(path)}: not formatted (syntax errors)", err=True)
                code = max(code, EXIT_ERRORS)
                continue
            if result.text == source.text:
                continue
            if check or diff:
                if diff:
                    shown = display_path(path)
                    # lines as the file has them (split at LF only: the compiler never
                    # splits source text with str.splitlines, which breaks at more)
                    typer.echo("".join(difflib.unified_diff(
                        io.StringIO(source.text).readlines(),
                        io.StringIO(result.text).readlines(),
                        f"{shown} (as it is)", f"{shown} (formatted)")), nl=False)
                typer.echo(f"{display_path(path)}: would be reformatted", err=True)
                code = max(code, EXIT_ERRORS)
            else:
                _write_whole(path, result.text)
                typer.echo(f"{display_path(path)}: formatted", err=True)
        return code

    guarded(run)


def register(app: typer.Typer) -> None:
    app.command("fmt")(fmt)
