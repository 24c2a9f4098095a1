"""Run the experiment: bind the compiled system (the MuJoCo LWR4+ as its device), attach the
recorder (and the viewer) to the device, run the interpreter deterministically on simulated
time until the control subsystem has switched behaviours ``switches`` times (cw -> ccw -> cw:
one clockwise and one counter-clockwise circle) or the time limit, and collect the result."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import field
from pathlib import Path
from typing import Any

from rssm_core.records import dataclass
from rssm_dsl.bindings import BindingError, resolve
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.pipeline import Compilation
from rssm_dsl.run.metrics import Metrics, measure
from rssm_dsl.run.recorder import Recorder, Samples, SwitchEvent
from rssm_dsl.run.rig import DAMPING_PARAM, DEVICE_BINDING, Rig, damping_param, find_rig

DAMPING_FORMS = ("velocity-error", "paper")


class RunError(Exception):
    """The experiment cannot run; ``diagnostics`` say why (``usage``: a bad option)."""

    def __init__(self, diagnostics: list[Diagnostic], usage: bool = False) -> None:
        super().__init__("; ".join(d.message for d in diagnostics))
        self.diagnostics = diagnostics
        self.usage = usage


@dataclass(frozen=True)
class RunOptions:
    until: float = 30.0                    # s of simulated time at most
    switches: int = 2                      # stop after this many behaviour switches of c
    damping: str | None = None             # "paper" | "velocity-error" | None (the spec's)
    seed: int = 0
    trace: Path | None = None              # the interpreter's trace (JSON lines; slow)
    keep_q: bool = False                   # record the joint angles (for a video)
    observers: tuple[Callable[[Any], None], ...] = ()   # more device observers (viewer)
    device_options: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Experiment:
    spec: str
    system: str
    rig: Rig
    reason: str          # switches | until | stopped (an observer) | interrupted | error | ...
    message: str
    samples: Samples
    switches: tuple[SwitchEvent, ...]
    metrics: Metrics
    simulated: float                       # s
    wall: float                            # s of wall-clock time the interpreter ran
    cpu: float                             # s of CPU time of this process meanwhile
    firings: int
    device_steps: int
    params: dict[str, Any]                 # the effector's parameters as run
    diagnostics: tuple[Diagnostic, ...]
    ok: bool                               # the interpreter's verdict on the end (RunResult.ok)
    model: Any = None                      # the MuJoCo model (for rendering)

    @property
    def real_time_factor(self) -> float:
        return self.simulated / self.wall if self.wall > 0 else float("inf")

    @property
    def us_per_step(self) -> float:
        return self.wall / self.device_steps * 1e6 if self.device_steps else float("nan")

    @property
    def cpu_real_time_factor(self) -> float:
        """Simulated time over CPU time: what the machine gives when nothing else runs."""
        return self.simulated / self.cpu if self.cpu > 0 else float("inf")


def _device_class() -> type[Any]:
    obj = resolve(DEVICE_BINDING, [])
    assert isinstance(obj, type)
    return obj


def run_experiment(comp: Compilation, options: RunOptions) -> Experiment:
    """Run the experiment of a compiled specification; raises RunError when it cannot."""
    from rssm_dsl.interp import RunConfig, SimOptions, Simulator, build_runtime
    from rssm_dsl.interp.clock import SimClock
    from rssm_dsl.interp.errors import SetupError
    from rssm_dsl.interp.trace import TraceWriter

    system = comp.system
    if system is None or not comp.ok:
        raise ValueError("run_experiment needs a specification that compiled without errors")
    rig = find_rig(system)
    if isinstance(rig, Diagnostic):
        raise RunError([rig])
    if options.damping is not None:
        if options.damping not in DAMPING_FORMS:
            raise RunError([Diagnostic("E871", f"--damping must be one of "
                                       f"{', '.join(DAMPING_FORMS)}, not {options.damping!r}",
                                       system.span)], usage=True)
        if not damping_param(system, rig):
            model = next(s for s in system.subsystems() if s.id == rig.effector)
            raise RunError([Diagnostic(
                "E871", f"--damping needs the parameter `{DAMPING_PARAM}: bool` in {rig.effector}",
                model.span, f"declare `param {DAMPING_PARAM}: bool = true` and pass it to "
                "cartesian_impedance(...), as examples/lwr4_circle.rssm does")], usage=True)
    try:
        device_class = _device_class()
    except BindingError as e:                      # pragma: no cover - shipped with rssmc
        raise RunError([Diagnostic("E801", e.message, system.span, e.hint)]) from None

    config = RunConfig(base_dir=comp.path.resolve().parent,
                       devices={rig.device: DEVICE_BINDING},
                       device_options={rig.device: dict(options.device_options)})
    try:
        rt = build_runtime(comp, config)
    except SetupError as e:
        raise RunError(list(e.diagnostics)) from None
    device: Any = rt.devices[rig.device].impl
    if not isinstance(device, device_class):      # pragma: no cover - bound above
        rt.close_devices()
        raise RunError([Diagnostic("E870", f"{rig.device} is not the MuJoCo LWR4+",
                                   system.span)])
    effector = rt.subsystems[rig.effector]
    if options.damping is not None:
        effector.vars[DAMPING_PARAM] = options.damping == "velocity-error"
    control = rt.subsystems[rig.control]
    assert isinstance(rt.clock, SimClock)          # the run is deterministic
    recorder = Recorder(rt.clock, rt.channels[rig.setpoint_channel], control,
                        control.ticker.period if control.ticker is not None else None,
                        options.switches if options.switches > 0 else None, options.keep_q)
    device.observers.append(recorder.observe)
    device.observers.extend(options.observers)

    tracer = TraceWriter(options.trace) if options.trace is not None else None
    rt.tracer = tracer
    sim = Simulator(rt, SimOptions(seed=options.seed, until=options.until,
                                   trace_info={"spec": str(comp.path)}))
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        result = sim.run()
    finally:
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        if tracer is not None:
            tracer.close()
    reason, message = result.reason, result.message
    samples = recorder.samples()
    params = {p.name: effector.vars[p.name] for p in effector.model.params}
    return Experiment(
        spec=str(comp.path), system=system.name, rig=rig, reason=reason, message=message,
        samples=samples, switches=tuple(recorder.switches), metrics=measure(samples),
        simulated=result.time, wall=wall, cpu=cpu, firings=result.steps,
        device_steps=rt.devices[rig.device].steps, params=params,
        diagnostics=tuple(result.diagnostics), ok=result.ok, model=device.arm.model)
