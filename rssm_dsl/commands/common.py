"""What the commands share: exit codes, the diagnostics format, the common arguments and
options, the guard that turns a crash into an internal-error report, and the diagnostics
report. `rssm_dsl.cli` imports the commands; the commands import this module, never the CLI.

Exit codes: 0 success (warnings allowed); 1 the specification has errors (or, for verify,
a property is violated); 2 a usage error (for verify, also a specification that does not
compile); 70 internal error; 130 interrupted (Ctrl-C). `rssmc verify` adds 3 inconclusive
and 4 verified without the progress check (rssm_dsl/commands/verify.py).
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Callable
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from rssm_dsl.pipeline import Compilation

EXIT_OK, EXIT_ERRORS, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 70
EXIT_INTERRUPTED = 130


class Format(str, Enum):
    text = "text"
    json = "json"


FileArg = Annotated[Path, typer.Argument(help="The .rssm file of the system.", show_default=False)]
FormatOpt = Annotated[Format, typer.Option("--format", "-f", help="How to print diagnostics.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing on success.")]


def guarded(fn: Callable[[], int]) -> None:
    """Run a command body; turn an unexpected exception into a clear internal-error report."""
    try:
        code = fn()
    except (typer.Exit, KeyboardInterrupt):
        raise
    except Exception as e:
        typer.echo(f"rssmc: internal error [E900]: {type(e).__name__}: {e}", err=True)
        typer.echo("  help: this is a bug in rssmc; please report it with the input file"
                   " (set RSSMC_DEBUG=1 for the traceback)", err=True)
        if os.environ.get("RSSMC_DEBUG"):
            traceback.print_exc()
        raise typer.Exit(EXIT_INTERNAL) from None
    raise typer.Exit(code)


def report(comp: Compilation, fmt: Format, quiet: bool = False) -> None:
    """Print the diagnostics of a compilation (text on stderr with a summary line, or JSON
    on stdout)."""
    from rssm_dsl.diagnostics.render import render_json, render_text, summary

    diags = list(comp.diagnostics)
    if fmt is Format.json:
        typer.echo(render_json(diags))
        return
    if diags:
        typer.echo(render_text(diags, comp.program.line), err=True)
    if diags or not quiet:
        typer.echo(f"{comp.path}: {summary(diags)}", err=True)
