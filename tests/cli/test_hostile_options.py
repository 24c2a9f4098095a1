"""Hostile values of the numeric options of every command: a usage error E890 (exit 2) before
anything runs or is written, never an internal error (E900, exit 70) or a traceback.

The options are found in the commands' own parsers, so that a numeric option added later is
covered too."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path
from typing import Any

import click
import pytest
import typer
from typer.testing import CliRunner

from rssm_dsl.cli import make_app
from tests.conftest import EXAMPLES, ROOT

SPEC = EXAMPLES / "semantics" / "iteration.rssm"
TRACKER = EXAMPLES / "camera_tracker.rssm"
LWR4 = EXAMPLES / "lwr4_circle.rssm"
HOSTILE = ["nan", "inf", "-inf", "-1", "0", "1e308", "1e999", "", "0x10", "1_000", "NaN",
           "1e3x", "٣", " 7 ", "1" * 5000]
# numeric options that the command reads as text (a size: 8G, 40%)
TEXT_NUMBERS = [("verify", "--max-memory")]


def numeric_options() -> list[tuple[str, str]]:
    group = typer.main.get_command(make_app())
    assert isinstance(group, click.Group)
    found = [(name, param.opts[0])
             for name, command in sorted(group.commands.items())
             for param in command.params
             if isinstance(param, click.Option) and not param.is_flag
             and isinstance(param.type, click.types.IntParamType | click.types.FloatParamType)]
    return found + TEXT_NUMBERS


OPTIONS = numeric_options()


def test_every_command_s_numbers_are_found() -> None:
    assert {("simulate", "--until"), ("simulate", "--steps"), ("simulate", "--seed"),
            ("simulate", "--workers"), ("simulate", "--stall-periods"),
            ("verify", "--timeout"), ("verify", "--max-states"), ("verify", "--seed"),
            ("render", "--max-steps"), ("render", "--from-step"), ("render", "--from-time"),
            ("run", "--until"), ("run", "--switches"),
            ("run", "--seed")} <= set(OPTIONS)


def accepted(command: str, option: str, value: str) -> bool:
    """Whether the value is one the option takes (the rest must be E890)."""
    text = value.strip()
    if text == "7":                 # blanks around a number are the shell's business
        return True
    if option == "--max-memory":
        return False
    if text == "inf":
        return (command, option) == ("verify", "--timeout")
    return text == "0" and (command, option) not in {
        ("simulate", "--workers"), ("verify", "--max-states"), ("verify", "--timeout")}


def base_args(command: str, option: str, out: Path) -> list[str]:
    """A quick, valid command line around the option."""
    if command == "simulate":
        bound = [] if option in ("--steps", "--until") else ["--steps", "20"]
        return [str(SPEC), "--no-live", "-q", "--trace", str(out / "trace.jsonl"), *bound]
    if command == "verify":
        return [str(SPEC), "--format", "json", "--promela", str(out / "net.pml")]
    if command == "render":
        return [str(SPEC), "-o", str(out / "render")]
    if command == "run":
        until = [] if option == "--until" else ["--until", "0"]
        return [str(LWR4), "-o", str(out / "run"), "-q", *until]
    raise AssertionError(f"no command line for {command}: add one")


def invoke(args: list[str]) -> Any:
    return CliRunner().invoke(make_app(), args)


@pytest.mark.parametrize("value", HOSTILE, ids=lambda v: repr(v)[:12])
@pytest.mark.parametrize(("command", "option"), OPTIONS, ids=lambda x: str(x))
def test_hostile_number(command: str, option: str, value: str, tmp_path: Path) -> None:
    out = tmp_path / "out"
    if accepted(command, option, value) and command == "run":
        pytest.skip("a valid value: the experiment itself is tested in tests/run")
    result = invoke([command, *base_args(command, option, out), option, value])
    text = result.stdout + result.stderr
    assert result.exit_code != 70, text
    assert "Traceback" not in text and "E900" not in text, text
    assert result.exception is None or isinstance(result.exception, SystemExit), text
    if accepted(command, option, value):
        return
    assert result.exit_code == 2, text
    assert "[E890]" in result.stderr, result.stderr
    assert not out.exists() or not any(out.iterdir()), "a rejected command wrote something"


def test_help_shows_each_range() -> None:
    result = invoke(["simulate", "--help"])
    assert result.exit_code == 0
    assert "0<=x<=1000000000" in result.stdout and "1<=x<=1024" in result.stdout
    result = invoke(["verify", "--help"])
    assert result.exit_code == 0 and "inf: no time limit" in result.stdout


# ---------------------------------------------------------- the reported cases, as a user runs them

def rssmc(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("until", ["nan", "inf", "1e308"])
def test_simulate_until_out_of_range_is_a_usage_error(until: str, tmp_path: Path) -> None:
    trace = tmp_path / "t.jsonl"
    r = rssmc("simulate", TRACKER, "--until", until, "--trace", trace, "--no-live", cwd=ROOT)
    assert r.returncode == 2, r.stderr
    assert "error[E890]" in r.stderr and "--until" in r.stderr
    assert "Traceback" not in r.stderr and "E900" not in r.stderr
    assert not trace.exists()


@pytest.mark.parametrize(("option", "value"), [("--max-memory", "1e999G"),
                                               ("--timeout", "nan"),
                                               ("--timeout", "1e999"),
                                               ("--max-memory", "1_000")])
def test_verify_limits_out_of_range_are_usage_errors(option: str, value: str,
                                                     tmp_path: Path) -> None:
    promela = tmp_path / "net.pml"
    r = rssmc("verify", TRACKER, option, value, "--promela", promela, cwd=ROOT)
    assert r.returncode == 2, r.stdout + r.stderr
    assert "error[E890]" in r.stderr and option in r.stderr
    assert r.stdout == "" and not promela.exists()


def test_verify_timeout_inf_is_still_no_time_limit() -> None:
    result = invoke(["verify", str(SPEC), "--timeout", "inf", "--format", "json"])
    assert result.exit_code != 2, result.stderr
    assert '"time_seconds": null' in result.stdout


# ---------------------------------------------------------- values that are words or file names

WORD_CASES = [
    ("simulate", [str(SPEC), "--mode", "fast\x1b[2J"]),
    ("simulate", [str(SPEC), "--device", "nothing-to-bind"]),
    ("simulate", [str(SPEC), "--device-option", "x"]),
    ("simulate", [str(SPEC), "--plot", "OUT/fig.jpg"]),
    ("simulate", [str(SPEC), "--replay", "TRACE", "--mode", "concurrent"]),
    ("verify", [str(SPEC), "--reduction", "maybe"]),
    ("verify", [str(SPEC), "--fairness", "fair"]),
    ("ros2", [str(SPEC), "-o", "OUT/ws", "--maintainer", "nobody"]),
    ("render", [str(SPEC), "-o", "OUT/r", "--from-step", "3"]),
    ("run", [str(LWR4), "-o", "OUT/run", "--damping", "soft"]),
    ("run", [str(LWR4), "-o", "OUT/run", "--video", "OUT/v.avi"]),
]


@pytest.mark.parametrize(("command", "args"), WORD_CASES,
                         ids=[f"{c}-{a[1]}" for c, a in WORD_CASES])
def test_a_word_or_file_name_an_option_does_not_take_is_E890(
        command: str, args: list[str], tmp_path: Path) -> None:
    """An option's value that is no number but still not one the command takes: E890 with
    what to do, exit 2, nothing written (these said `rssmc: <message>` with no code)."""
    out = tmp_path / "out"
    trace = tmp_path / "t.jsonl"
    if "TRACE" in args:
        made = invoke(["simulate", str(SPEC), "--steps", "20", "-q", "--trace", str(trace)])
        assert made.exit_code == 0, made.stderr
    args = [a.replace("OUT", str(out)).replace("TRACE", str(trace)) for a in args]
    result = invoke([command, *args])
    assert result.exit_code == 2, result.stdout + result.stderr
    lines = result.stderr.splitlines()
    assert lines[0].startswith("rssmc: error[E890]: "), result.stderr
    assert lines[1].startswith("  help: "), result.stderr
    assert "\x1b" not in result.stderr
    assert not out.exists() or not any(out.rglob("*")), "a rejected command wrote something"
