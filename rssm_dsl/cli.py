"""The `rssmc` command line. Heavy modules are imported inside the commands so that
`rssmc --help` stays fast.

Exit codes: 0 success (warnings allowed); 1 the specification has errors (or, for verify,
a property is violated); 2 a usage error (or, for verify, inconclusive); 70 internal error.
"""

from __future__ import annotations

import os
import sys
import traceback
from collections.abc import Callable
from enum import Enum
from typing import Annotated, TypeVar

import typer

from rssm_dsl import __version__

app = typer.Typer(
    name="rssmc",
    help="Compile, check and verify RSSM robot-controller specifications (hierarchical Petri nets).",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

EXIT_OK, EXIT_ERRORS, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 70
T = TypeVar("T")


class Format(str, Enum):
    text = "text"
    json = "json"


def _version(value: bool) -> None:
    if value:
        typer.echo(f"rssmc {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print the version and exit.")] = False,
) -> None:
    """rssmc: the RSSM compiler."""


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


def report(comp: object, fmt: Format, quiet: bool = False) -> None:
    from rssm_dsl.diagnostics.render import render_json, render_text, summary
    from rssm_dsl.pipeline import Compilation

    assert isinstance(comp, Compilation)
    diags = list(comp.diagnostics)
    if fmt is Format.json:
        typer.echo(render_json(diags))
        return
    if diags:
        typer.echo(render_text(diags, comp.program.line), err=True)
    if diags or not quiet:
        typer.echo(f"{comp.path}: {summary(diags)}", err=True)


def _register_commands() -> None:
    """Each command lives in rssm_dsl/commands/<name>.py with a `register(app)` function;
    command modules import their heavy dependencies inside the command body."""
    import importlib

    from rssm_dsl.commands import COMMANDS

    for name in COMMANDS:
        importlib.import_module(f"rssm_dsl.commands.{name}").register(app)


_register_commands()


def entry() -> None:
    """Console-script entry point."""
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)
