"""The core install and its extras (rssm_dsl/extras.py): a command that needs a missing extra
prints one line naming it, with the `pip install` to type, and writes nothing; a device
module that imports a missing extra gets the same hint in its diagnostic. The real core
install (a fresh venv without the extras) is tests/test_wheel.py."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from rssm_dsl import extras
from rssm_dsl.bindings import BindingError, import_module
from rssm_dsl.cli import make_app
from tests.conftest import EXAMPLES


def _without(monkeypatch: pytest.MonkeyPatch, *gone: str) -> None:
    real = importlib.util.find_spec

    def find_spec(name: str, package: str | None = None) -> object:
        return None if name in gone else real(name, package)

    monkeypatch.setattr(extras.importlib.util, "find_spec", find_spec)


def test_every_extra_module_is_installed_here() -> None:
    assert extras.missing("run") == [] and extras.missing("video") == []
    assert extras.missing_message("rssmc run", "run") is None


def test_run_without_the_run_extra_says_which_in_one_line(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    _without(monkeypatch, "mujoco", "pinocchio")
    out = tmp_path / "out"
    result = CliRunner().invoke(make_app(), ["run", str(EXAMPLES / "lwr4_circle.rssm"), "-o", str(out),
                                      "--until", "0.01"])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert "'run' extra" in lines[0] and "mujoco, pinocchio" in lines[0]
    assert "pip install 'rssmc[run]'" in lines[0]
    assert not out.exists()


def test_a_device_module_needing_an_extra_gets_the_install_hint(
        monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setitem(sys.modules, "mujoco", None)        # import mujoco now fails
    (tmp_path / "needs_mujoco.py").write_text("import mujoco\n")
    with pytest.raises(BindingError) as e:
        import_module("needs_mujoco", [tmp_path])
    assert "'mujoco'" in e.value.message and (e.value.hint or "").startswith("pip install 'rssmc[run]'")
    (tmp_path / "needs_extra.py").write_text("import matplotlib_is_not_here.sub\n")
    with pytest.raises(BindingError) as e:
        import_module("needs_extra", [tmp_path])
    assert "matplotlib_is_not_here" in e.value.message
    # a module no extra provides: the generic hint
    assert e.value.hint is not None and "rssmc[" not in e.value.hint
    assert extras.hint_for("matplotlib.pyplot") == extras.install_command("run")
    assert "pip install -e '.[video]'" in (extras.hint_for("av") or "")
    assert extras.hint_for("numpy") is None
