"""The exporters do work proportional to the net: no per-page scan of the tables.

Performance is measured by benchmarks (bench/compile.py prints the export times), not by
timed tests; here the work is counted instead, exactly: the Python events (calls, lines,
loop iterations) an exporter executes on generated systems of 10 and 30 agents. Linear work
grows as the net does (x3); a scan of every table per page would grow about x9."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

import pytest

from rssm_dsl.emit import EMITTERS
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import HPN, HpnIndex
from rssm_dsl.hpn.wellformed import violations
from rssm_dsl.pipeline import compile_file
from rssm_dsl.render.names import figure_files
from rssm_dsl.render.svg import figures
from rssm_dsl.synth import ring_system

SMALL, LARGE = 10, 30

WORK: dict[str, Callable[[HPN], object]] = {
    **{f"emit {name}": emitter for name, emitter in EMITTERS.items() if name != "json"},
    "index": HpnIndex.build,
    "flatten": flatten,
    "wellformed": violations,
    "figures": lambda hpn: figures(hpn, figure_files(hpn)),
}


def events(work: Callable[[], object]) -> int:
    """How many trace events (calls, lines, returns, ...) running ``work`` produces."""
    n = 0

    def tracer(frame: FrameType, event: str, arg: Any) -> Callable[..., Any]:
        nonlocal n
        n += 1
        return tracer

    sys.settrace(tracer)
    try:
        work()
    finally:
        sys.settrace(None)
    return n


@pytest.fixture(scope="module")
def systems(tmp_path_factory: pytest.TempPathFactory) -> dict[int, HPN]:
    out: dict[int, HPN] = {}
    for n in (SMALL, LARGE):
        path: Path = tmp_path_factory.mktemp("ring") / f"ring{n}.rssm"
        path.write_text(ring_system(n), encoding="utf-8")
        hpn = compile_file(path).hpn
        assert hpn is not None
        hpn.index()                      # built once per net; counted on its own ("index")
        out[n] = hpn
    return out


def size(hpn: HPN) -> int:
    return len(hpn.pages) + len(hpn.places) + len(hpn.transitions) + len(hpn.arcs)


@pytest.mark.parametrize("name", list(WORK))
def test_work_grows_as_the_net(systems: dict[int, HPN], name: str) -> None:
    work = WORK[name]
    small, large = systems[SMALL], systems[LARGE]
    growth = size(large) / size(small)
    assert 2.9 < growth < 3.1
    counted = events(lambda: work(large)) / events(lambda: work(small))
    assert counted < 1.1 * growth, f"{name}: work x{counted:.2f} for a net x{growth:.2f}"
