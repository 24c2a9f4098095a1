"""`rssmc compile` on two processes (rssm_dsl/emit/outputs.py): the same bytes as one process
writes, and a failure in either leaves nothing and is reported as one process reports it."""

from __future__ import annotations

import gc
import hashlib
import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import Result
from typer.testing import CliRunner

from rssm_dsl.cli import make_app
from rssm_dsl.commands import common
from rssm_dsl.emit import outputs
from rssm_dsl.emit.outputs import STREAMS, split, write_compiled
from rssm_dsl.filenames import UnusableFileName
from rssm_dsl.hpn.ir import HPN
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.model import System
from rssm_dsl.synth import small_agents_system
from tests.conftest import EXAMPLES

SPEC = EXAMPLES / "lwr4_circle.rssm"
ALL = ["json", "dump", "dot", "pnml", "pnml-paged", "cpn", "mcc"]


@pytest.fixture(autouse=True)
def _collector_back() -> Iterator[None]:
    """A compile run in-process turns the cyclic collector off (one_shot): on again after."""
    yield
    common._one_shot = False
    gc.enable()


def _digests(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


@pytest.mark.parametrize("agents", [0, 400])    # the example; a net of many pieces
def test_the_streamed_outputs_are_the_emitters_texts(tmp_path: Path, agents: int) -> None:
    """What `rssmc compile` writes piece by piece is what each emitter returns whole."""
    from rssm_dsl.emit import EMITTERS
    from rssm_dsl.emit.mcc import emit_mcc

    spec = SPEC
    if agents:
        spec = tmp_path / "agents.rssm"
        spec.write_text(small_agents_system(agents), encoding="utf-8")
    comp = compile_file(spec)
    assert comp.hpn is not None
    for kind in ALL if not agents else ["json", "dump", "dot", "pnml"]:
        whole = emit_mcc(comp.hpn, comp.system) if kind == "mcc" else EMITTERS[kind](comp.hpn)
        streamed = {rel: "".join(pieces) for rel, pieces in STREAMS[kind](comp.hpn, comp.system)}
        assert streamed == whole, kind


def test_two_processes_write_the_bytes_one_writes(tmp_path: Path) -> None:
    comp = compile_file(SPEC)
    assert comp.hpn is not None
    one = write_compiled(tmp_path / "one", ALL, comp.hpn, comp.system, parallel=False)
    two = write_compiled(tmp_path / "two", ALL, comp.hpn, comp.system, parallel=True)
    assert [p.relative_to(tmp_path / "one") for p in one] == \
        [p.relative_to(tmp_path / "two") for p in two]
    assert _digests(tmp_path / "one") == _digests(tmp_path / "two")
    assert _leftovers(tmp_path) == ["one", "two"]          # no staging folder left


def test_the_outputs_are_split_in_two_groups_by_cost() -> None:
    mine, theirs = split(["json", "dump", "dot", "pnml"])
    assert sorted(mine + theirs) == ["dot", "dump", "json", "pnml"]
    assert mine and theirs
    assert split(["dump", "json"]) == (["json"], ["dump"])   # the costliest here, at once


def _failing(kind: str, error: Exception) -> outputs.Stream:
    def stream(hpn: HPN, system: System | None) -> outputs.Files:
        yield f"{kind}-first.txt", ["written before the failure"]
        raise error
    return stream


def _invoke(out: Path) -> Result:
    return CliRunner().invoke(make_app(), ["compile", str(SPEC), "-o", str(out), "-q"])


@pytest.mark.parametrize("side", ["parent", "child"])
@pytest.mark.parametrize(("error", "code", "shown"), [
    (ValueError("a bug in an emitter"), "E900", "ValueError: a bug in an emitter"),
    (OSError(28, "No space left on device", "/somewhere/out.json"), "E881",
     "No space left on device: '/somewhere/out.json'"),
    (UnusableFileName("a/b", "it contains '/'"), "E881", "cannot name a file"),
])
def test_a_failing_output_leaves_nothing_and_is_reported_as_one_process_reports_it(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, side: str, error: Exception,
        code: str, shown: str) -> None:
    monkeypatch.setattr(outputs, "PARALLEL_SIZE", 0)        # two processes on any net
    mine, theirs = split(["json", "dump", "dot", "pnml"])
    kind = (mine if side == "parent" else theirs)[0]
    monkeypatch.setitem(STREAMS, kind, _failing(kind, error))
    out = tmp_path / "out"
    result = _invoke(out)
    assert result.exit_code != 0 and f"[{code}]" in result.output, result.output
    assert shown in result.output, result.output
    assert _leftovers(tmp_path) == []        # no output folder, no staging folder


def test_an_error_the_child_cannot_send_as_it_is_reads_the_same(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    class Odd(Exception):
        def __init__(self, a: int, b: int) -> None:      # (not made again by pickle)
            super().__init__(f"odd {a + b}")

    monkeypatch.setattr(outputs, "PARALLEL_SIZE", 0)
    kind = split(["json", "dump", "dot", "pnml"])[1][0]
    monkeypatch.setitem(STREAMS, kind, _failing(kind, Odd(1, 2)))
    result = _invoke(tmp_path / "out")
    assert "[E900]" in result.output and "Odd: odd 3" in result.output, result.output
    assert _leftovers(tmp_path) == []


def test_when_both_fail_the_first_output_asked_for_is_reported(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(outputs, "PARALLEL_SIZE", 0)
    kinds = ["json", "dump", "dot", "pnml"]
    for kind in kinds:
        monkeypatch.setitem(STREAMS, kind, _failing(kind, ValueError(f"{kind} failed")))
    result = _invoke(tmp_path / "out")
    assert "ValueError: json failed" in result.output, result.output
    assert _leftovers(tmp_path) == []


def test_a_child_that_dies_leaves_nothing(tmp_path: Path,
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    def dies(hpn: HPN, system: System | None) -> outputs.Files:
        yield "dying.txt", ["half"]
        os._exit(3)

    monkeypatch.setattr(outputs, "PARALLEL_SIZE", 0)
    monkeypatch.setitem(STREAMS, split(["json", "dump", "dot", "pnml"])[1][0], dies)
    result = _invoke(tmp_path / "out")
    assert "[E900]" in result.output and "status 3" in result.output, result.output
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("size", [0, 10**9])             # two processes, one
def test_a_failure_leaves_no_folder_made_for_the_outputs(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, size: int) -> None:
    """The outputs are staged as they are made: the folders made for them (the target's
    missing parents) go too when one fails, as when nothing was written before all were
    made."""
    monkeypatch.setattr(outputs, "PARALLEL_SIZE", size)
    monkeypatch.setitem(STREAMS, "pnml", _failing("pnml", ValueError("late")))
    result = _invoke(tmp_path / "new" / "deeper" / "out")
    assert "ValueError: late" in result.output, result.output
    assert _leftovers(tmp_path) == []
