"""Sample the experiment at every step of the LWR4+ device.

The recorder is an observer of the MuJoCo device (``MujocoLwr4Device.observers``): at the start
of each device step, before the physics advances, it reads the simulated clock, the end-effector
position MuJoCo computed for that instant, the set point the control subsystem last sent
(``desired``) and the control subsystem's behaviour. It only reads the run's state.

The desired position at time ``t`` is the last set point ``(p, v)`` sent on the set-point
channel, held to first order from the tick ``t_c`` of the control subsystem that sent it:
``p + v (t - t_c)`` (zero order when the set point has no velocity). That is the path the
control subsystem commands, whatever the effector makes of it, so the tracking error includes
the latency of the asynchronous communication.

The recorder also stops the run: after ``stop_after`` behaviour switches of the control
subsystem (the experiment's cw -> ccw -> cw) it raises the interpreter's
:class:`~rssm_dsl.interp.errors.StopSimulation` with reason ``switches``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from rssm_core.records import dataclass
from rssm_dsl.interp.clock import SimClock
from rssm_dsl.interp.errors import StopSimulation

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SwitchEvent:
    time: float                   # s, the tick of the control subsystem that switched
    source: str | None
    target: str | None


@dataclass(frozen=True)
class Samples:
    """What was recorded, one row per device step that had a set point."""

    t: FloatArray                 # (n,) s
    desired: FloatArray           # (n, 3) m
    actual: FloatArray            # (n, 3) m
    behaviour: tuple[str, ...]    # (n,) the control subsystem's behaviour ("" if none)
    q: FloatArray | None          # (n, 7) rad, when asked for (video)


class Recorder:
    """The device's observer is :meth:`observe` (a bound method costs less to call than an
    instance); call :meth:`samples` after the run. Per step it only appends to lists (the
    device's last measurement is read, not computed again); the desired positions are
    computed once at the end."""

    def __init__(self, clock: SimClock, channel: Any, control: Any,
                 control_period_ns: int | None, stop_after: int | None,
                 keep_q: bool = False) -> None:
        self._clock = clock                      # simulated time: its field ns is read
        self._channel = channel                  # rssm_dsl.interp.channels.ChannelState
        self._control = control                  # rssm_dsl.interp.state.SubsystemState
        self._period = control_period_ns
        self._stop_after = stop_after if stop_after is not None else -1
        self._keep_q = keep_q
        self._sent = 0
        self._behaviour: str | None = control.behaviour
        self._switches: int = control.switches
        self.switches: list[SwitchEvent] = []
        self.stopped = False
        # the set points (position, velocity or None, tick of c that sent it)
        self._setpoints: list[tuple[Any, Any, int]] = []
        self._k = -1                             # index of the current set point
        # one row per sample: time (ns), set point index, position, behaviour
        self._rows: list[tuple[int, int, FloatArray, str | None]] = []
        self._q: list[FloatArray] = []

    def _tick(self, now: int) -> int:
        """The control subsystem's tick at or before ``now`` (when it sent or switched)."""
        period = self._period
        return now if period is None else now // period * period

    def _setpoint(self, now: int) -> None:
        ch = self._channel
        self._sent = ch.sent
        value = ch.value
        self._setpoints.append((value["position"], value.get("velocity"), self._tick(now)))
        self._k = len(self._setpoints) - 1

    def _switch(self, now: int) -> None:
        control = self._control
        self._switches = control.switches
        self.switches.append(SwitchEvent(self._tick(now) / 1e9, self._behaviour,
                                         control.behaviour))
        if len(self.switches) == self._stop_after:
            self.stopped = True

    def observe(self, device: Any) -> None:
        now = self._clock.ns
        if self._channel.sent != self._sent:     # a new set point since the last step
            self._setpoint(now)
        control = self._control
        if control.switches != self._switches:   # a switch (the initial entry is not one)
            self._switch(now)
        behaviour = self._behaviour = control.behaviour
        if self._k >= 0:
            state = device.state                 # measured when the physics last advanced
            self._rows.append((now, self._k, state["position"], behaviour))
            if self._keep_q:
                self._q.append(state["q"])
        if self.stopped:
            raise StopSimulation("switches", f"{self._control.model.id} switched behaviours "
                                 f"{len(self.switches)} times by t = {now / 1e9:g} s")

    def samples(self) -> Samples:
        rows = self._rows
        n = len(rows)
        t = np.array([r[0] for r in rows], dtype=np.float64) / 1e9
        which = np.array([r[1] for r in rows], dtype=np.intp)
        sp = self._setpoints
        p = np.array([x[0] for x in sp], dtype=np.float64).reshape(len(sp), 3)
        v = np.array([np.zeros(3) if x[1] is None else x[1] for x in sp],
                     dtype=np.float64).reshape(len(sp), 3)
        t0 = np.array([x[2] for x in sp], dtype=np.float64) / 1e9
        desired = p[which] + v[which] * (t - t0[which])[:, None]
        actual = np.array([r[2] for r in rows], dtype=np.float64).reshape(n, 3)
        q = np.array(self._q, dtype=np.float64).reshape(n, -1) if self._keep_q else None
        return Samples(t, desired, actual, tuple(r[3] or "" for r in rows), q)
