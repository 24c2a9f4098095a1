"""The `rssmc` command line. Heavy modules are imported inside the commands so that
`rssmc --help` stays fast.

Exit codes (rssm_dsl/commands/common.py): 0 success (warnings allowed); 1 the specification
has errors (or, for verify, a property is violated); 2 a usage error; 70 internal error;
130 interrupted. `rssmc verify` adds 3 (inconclusive) and 4 (verified without the progress
check).
"""

from __future__ import annotations

import importlib
import os
import sys
from typing import Annotated

import typer

from rssm_dsl import __version__
from rssm_dsl.commands import COMMANDS, MODULE_OF
from rssm_dsl.commands.common import EXIT_INTERRUPTED, exit_now


def _version(value: bool) -> None:
    if value:
        typer.echo(f"rssmc {__version__}")
        raise typer.Exit()


def main(
    version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                          help="Print the version and exit.")] = False,
) -> None:
    """rssmc: the RSSM compiler."""


def make_app(argv: list[str] | None = None) -> typer.Typer:
    """The `rssmc` application. Each command lives in rssm_dsl/commands/<name>.py with a
    `register(app)` function; command modules import their heavy dependencies inside the
    command body, and what they share from rssm_dsl/commands/common.py (never from this
    module).

    Given the command line, only the module of the command it names is registered: typer
    reads the signature of every registered command at each start. `--help`, a misspelt
    command and shell completion see them all."""
    app = typer.Typer(
        name="rssmc",
        help="Compile, check and verify RSSM robot-controller specifications (hierarchical Petri nets).",
        no_args_is_help=True,
        add_completion=True,     # --install-completion, --show-completion (bash, zsh, fish, PowerShell)
        pretty_exceptions_enable=False,
        suggest_commands=False,  # click (8.2 and later) suggests a misspelt command itself
    )
    app.callback()(main)
    names = COMMANDS
    if argv is not None and not any(k.startswith("_RSSMC_COMPLETE") for k in os.environ):
        first = next((a for a in argv[1:] if not a.startswith("-")), None)
        module = MODULE_OF.get(first, first) if first is not None else None
        if module in COMMANDS:
            names = (module,)
    for name in names:
        importlib.import_module(f"rssm_dsl.commands.{name}").register(app)
    return app


def entry() -> None:
    """Console-script entry point."""
    app = make_app(sys.argv)
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(EXIT_INTERRUPTED)
    except SystemExit as done:
        exit_now(done.code)     # a one-shot command ends here, without the teardown
        raise
