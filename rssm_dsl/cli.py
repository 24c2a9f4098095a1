"""The `rssmc` command line. Heavy modules are imported inside the commands so that
`rssmc --help` stays fast.

Exit codes (rssm_dsl/commands/common.py): 0 success (warnings allowed); 1 the specification
has errors (or, for verify, a property is violated); 2 a usage error; 70 internal error;
130 interrupted. `rssmc verify` adds 3 (inconclusive) and 4 (verified without the progress
check).
"""

from __future__ import annotations

import importlib
import sys
from typing import Annotated

import typer

from rssm_dsl import __version__
from rssm_dsl.commands import COMMANDS
from rssm_dsl.commands.common import EXIT_INTERRUPTED

app = typer.Typer(
    name="rssmc",
    help="Compile, check and verify RSSM robot-controller specifications (hierarchical Petri nets).",
    no_args_is_help=True,
    add_completion=True,         # --install-completion, --show-completion (bash, zsh, fish, PowerShell)
    pretty_exceptions_enable=False,
)


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


def _register_commands() -> None:
    """Each command lives in rssm_dsl/commands/<name>.py with a `register(app)` function;
    command modules import their heavy dependencies inside the command body, and what they
    share from rssm_dsl/commands/common.py (never from this module)."""
    for name in COMMANDS:
        importlib.import_module(f"rssm_dsl.commands.{name}").register(app)


_register_commands()


def entry() -> None:
    """Console-script entry point."""
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(EXIT_INTERRUPTED)
