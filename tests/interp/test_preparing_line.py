"""`rssmc simulate --live` says what it prepares on a slow start (issue 32, item 5: progress
within a second on any net): from one second on, the phase (compiling, building the
interpreter) and its seconds, redrawn in place and cleared before the run's own summary;
nothing on a quick start, nothing without --live."""

from __future__ import annotations

import time
from typing import Any

import pytest
from typer.testing import CliRunner

from rssm_dsl import pipeline
from rssm_dsl.cli import make_app
from rssm_dsl.commands import simulate
from tests.conftest import EXAMPLES

SPEC = EXAMPLES / "semantics" / "iteration.rssm"


def _simulate(*extra: str) -> Any:
    return CliRunner().invoke(make_app(), ["simulate", str(SPEC), "--until", "0.1", *extra])


@pytest.fixture
def slow_compile(monkeypatch: pytest.MonkeyPatch) -> None:
    real = pipeline.compile_file

    def slow(*args: Any, **kwargs: Any) -> Any:
        time.sleep(1.5)
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "compile_file", slow)
    # shown from 0.2 s on here (1 s in use): a loaded machine's thread still gets its turn
    monkeypatch.setattr(simulate._Preparing, "FIRST_AFTER", 0.2)


@pytest.mark.usefixtures("slow_compile")
def test_a_slow_compilation_is_shown_live_then_cleared() -> None:
    result = _simulate("--live")
    assert result.exit_code == 0, result.stderr
    assert "\rrssmc simulate: compiling (" in result.stderr and " s)\x1b[K" in result.stderr
    shown = result.stderr.rindex("rssmc simulate: compiling")
    cleared = result.stderr.index("\r\x1b[K", shown)
    assert "building the interpreter" not in result.stderr[cleared:]


@pytest.mark.usefixtures("slow_compile")
def test_without_live_nothing_is_shown() -> None:
    result = _simulate("--no-live")
    assert result.exit_code == 0, result.stderr
    assert "rssmc simulate: compiling" not in result.stderr


def test_a_quick_start_shows_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(simulate._Preparing, "FIRST_AFTER", 30.0)   # a start under 30 s
    result = _simulate("--live")
    assert result.exit_code == 0, result.stderr
    assert "rssmc simulate:" not in result.stderr
