"""The tracking figures of a run on ROS 2, from what rssm_dsl/ros2/record.py recorded: the
same samples and metrics as ``rssmc run`` computes in the interpreter (rssm_dsl/run/recorder.py
and metrics.py), from the topics instead of the interpreter's state.

One sample per state the device published (its stamp is the instant of the measurement): the
actual end-effector position, and the desired one, the last set point ``(p, v)`` stamped at or
before that instant, held to first order from its stamp ``t_c`` (the control subsystem's
clock when it sent it): ``p + v (t - t_c)``, as the interpreter's recorder holds it. Samples
start with the first set point and end at the control subsystem's last recorded switch (the
interpreter's run stops there too).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from rssm_core.records import dataclass
from rssm_dsl.run.metrics import Metrics, measure
from rssm_dsl.run.recorder import Samples, SwitchEvent


@dataclass(frozen=True)
class Recording:
    setpoints: list[dict[str, Any]]     # kind, seq, t, position, velocity (by stamp)
    states: list[dict[str, Any]]
    switches: tuple[SwitchEvent, ...]


def load(path: Path) -> Recording:
    # JSON lines: records end at "\n" (json escapes it inside one; a U+2028 is no line end)
    rows = [json.loads(line) for line in path.read_text(encoding="utf-8").split("\n") if line]
    by_time = sorted(rows, key=lambda r: (r["t"], r.get("seq", 0)))
    return Recording([r for r in by_time if r["kind"] == "setpoint"],
                     [r for r in by_time if r["kind"] == "state"],
                     tuple(SwitchEvent(r["t"], r["from"] or None, r["to"] or None)
                           for r in rows if r["kind"] == "switch"))


def samples(rec: Recording) -> Samples:
    """The samples of the run: every state from the first set point to the last switch."""
    sp = rec.setpoints
    if not sp or not rec.states:
        empty = np.zeros((0, 3))
        return Samples(np.zeros(0), empty, empty, (), None)
    t_c = np.array([r["t"] for r in sp])
    p = np.array([r["position"] for r in sp], dtype=np.float64)
    v = np.array([r["velocity"] or (0.0, 0.0, 0.0) for r in sp], dtype=np.float64)
    end = rec.switches[-1].time if rec.switches else float("inf")
    states = [r for r in rec.states if t_c[0] <= r["t"] <= end + 1e-9]
    t = np.array([r["t"] for r in states], dtype=np.float64)
    which = np.searchsorted(t_c, t + 1e-9, side="right") - 1
    desired = p[which] + v[which] * (t - t_c[which])[:, None]
    actual = np.array([r["position"] for r in states], dtype=np.float64).reshape(len(t), 3)
    names = _behaviours(rec.switches, t)
    return Samples(t, desired, actual, names, None)


def _behaviours(switches: tuple[SwitchEvent, ...], t: Any) -> tuple[str, ...]:
    """The control subsystem's behaviour at each instant (the switches' sources, then
    targets)."""
    if not switches:
        return ("",) * len(t)
    times = np.array([s.time for s in switches])
    names = [switches[0].source or "", *(s.target or "" for s in switches)]
    return tuple(names[k] for k in np.searchsorted(times, t, side="left"))


def metrics(rec: Recording) -> Metrics:
    return measure(samples(rec))
