"""Traces and counterexamples are fired on the flat net; bad ones are coded diagnostics."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.hpn.flat import FlatNet, FlatPlace, FlatTransition
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.render.playback import Window, load_playback
from rssm_dsl.source import Span
from rssm_dsl.verify.report import render_json
from rssm_dsl.verify.verifier import verify
from tests.render.support import lwr4_net, markings, random_run, write_trace

SPECS = Path(__file__).parent / "specs"


def test_simulate_trace_gives_the_markings_of_the_run(tmp_path: Path) -> None:
    net = lwr4_net()
    names = random_run(net, 400, seed=3)
    assert len(names) == 400  # the LWR4+ net never deadlocks
    bag = DiagnosticBag()
    pb = load_playback(write_trace(tmp_path / "t.jsonl", names), net, bag)
    assert not bag.items and pb is not None
    assert pb.kind == "trace"
    assert pb.initial == tuple(sorted(net.initial))
    assert [s.transition for s in pb.steps] == names
    assert [frozenset(s.marking) for s in pb.steps] == markings(net, names)
    assert all(not s.unsafe for s in pb.steps)
    # line numbers point into the file (other events are interleaved)
    lines = (tmp_path / "t.jsonl").read_text().splitlines()
    for s in pb.steps[:20]:
        assert json.loads(lines[s.line - 1])["transition"] == s.transition


@pytest.mark.parametrize("shape", ["list", "objects", "keyed", "report", "progress"])
def test_counterexample_documents(tmp_path: Path, shape: str) -> None:
    net = lwr4_net()
    names = random_run(net, 3000, seed=5)
    # a real cycle of the run: the marking after step j is the one after step i (i > 5)
    first: dict[frozenset[int], int] = {}
    i = j = 0
    for k, m in enumerate(markings(net, names), start=1):
        if k <= 5:
            continue
        if m in first:
            i, j = first[m], k
            break
        first[m] = k
    assert 5 < i < j
    names = names[:j]
    doc: object = {
        "list": names,
        "objects": [{"transition": n, "label": "x"} for n in names],
        "keyed": {"verdict": "deadlock", "counterexample": names},
        "report": {"verdict": "violated", "invariants": {"list": [{"proves_safe": ["x"]}]},
                   "deadlocks": [], "unsafe": {"kind": "unsafe", "steps": [
                       {"name": n, "file": "x", "line": 1} for n in names]}, "progress": []},
        "progress": {"kind": "progress", "steps": names[:5], "to_cycle": names[5:i],
                     "cycle": names[i:j]},
    }[shape]
    if shape == "progress":  # the steps, the way to the cycle, then the cycle twice
        names = names[:j] + names[i:j]
    path = tmp_path / "cex.json"
    path.write_text(json.dumps(doc, indent=2))
    bag = DiagnosticBag()
    pb = load_playback(path, net, bag)
    assert not bag.items and pb is not None
    assert pb.kind == {"report": "unsafe", "progress": "progress"}.get(shape, "counterexample")
    assert [s.transition for s in pb.steps] == names
    assert [frozenset(s.marking) for s in pb.steps] == markings(net, names)


def test_a_real_verifier_report_plays_its_deadlock(tmp_path: Path) -> None:
    comp = compile_file(SPECS / "blocking_deadlock.rssm")
    assert comp.ok and comp.hpn is not None
    net = flatten(comp.hpn)
    report = verify(net)
    assert report.deadlocks
    path = tmp_path / "report.json"
    path.write_text(render_json(report))
    bag = DiagnosticBag()
    pb = load_playback(path, net, bag)
    assert not bag.items and pb is not None
    assert pb.kind == "deadlock"
    assert [s.transition for s in pb.steps] == [t.name for t in report.deadlocks[0].steps]
    end = set(pb.steps[-1].marking)
    assert not [t for t in net.transitions if set(t.pre) <= end]  # nothing can fire
    assert {net.places[p].label for p in end} == set(report.deadlocks[0].marking)


def test_a_report_without_counterexample_is_E852(tmp_path: Path) -> None:
    path = tmp_path / "report.json"
    path.write_text(json.dumps({"verdict": "verified", "deadlocks": [], "unsafe": None,
                                "progress": [], "dead_transitions": [{"name": "t[in]"}]}))
    bag = DiagnosticBag()
    assert load_playback(path, lwr4_net(), bag) is None
    assert [d.code for d in bag.items] == ["E852"] and "verified" in bag.items[0].message


def test_a_long_trace_is_cut_with_W855(tmp_path: Path) -> None:
    net = lwr4_net()
    names = random_run(net, 30, seed=4)
    path = write_trace(tmp_path / "t.jsonl", names)
    bag = DiagnosticBag()
    pb = load_playback(path, net, bag, Window(max_steps=10))
    assert pb is not None and [s.transition for s in pb.steps] == names[:10]
    assert [d.code for d in bag.items] == ["W855"] and not bag.has_errors
    line = path.read_text().splitlines()[bag.items[0].span.line - 1]
    assert json.loads(line)["transition"] == names[10]


def _codes(bag: DiagnosticBag) -> list[tuple[str, int]]:
    return [(d.code, d.span.line) for d in bag.items]


def test_unknown_transition_is_E853_at_its_line(tmp_path: Path) -> None:
    net = lwr4_net()
    names = random_run(net, 3, seed=1)
    path = tmp_path / "t.jsonl"
    path.write_text("\n".join(json.dumps({"event": "fire", "transition": n})
                              for n in [*names, "t[9,nope]"]) + "\n")
    bag = DiagnosticBag()
    assert load_playback(path, net, bag) is None
    assert _codes(bag) == [("E853", 4)]
    assert "t[9,nope]" in bag.items[0].message


def test_transition_not_enabled_is_E854(tmp_path: Path) -> None:
    net = lwr4_net()
    path = tmp_path / "t.jsonl"
    path.write_text(json.dumps({"event": "fire", "transition": "t[out]"}) + "\n")
    bag = DiagnosticBag()
    assert load_playback(path, net, bag) is None
    assert _codes(bag) == [("E854", 1)]
    assert "p[1,out]" in bag.items[0].message  # the input place that is not marked


@pytest.mark.parametrize(("text", "line"), [
    ('{"event": "fire", "transition": "t[in]"}\nnot json\n', 2),
    ('{"event": "fire", "transition": "t[in]"}\n[1, 2]\n', 2),
    ('{"event": "fire", "transition": 3}\n{"event": "fire"}\n', 1),
    ('{"verdict": "safe"}', 1),
    ("", 1),
])
def test_unreadable_traces_are_E852(tmp_path: Path, text: str, line: int) -> None:
    path = tmp_path / "t.jsonl"
    path.write_text(text)
    bag = DiagnosticBag()
    pb = load_playback(path, lwr4_net(), bag)
    # an empty file is no trace (a run writes its header first), as `simulate --replay` says
    assert pb is None
    assert _codes(bag) == [("E852", line)]


def test_missing_and_binary_files_are_E852(tmp_path: Path) -> None:
    bag = DiagnosticBag()
    assert load_playback(tmp_path / "absent.jsonl", lwr4_net(), bag) is None
    (tmp_path / "bin").write_bytes(b"\xff\xfe\x00")
    assert load_playback(tmp_path / "bin", lwr4_net(), bag) is None
    assert [d.code for d in bag.items] == ["E852", "E852"]


def test_an_unsafe_firing_is_played_and_flagged(tmp_path: Path) -> None:
    span = Span("n.rssm", 1, 1, 1, 1)
    places = tuple(FlatPlace(i, f"p{i}", f"p{i}", span, (f"p{i}",)) for i in range(3))
    net = FlatNet("n", places, (
        FlatTransition(0, "t0", "t0", span, (0,), (1, 2)),
        FlatTransition(1, "t1", "t1", span, (1,), (0,)),
    ), frozenset({0}), frozenset())
    path = tmp_path / "cex.json"
    path.write_text(json.dumps({"counterexample": ["t0", "t1", "t0"]}))
    bag = DiagnosticBag()
    pb = load_playback(path, net, bag)
    assert not bag.items and pb is not None
    assert [s.unsafe for s in pb.steps] == [(), (), (2,)]
    assert pb.steps[-1].marking == (1, 2)
