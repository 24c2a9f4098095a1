"""Joint-space tracking of the arms of the standard library's ``robots`` module.

:func:`run_arms_tracking` runs a compiled system deterministically on simulated time with an
observer on every device bound to ``rssm_stdlib.robots.device:MujocoArmDevice``, and measures
how each arm's joints follow the joint set points (a record with ``q: float[n]`` and
optionally ``dq: float[n]``) that the virtual effector driving the device receives from
another subsystem. The desired joint positions at a device step at time ``t`` are the last set
point ``(q, dq)`` sent on that channel, held to first order from the tick ``t_c`` of the
subsystem that sent it: ``q + dq (t - t_c)`` (as the Cartesian recorder of ``rssmc run``).
The run may stop after ``switches`` behaviour switches of the first arm's control subsystem
(the arms in the order the system declares their devices). :func:`run_joint_tracking` is the
same run measured on the first arm.

``rssmc run`` uses it for a system without the LWR4+ experiment's parts (its outputs:
joints_report.py); ``bench/panda.py`` for its figures.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.pipeline import Compilation
from rssm_dsl.semantics.model import Device, System
from rssm_dsl.semantics.types import ArrayT, RecordT

ARM_BINDING = "rssm_stdlib.robots.device:MujocoArmDevice"
FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class JointRig:
    device: str                # "a1.E.arm"
    effector: str              # "a1.e.arm"
    control: str               # "a1.c"
    setpoint_channel: str


@dataclass(frozen=True)
class JointTracking:
    rig: JointRig
    t: FloatArray              # (n,) s, device steps that had a set point
    desired: FloatArray        # (n, dof) rad
    actual: FloatArray         # (n, dof) rad
    simulated: float           # s
    wall: float                # s the interpreter ran
    device_steps: int
    firings: int
    reason: str
    ok: bool
    diagnostics: tuple[Diagnostic, ...]
    message: str = ""
    robot: str = ""
    behaviour: tuple[str, ...] = ()            # (n,) the control subsystem's behaviour
    switches: tuple[tuple[float, str | None, str | None], ...] = ()   # (t, from, to)
    cpu: float = 0.0

    @property
    def error(self) -> FloatArray:
        return np.asarray(self.actual - self.desired, dtype=np.float64)

    @property
    def rms_per_joint(self) -> FloatArray:
        return np.asarray(np.sqrt(np.mean(self.error ** 2, axis=0)), dtype=np.float64)

    @property
    def rms(self) -> float:
        """RMS over all joints and samples (rad)."""
        return float(np.sqrt(np.mean(self.error ** 2)))

    @property
    def max_abs(self) -> float:
        return float(np.max(np.abs(self.error)))

    @property
    def us_per_step(self) -> float:
        return self.wall / self.device_steps * 1e6 if self.device_steps else float("nan")


def _is_joint_setpoint(t: Any) -> bool:
    return isinstance(t, RecordT) and isinstance(t.field("q"), ArrayT)


def _rig_of(system: System, device: Device, subsystems: set[str]) -> JointRig | Diagnostic:
    feeding = [ch for ch in system.channels
               if ch.consumer.owner == device.id and ch.producer.owner in subsystems]
    if not feeding:
        return Diagnostic("E870", f"no virtual effector sends commands to {device.id}",
                          device.span)
    effector = feeding[0].producer.owner
    setpoints = [ch for ch in system.channels
                 if ch.consumer.owner == effector and ch.producer.owner in subsystems
                 and _is_joint_setpoint(ch.consumer.type)]
    if not setpoints:
        return Diagnostic("E870", f"{effector} receives no joint set points (a record with "
                          "`q: float[n]`) from another subsystem", device.span)
    ch = setpoints[0]
    return JointRig(device.id, effector, ch.producer.owner, ch.id)


def find_joint_rigs(system: System) -> list[JointRig] | Diagnostic:
    """One rig per device bound to the arm class, in declaration order; E870 at the first
    device whose effector or set points are missing."""
    devices = [d for d in system.devices() if d.binding == ARM_BINDING]
    if not devices:
        return Diagnostic("E870", f"system {system.name} has no device bound to "
                          f"{ARM_BINDING}", system.span)
    subsystems = {s.id for s in system.subsystems()}
    rigs: list[JointRig] = []
    for device in devices:
        rig = _rig_of(system, device, subsystems)
        if isinstance(rig, Diagnostic):
            return rig
        rigs.append(rig)
    return rigs


def find_joint_rig(system: System) -> JointRig | Diagnostic:
    """The first arm's rig (:func:`find_joint_rigs`)."""
    rigs = find_joint_rigs(system)
    return rigs if isinstance(rigs, Diagnostic) else rigs[0]


