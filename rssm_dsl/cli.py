"""The `rssmc` command line. Heavy modules are imported inside the commands so that
`rssmc --help` stays fast.

Exit codes (rssm_dsl/commands/common.py): 0 success (warnings allowed); 1 the specification
has errors (or, for verify, a property is violated); 2 a usage error; 70 internal error;
130 interrupted. `rssmc verify` adds 3 (inconclusive) and 4 (verified without the progress
check).
"""

from __future__ import annotations

import importlib
import math
import os
import re
import sys
from typing import IO, Annotated, Any

import click
import typer
from typer.core import TyperCommand

from rssm_dsl import __version__
from rssm_dsl.commands import COMMANDS, MODULE_OF
from rssm_dsl.commands.common import BAD_OPTION_VALUE, EXIT_INTERRUPTED, exit_now


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
    for info in app.registered_commands:
        if info.cls in (None, TyperCommand):
            info.cls = CheckedNumbersCommand
    return app


# ------------------------------------------------------------------ numeric options
# Every int and float option of every command is read by `IntOption` or `FloatOption`
# (installed by `CheckedNumbersCommand`): a plain decimal number (no nan, no inf unless the option gives it a
# meaning, no 0x10, no 1_000), within the option's range, else a usage error E890 (exit 2)
# before the command starts. The range: the option's own `min=`/`max=`, else 0 at the least,
# and at most the sane bound below (an option where a negative number means something must
# say so here).

SECONDS_MAX = 1e9           # 31 years; in nanoseconds still within a 64-bit integer
COUNT_MAX = 10**12
SEED_MAX = 2**63 - 1


class NumberRule:
    """What an option's number is (for the message), its bounds, and the meaning of inf
    when it has one."""

    def __init__(self, noun: str, high: float, low: float | None = None,
                 infinite: str | None = None) -> None:
        self.noun, self.high, self.low, self.infinite = noun, high, low, infinite


# (command, option) -> its rule; ("*", option) for every command
NUMBER_RULES: dict[tuple[str, str], NumberRule] = {
    ("*", "--until"): NumberRule("a number of seconds", SECONDS_MAX),
    ("*", "--from-time"): NumberRule("a time in seconds", SECONDS_MAX),
    ("verify", "--timeout"): NumberRule("a number of seconds", SECONDS_MAX,
                                        infinite="no time limit"),
    ("*", "--seed"): NumberRule("a seed", SEED_MAX, low=0),
    ("simulate", "--workers"): NumberRule("a number of worker threads", 1024),
    ("*", "--stall-periods"): NumberRule("a number of periods", 10**9),
    ("*", "--switches"): NumberRule("a number of behaviour switches", 10**9),
}
DEFAULT_INT = NumberRule("a whole number", COUNT_MAX)
DEFAULT_FLOAT = NumberRule("a number", SECONDS_MAX)

MAX_NUMBER_TEXT = 64        # longer is no number an option takes (int() stops at 4300 digits)
_INT_TEXT = re.compile(r"[+-]?[0-9]+\Z")
_FLOAT_TEXT = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
_INF_TEXT = re.compile(r"\+?(?:inf|infinity)\Z", re.IGNORECASE)


class OptionValueError(click.BadParameter):
    """A numeric option's value that the command does not accept: usage error E890."""

    def format_message(self) -> str:
        return self.message

    def show(self, file: IO[Any] | None = None) -> None:
        if file is None:
            file = sys.stderr
        click.echo(f"rssmc: error[{BAD_OPTION_VALUE}]: {self.message}", file=file)
        if self.ctx is not None:
            click.echo(f"  help: 'rssmc {self.ctx.info_name} --help' lists the options and "
                       "their ranges", file=file)


def _number(value: float) -> str:
    if isinstance(value, int) or (float(value).is_integer() and abs(value) < 1e16):
        return str(int(value))
    return f"{value:g}"


