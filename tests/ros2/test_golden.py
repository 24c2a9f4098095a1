"""Golden files: every file `rssmc ros2` generates for each example and each test
specification (the copies of the runtime modules are checked against their source in
test_generate.py, the shipped user modules are listed in COPIES.txt). Update with
`pytest --update-goldens` (refused in CI)."""

from __future__ import annotations

from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.ros2.generator import generate
from tests.conftest import ROOT, example_specs
from tests.hpn.test_golden import check_golden
from tests.ros2.conftest import SPECS

GOLDEN = ROOT / "tests" / "golden" / "ros2"
SPEC_FILES = [*example_specs(), SPECS / "relay.rssm", SPECS / "wire.rssm",
              SPECS / "tricky.rssm", SPECS / "deploy.rssm"]


def _name(spec: Path) -> str:
    return spec.relative_to(ROOT).with_suffix("").as_posix().replace("/", "__")


@pytest.mark.parametrize("spec", SPEC_FILES, ids=lambda p: p.stem)
def test_workspace_golden(spec: Path, update_goldens: bool,
                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)
    comp = compile_file(spec.relative_to(ROOT))
    ws = generate(comp)
    assert not isinstance(ws, list), ws
    folder = GOLDEN / _name(spec)
    runtime = f"{ws.view.runtime.name}/{ws.view.runtime.name}/"
    files = {rel: text for rel, text in ws.files.items()
             if not (rel.startswith(runtime) and rel != runtime + "__init__.py")}
    copies = "".join(f"{rel} <- {src.relative_to(ROOT).as_posix()}\n"
                     for rel, src in sorted(ws.copies.items()))
    files["COPIES.txt"] = copies
    for rel, text in files.items():
        check_golden(folder / rel, text, update_goldens)
    if folder.exists():
        stale = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*")
                       if p.is_file() and p.relative_to(folder).as_posix() not in files)
        assert not stale, f"golden files no longer generated: {stale}"