class _Observer:
    def __init__(self, rt: Any, rig: JointRig, stop_after: int) -> None:
        self._now = rt.clock.now
        self._channel = rt.channels[rig.setpoint_channel]
        self._control = control = rt.subsystems[rig.control]
        ticker = control.ticker
        self._period: int | None = ticker.period if ticker is not None else None
        self._stop_after = stop_after
        self._switches: int = control.switches
        self._behaviour: str | None = control.behaviour
        self.switches: list[tuple[float, str | None, str | None]] = []
        self.behaviour: list[str] = []
        self._sent = 0
        self._setpoint: tuple[FloatArray, FloatArray | None, int] | None = None
        self.t: list[float] = []
        self.desired: list[FloatArray] = []
        self.actual: list[FloatArray] = []

    def _tick(self, now: int) -> int:
        return now if self._period is None else now // self._period * self._period

    def __call__(self, device: Any) -> None:
        from rssm_dsl.interp.errors import StopSimulation

        now = self._now()
        ch = self._channel
        if ch.sent != self._sent:
            self._sent = ch.sent
            self._setpoint = (ch.value["q"], ch.value.get("dq"), self._tick(now))
        control = self._control
        if control.switches != self._switches:
            self._switches = control.switches
            self.switches.append((self._tick(now) / 1e9, self._behaviour, control.behaviour))
            if len(self.switches) == self._stop_after:
                raise StopSimulation("switches", f"{control.model.id} switched behaviours "
                                     f"{len(self.switches)} times by t = {now / 1e9:g} s")
        self._behaviour = control.behaviour
        if self._setpoint is None:
            return
        q, dq, tick = self._setpoint
        desired = q if dq is None else q + dq * ((now - tick) / 1e9)
        self.t.append(now / 1e9)
        self.desired.append(np.asarray(desired, dtype=np.float64))
        self.actual.append(device.state["q"])
        self.behaviour.append(self._behaviour or "")


class JointRunError(ValueError):
    """The run cannot start; ``diagnostics`` say why."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        super().__init__("; ".join(d.message for d in diagnostics))
        self.diagnostics = diagnostics


def run_joint_tracking(comp: Compilation, until: float, seed: int = 0, switches: int = 0,
                       trace: Path | None = None) -> JointTracking:
    """Run ``comp`` until ``until`` s (or ``switches`` behaviour switches of the first arm's
    control subsystem, if positive) and measure the first arm's joint tracking; JointRunError
    when the system has no such rig or cannot be set up."""
    return run_arms_tracking(comp, until, seed, switches, trace)[0]


def run_arms_tracking(comp: Compilation, until: float, seed: int = 0, switches: int = 0,
                      trace: Path | None = None) -> tuple[JointTracking, ...]:
    """Run ``comp`` as :func:`run_joint_tracking` does and measure every arm's tracking (one
    result per arm, in declaration order, sharing the run's figures)."""
    from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
    from rssm_dsl.interp.errors import SetupError
    from rssm_dsl.interp.trace import TraceWriter

    system = comp.system
    if system is None or not comp.ok:
        raise ValueError("run_arms_tracking needs a specification that compiled cleanly")
    rigs = find_joint_rigs(system)
    if isinstance(rigs, Diagnostic):
        raise JointRunError([rigs])
    try:
        rt = build_runtime(comp, RunConfig(base_dir=comp.path.resolve().parent))
    except SetupError as e:
        raise JointRunError(list(e.diagnostics)) from None
    observers = [_Observer(rt, rig, switches if switches > 0 and k == 0 else -1)
                 for k, rig in enumerate(rigs)]
    devices: list[Any] = [rt.devices[rig.device].impl for rig in rigs]
    for device, observer in zip(devices, observers, strict=True):
        device.observers.append(observer)
    tracer = TraceWriter(trace) if trace is not None else None
    rt.tracer = tracer
    sim = Simulator(rt, SimOptions(seed=seed, until=until,
                                   trace_info={"spec": str(comp.path)}))
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        result = sim.run()
    finally:
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        if tracer is not None:
            tracer.close()
    runs = []
    for rig, device, observer in zip(rigs, devices, observers, strict=True):
        n = len(observer.t)
        runs.append(JointTracking(
            rig=rig, t=np.array(observer.t, dtype=np.float64),
            desired=np.array(observer.desired, dtype=np.float64).reshape(n, -1),
            actual=np.array(observer.actual, dtype=np.float64).reshape(n, -1),
            simulated=result.time, wall=wall, device_steps=rt.devices[rig.device].steps,
            firings=result.steps, reason=result.reason, ok=result.ok,
            diagnostics=tuple(result.diagnostics), message=result.message,
            robot=getattr(getattr(device, "robot", None), "name", ""),
            behaviour=tuple(observer.behaviour), switches=tuple(observer.switches), cpu=cpu))
    return tuple(runs)