class _Checked:
    """An int or float option read strictly and checked against its range (E890); mixed
    into click's IntRange and FloatRange, so that the help shows the range."""

    min: Any
    max: Any
    min_open: bool
    max_open: bool
    is_int: bool = False
    rule: NumberRule = DEFAULT_FLOAT

    def _describe_range(self) -> str:
        low = "" if self.min is None else f"{_number(self.min)}{'<' if self.min_open else '<='}"
        high = "" if self.max is None else f"{'<' if self.max_open else '<='}{_number(self.max)}"
        inf = f"; inf: {self.rule.infinite}" if self.rule.infinite else ""
        return f"{low}x{high}{inf}"

    def describe(self) -> str:
        """'a number of seconds (from 0 to 1000000000)' and the like."""
        if self.min is None:
            span = f"at most {_number(self.max or 0)}"
        else:
            lowest = f"above {_number(self.min)}" if self.min_open else f"from {_number(self.min)}"
            span = f"{lowest} to {_number(self.max or 0)}"
        whole = "a whole number, " if self.is_int and "whole" not in self.rule.noun else ""
        extra = f", or inf for {self.rule.infinite}" if self.rule.infinite else ""
        return f"{self.rule.noun} ({whole}{span}){extra}"

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        from rssm_dsl.diagnostics.diagnostic import bound_text

        name = param.opts[0] if param is not None and param.opts else "the option"
        number: float | None = None
        if isinstance(value, int | float) and not isinstance(value, bool):
            number = value           # a default
            if math.isinf(number) and number > 0 and self.rule.infinite is not None:
                return number
        elif isinstance(value, str) and len(value) <= MAX_NUMBER_TEXT:
            text = value.strip()
            if self.rule.infinite is not None and _INF_TEXT.match(text):
                return math.inf
            if _INT_TEXT.match(text):
                number = int(text) if self.is_int else float(text)
            elif not self.is_int and _FLOAT_TEXT.match(text):
                number = float(text)
        shown = str(value)
        shown = bound_text(shown if shown and shown.isprintable() and shown.strip() == shown
                           else repr(shown))
        if number is None or not math.isfinite(number):
            raise OptionValueError(f"{name} {shown}: give {self.describe()}", ctx=ctx,
                                   param=param)
        below = self.min is not None and (number <= self.min if self.min_open
                                          else number < self.min)
        above = self.max is not None and (number >= self.max if self.max_open
                                          else number > self.max)
        if below or above:
            raise OptionValueError(f"{name} {shown}: too {'small' if below else 'large'}: "
                                   f"give {self.describe()}", ctx=ctx, param=param)
        return number


class IntOption(_Checked, click.IntRange):
    is_int = True


class FloatOption(_Checked, click.FloatRange):
    pass


def checked_number(command: str, param: click.Parameter) -> IntOption | FloatOption | None:
    """The strict reader of a numeric option of ``command`` (None: not a number option)."""
    kind = param.type
    if not isinstance(kind, click.types.IntParamType | click.types.FloatParamType):
        return None
    is_int = isinstance(kind, click.types.IntParamType)
    option = param.opts[0] if param.opts else param.name or ""
    rule = (NUMBER_RULES.get((command, option)) or NUMBER_RULES.get(("*", option))
            or (DEFAULT_INT if is_int else DEFAULT_FLOAT))
    low: float = rule.low if rule.low is not None else 0
    low_open = high_open = False
    high: float = rule.high
    if isinstance(kind, click.IntRange | click.FloatRange):
        if kind.min is not None:
            low, low_open = kind.min, kind.min_open
        if kind.max is not None and kind.max <= high:
            high, high_open = kind.max, kind.max_open
    checked: IntOption | FloatOption
    if is_int:
        checked = IntOption(int(low), int(high), low_open, high_open)
    else:
        checked = FloatOption(float(low), float(high), low_open, high_open)
    checked.rule = rule
    return checked


class CheckedNumbersCommand(TyperCommand):
    """A command whose int and float options are read by :class:`IntOption` and
    :class:`FloatOption` (`make_app` makes every command one)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        for param in self.params:
            checked = checked_number(self.name or "", param)
            if checked is not None:
                param.type = checked


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
