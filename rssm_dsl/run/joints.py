"""Joint-space tracking of any arm of the standard library's ``robots`` module.

:func:`run_joint_tracking` runs a compiled system deterministically on simulated time with an
observer on its first device bound to ``rssm_stdlib.robots.device:MujocoArmDevice``, and
measures how the joints follow the joint set points (a record with ``q: float[n]`` and
optionally ``dq: float[n]``) that the virtual effector driving the device receives from
another subsystem. The desired joint positions at a device step at time ``t`` are the last set
point ``(q, dq)`` sent on that channel, held to first order from the tick ``t_c`` of the
subsystem that sent it: ``q + dq (t - t_c)`` (as the Cartesian recorder of ``rssmc run``).
The run may stop after ``switches`` behaviour switches of that subsystem.

``rssmc run`` uses it for a system without the LWR4+ experiment's parts
(:func:`joint_output_files`, :func:`joint_summary_text`); ``bench/panda.py`` for its figures.
"""

from __future__ import annotations

import io
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.pipeline import Compilation
from rssm_dsl.semantics.model import System
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


def find_joint_rig(system: System) -> JointRig | Diagnostic:
    devices = [d for d in system.devices() if d.binding == ARM_BINDING]
    if not devices:
        return Diagnostic("E870", f"system {system.name} has no device bound to "
                          f"{ARM_BINDING}", system.span)
    device = devices[0]
    subsystems = {s.id for s in system.subsystems()}
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
    """Run ``comp`` until ``until`` s (or ``switches`` behaviour switches of the control
    subsystem, if positive) and measure the joint tracking; JointRunError when the system has
    no such rig or cannot be set up."""
    from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
    from rssm_dsl.interp.errors import SetupError
    from rssm_dsl.interp.trace import TraceWriter

    system = comp.system
    if system is None or not comp.ok:
        raise ValueError("run_joint_tracking needs a specification that compiled cleanly")
    rig = find_joint_rig(system)
    if isinstance(rig, Diagnostic):
        raise JointRunError([rig])
    try:
        rt = build_runtime(comp, RunConfig(base_dir=comp.path.resolve().parent))
    except SetupError as e:
        raise JointRunError(list(e.diagnostics)) from None
    observer = _Observer(rt, rig, switches if switches > 0 else -1)
    device: Any = rt.devices[rig.device].impl
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
    n = len(observer.t)
    return JointTracking(
        rig=rig, t=np.array(observer.t, dtype=np.float64),
        desired=np.array(observer.desired, dtype=np.float64).reshape(n, -1),
        actual=np.array(observer.actual, dtype=np.float64).reshape(n, -1),
        simulated=result.time, wall=wall, device_steps=rt.devices[rig.device].steps,
        firings=result.steps, reason=result.reason, ok=result.ok,
        diagnostics=tuple(result.diagnostics), message=result.message,
        robot=getattr(getattr(device, "robot", None), "name", ""),
        behaviour=tuple(observer.behaviour), switches=tuple(observer.switches), cpu=cpu)


def joint_summary_dict(r: JointTracking) -> dict[str, Any]:
    return {
        "system_rig": {"control": r.rig.control, "effector": r.rig.effector,
                       "device": r.rig.device, "robot": r.robot},
        "reason": r.reason, "message": r.message,
        "simulated_s": r.simulated, "wall_s": r.wall, "cpu_s": r.cpu,
        "real_time_factor": r.simulated / r.wall if r.wall > 0 else None,
        "us_per_device_step": r.us_per_step, "device_steps": r.device_steps,
        "firings": r.firings, "samples": len(r.t),
        "rms_error_rad": r.rms if len(r.t) else None,
        "max_error_rad": r.max_abs if len(r.t) else None,
        "rms_error_per_joint_rad": [float(x) for x in r.rms_per_joint] if len(r.t) else [],
        "switches": [{"time": t, "from": a, "to": b} for t, a, b in r.switches],
    }


def joint_trajectory_csv(r: JointTracking) -> str:
    dof = r.actual.shape[1] if r.actual.ndim == 2 else 0
    head = (["t"] + [f"q{i + 1}_des" for i in range(dof)] + [f"q{i + 1}" for i in range(dof)]
            + ["error", "behaviour"])
    rows = [",".join(head)]
    err = np.sqrt(np.sum(r.error ** 2, axis=1)) if len(r.t) else np.zeros(0)
    for k in range(len(r.t)):
        values = [r.t[k], *r.desired[k], *r.actual[k], err[k]]
        rows.append(",".join(f"{v:.9g}" for v in values) + f",{r.behaviour[k]}")
    return "\n".join(rows) + "\n"


def joint_figure_png(r: JointTracking, dpi: int = 110) -> bytes:
    """(a) each joint and its desired position over time; (b) each joint's error (mrad)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11.0, 6.5), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True)
    for j in range(r.actual.shape[1] if len(r.t) else 0):
        line = top.plot(r.t, r.actual[:, j], lw=1.2, label=f"q{j + 1}")[0]
        top.plot(r.t, r.desired[:, j], ls="--", lw=0.9, color=line.get_color())
        bottom.plot(r.t, r.error[:, j] * 1e3, lw=1.0, color=line.get_color())
    for t, _, _ in r.switches:
        for ax in (top, bottom):
            ax.axvline(t, color="0.6", lw=0.8, ls=":")
    top.set_ylabel("joint position (rad); desired dashed")
    top.set_title(f"(a) joints of {r.rig.device} ({r.robot})", loc="left")
    top.legend(ncols=7, fontsize=8, loc="upper right")
    bottom.set_ylabel("error q - q_des (mrad)")
    bottom.set_xlabel("t (s)")
    bottom.set_title(f"(b) tracking error: RMS {r.rms * 1e3:.3f} mrad" if len(r.t) else
                     "(b) tracking error", loc="left")
    for ax in (top, bottom):
        ax.grid(True, lw=0.4, alpha=0.5)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


def joint_output_files(r: JointTracking) -> dict[str, str | bytes]:
    return {
        "trajectory.csv": joint_trajectory_csv(r),
        "summary.json": json.dumps(joint_summary_dict(r), indent=2) + "\n",
        "joints.png": joint_figure_png(r),
    }


def joint_summary_text(r: JointTracking, system: str) -> str:
    lines = [f"{system}: {r.rig.control} -> {r.rig.effector} -> {r.rig.device} "
             f"({r.robot} simulated by MuJoCo, joint space)"]
    lines.append(f"  simulated  {r.simulated:.3f} s: {r.device_steps} device steps, "
                 f"{r.firings:,} firings ({r.message})")
    rtf = r.simulated / r.wall if r.wall > 0 else float("inf")
    lines.append(f"  wall       {r.wall:.3f} s: {rtf:.1f}x real time, {r.us_per_step:.1f} us "
                 f"per device step")
    if len(r.t):
        lines.append(f"  tracking   joint RMS {r.rms * 1e3:.3f} mrad, max {r.max_abs * 1e3:.3f} "
                     f"mrad, {len(r.t)} samples")
        lines.append("  per joint  RMS " + " ".join(f"{x * 1e3:.3f}" for x in r.rms_per_joint)
                     + " mrad")
    else:
        lines.append("  tracking   no set point arrived")
    if r.switches:
        lines.append(f"  switches   {r.rig.control}: " + "; ".join(
            f"{a} -> {b} at {t:.2f} s" for t, a, b in r.switches))
    return "\n".join(lines)
