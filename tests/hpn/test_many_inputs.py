"""A control subsystem with many inputs (one per robot of a fleet): the net holds the cases
its text distinguishes (rssm_dsl/semantics/cases.py), not 2^nu of them, so it checks,
compiles, verifies and simulates, and its size grows linearly with the inputs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import CondKind
from rssm_dsl.pipeline import compile_file
from tests.conftest import ROOT
from tests.hpn.fleet import fleet

SIZES = (24, 64)


def _write(tmp_path: Path, n: int, cases: bool) -> Path:
    path = tmp_path / f"fleet{n}{'_cases' if cases else ''}.rssm"
    path.write_text(fleet(n, cases), encoding="utf-8")
    return path


def _rssmc(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600)


@pytest.mark.parametrize("cases", [False, True], ids=["no-case", "cases-over-2"])
def test_the_net_grows_linearly_with_the_inputs(tmp_path: Path, cases: bool) -> None:
    sizes = {}
    for n in (6, *SIZES):
        comp = compile_file(_write(tmp_path, n, cases))
        assert comp.ok and comp.hpn is not None, [d.message for d in comp.diagnostics]
        assert not [d for d in comp.diagnostics if d.is_error]
        hpn = comp.hpn
        coord = next(s for a in comp.system.agents for s in a.subsystems  # type: ignore[union-attr]
                     if a.name == "coord")
        assert len(coord.inputs) == n
        # the coordinator's cases: one without case clauses, 2^2 over new(s1), new(s2)
        memory = coord.behaviours[0].functions[-1]
        assert len(memory.cases) == (4 if cases else 1)
        case_conditions = [t.condition for t in hpn.transitions.values()
                           if t.condition is not None and t.condition.kind is CondKind.CASE
                           and t.condition.subsystem == "coord.c"]
        assert len(case_conditions) == len(memory.cases)
        net = flatten(hpn)
        sizes[n] = (len(hpn.places), len(hpn.transitions), len(net.places), len(net.transitions))
        # a few dozen elements per robot (its own agent, subsystem and behaviour pages, a
        # channel, a receive page in the coordinator), nothing exponential
        assert all(x <= 40 * (n + 1) for x in sizes[n]), sizes[n]
    for small, large in zip(sizes[6], sizes[64], strict=True):
        # linear: the growth from 6 to 64 robots is about 64 / 6, not 2^58
        assert large / small < 64 / 6 * 1.2


@pytest.mark.parametrize("n", SIZES)
def test_check_compile_verify_and_simulate(tmp_path: Path, n: int) -> None:
    spec = _write(tmp_path, n, cases=True)
    r = _rssmc("check", spec)
    assert r.returncode == 0 and "0 errors" in r.stdout + r.stderr, r.stderr
    r = _rssmc("compile", spec, "-o", tmp_path / "out", "--emit", "json,dump")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "out").is_dir()
    # the interleavings of n+1 agents are many: a verdict on a bounded search (safeness is
    # proved by place invariants, deadlocks stay open at the state limit)
    r = _rssmc("verify", spec, "--max-states", "20000", "--reduction", "on")
    assert r.returncode == 3, r.stdout + r.stderr
    assert r.stdout.startswith("system fleet: INCONCLUSIVE")
    assert "safeness:   safe (proved by place invariants)" in r.stdout
    assert "Traceback" not in r.stdout + r.stderr
    r = _rssmc("simulate", spec, "--steps", "3000", "--seed", "1")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "stopped after 3000 firings" in r.stdout + r.stderr
    # every robot's channel carried data to the coordinator
    assert all(f"r{k}.c.s{k}->coord.c.s{k}" in r.stdout for k in range(1, n + 1))
