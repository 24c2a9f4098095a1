"""The determinism rule and the comparison of tests/ros2/differential.py, without ROS: which
subsystems the rule calls deterministic, and that the comparison finds what a faulty node
would do (a switch, a data case, a value taken that the interpreter's run excludes), while
accepting what timing may change."""

from __future__ import annotations

import copy
from pathlib import Path

from tests.conftest import ROOT
from tests.ros2 import differential
from tests.ros2.conftest import SPECS

SEM = ROOT / "examples" / "semantics"


def _det(spec: Path) -> set[str]:
    system = differential.compile_spec(spec).system
    assert system is not None
    return differential.deterministic_subsystems(system)


def test_the_rule() -> None:
    assert _det(SPECS / "relay.rssm") == {"src.c", "dst.c", "dst.e.arm"}     # all blocking
    assert _det(SEM / "mode_bb.rssm") == {"fast_src.c", "slow_src.c", "fast_dst.c",
                                          "slow_dst.c"}
    for mode in ("bn", "nb", "nn"):                 # a non-blocking side: consumers depend on timing
        assert _det(SEM / f"mode_{mode}.rssm") == {"fast_src.c", "slow_src.c"}
    # a cycle of blocking channels is deterministic (it deadlocks, always at the same point)
    assert _det(ROOT / "examples" / "verify" / "deadlock_pair.rssm") == {"left.c", "right.c"}
    # a device feeds it: not deterministic, nor what depends on it
    assert _det(SPECS / "deploy.rssm") == set()


def _nodes_like(run: differential.InterpreterRun, n: int) -> dict[str, differential.Record]:
    """Node records that did the first n iterations of the interpreter's run."""
    out = {}
    for sid, r in run.records.items():
        rec = differential.Record(switches=list(r.switches[:1]), iterations=r.iterations[:n])
        for buffer, values in r.received.items():
            rec.received[buffer] = values[:n]
            rec.seqs[buffer] = list(range(1, len(values[:n]) + 1))
        out[sid] = rec
    return out


def test_the_comparison(tmp_path: Path) -> None:
    spec = SEM / "mode_bn.rssm"
    system = differential.compile_spec(spec).system
    assert system is not None
    run = differential.interpreter_records(spec, tmp_path / "i.jsonl", until=10.0)
    nodes = _nodes_like(run, 5)
    ok = differential.compare(system, run, nodes)
    assert ok.mismatches == [], ok.mismatches
    assert ok.full == ["fast_src.c", "slow_src.c"] and ok.compared_values == 10

    # a non-blocking consumer may find nothing new in some iterations: not a mismatch
    timing = copy.deepcopy(nodes)
    it = timing["fast_dst.c"].iterations
    it.insert(1, (it[1][0], [False], it[1][2]))
    assert differential.compare(system, run, timing).mismatches == []

    wrong = copy.deepcopy(nodes)                    # a data case the interpreter did not take
    b, new, cases = wrong["fast_src.c"].iterations[2]
    wrong["fast_src.c"].iterations[2] = (b, new, [c + 1 for c in cases])
    assert any("fast_src.c iterations: #2" in m
               for m in differential.compare(system, run, wrong).mismatches)

    wrong = copy.deepcopy(nodes)                    # a value that was not the sample's
    wrong["slow_dst.c"].received["x"][3] += 100
    assert any("slow_dst.c.x: sample 4" in m
               for m in differential.compare(system, run, wrong).mismatches)

    wrong = copy.deepcopy(nodes)                    # a blocking producer's sample skipped
    wrong["fast_dst.c"].seqs["x"][2:] = [s + 1 for s in wrong["fast_dst.c"].seqs["x"][2:]]
    assert any("skipped" in m for m in differential.compare(system, run, wrong).mismatches)

    wrong = copy.deepcopy(nodes)                    # a switch the interpreter did not make
    wrong["slow_src.c"].switches[0] = (None, "read")
    assert differential.compare(system, run, wrong).mismatches


def test_a_complete_run_bounds_the_nodes(tmp_path: Path) -> None:
    spec = SPECS / "relay.rssm"                     # every subsystem deterministic, all end
    system = differential.compile_spec(spec).system
    assert system is not None
    run = differential.interpreter_records(spec, tmp_path / "i.jsonl")
    assert run.complete
    nodes = _nodes_like(run, 1000)
    for sid, r in run.records.items():
        nodes[sid].switches = list(r.switches)
    assert differential.compare(system, run, nodes).mismatches == []
    more = copy.deepcopy(nodes)                     # an iteration after the interpreter's last
    more["dst.e.arm"].switches.pop()
    more["dst.e.arm"].iterations.append(more["dst.e.arm"].iterations[-1])
    assert any("complete run" in m for m in differential.compare(system, run, more).mismatches)
    early = copy.deepcopy(nodes)                    # ended, but earlier than the interpreter
    early["src.c"].iterations.pop()
    assert any("both ended" in m for m in differential.compare(system, run, early).mismatches)
