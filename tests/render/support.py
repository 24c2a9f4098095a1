"""Shared by the render tests: the LWR4+ example compiled once, and real firing sequences."""

from __future__ import annotations

import json
import random
from functools import cache
from pathlib import Path

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import Compilation, compile_file
from tests.conftest import EXAMPLES

LWR4 = EXAMPLES / "lwr4_circle.rssm"


@cache
def lwr4() -> Compilation:
    comp = compile_file(LWR4)
    assert comp.ok and comp.hpn is not None
    return comp


@cache
def lwr4_net() -> FlatNet:
    hpn = lwr4().hpn
    assert hpn is not None
    return flatten(hpn)


def random_run(net: FlatNet, steps: int, seed: int) -> list[str]:
    """A firing sequence of the net chosen at random among the enabled transitions."""
    rnd = random.Random(seed)
    marking = set(net.initial)
    names: list[str] = []
    for _ in range(steps):
        enabled = [t for t in net.transitions if all(p in marking for p in t.pre)]
        if not enabled:
            break
        t = rnd.choice(enabled)
        marking.difference_update(t.pre)
        marking.update(t.post)
        names.append(t.name)
    return names


def markings(net: FlatNet, names: list[str]) -> list[frozenset[int]]:
    """The marking after each firing, computed here independently of rssm_dsl.render."""
    by_name = {t.name: t for t in net.transitions}
    marking = set(net.initial)
    out = []
    for n in names:
        t = by_name[n]
        assert set(t.pre) <= marking
        marking = (marking - set(t.pre)) | set(t.post)
        out.append(frozenset(marking))
    return out


def write_trace(path: Path, names: list[str]) -> Path:
    """A trace in the JSON-lines form of `rssmc simulate`, with other events in between."""
    lines = []
    for k, n in enumerate(names):
        if k % 5 == 0:
            lines.append(json.dumps({"event": "behaviour", "subsystem": "a1.c", "behaviour": "cw"}))
        lines.append(json.dumps({"event": "fire", "transition": n, "time": k * 0.001}))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path
