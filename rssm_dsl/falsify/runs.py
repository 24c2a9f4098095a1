"""One seeded random run of the interpreter for the falsifier: deterministic mode on
simulated time, the devices that measure values of finite type bound to ``RandomDevice``
(their measurements drawn from their types, or from the user's ``values`` option; see
:func:`random_devices`), the choice among the enabled transitions made by the run's seed.
The firing sequence is recorded (every firing goes through the simulator's per-transition
firing code, macro steps off), so that what the run ends in can be confirmed in the net.
"""

from __future__ import annotations

import time
from array import array
from collections.abc import Callable
from fnmatch import fnmatchcase
from pathlib import Path

from rssm_core.records import dataclass
from rssm_dsl.interp.errors import SetupError, StopSimulation
from rssm_dsl.interp.program import RunConfig, build_runtime
from rssm_dsl.interp.scheduler import SimOptions, Simulator
from rssm_dsl.interp.summary import Snapshot
from rssm_dsl.interp.watchdog import STALL_PERIODS
from rssm_dsl.pipeline import Compilation
from rssm_dsl.semantics.types import ArrayT, RecordT, Type, finite_domain

RANDOM_DEVICE = "rssm_stdlib.devices.random_values:RandomDevice"
CONSTANT_DEVICE = "rssm_stdlib.devices.constant:ConstantDevice"
OUT_OF_TIME = "out-of-time"       # the reason of a run the falsifier's deadline stopped


@dataclass
class RunOutcome:
    """What one random run did: how it ended (the interpreter's reason: steps, until,
    finished, deadlock, stalled, error, ... or ``out-of-time``) and its firing sequence
    (transition indices of the interpreter's flat net, which the verifier's flattening
    reproduces)."""

    seed: int
    reason: str
    message: str
    steps: int
    time: float                       # simulated seconds
    sequence: array[int]
    names: tuple[str, ...]            # the transitions of the run's net, by index
    stalled: tuple[str, ...] = ()     # the subsystems of an E809
    codes: tuple[str, ...] = ()       # the codes of the run's diagnostics


class RunSetupError(Exception):
    """The specification cannot be run (a binding of an extern is missing, ...)."""


def _recording(fire: list[Callable[[], None]], out: array[int]) -> None:
    """Wrap each transition's firing code so that it appends its index to ``out`` first.
    The code is compiled when first called, which puts it in its place in ``fire``: the
    wrapper then takes the compiled code and puts itself back."""
    append = out.append

    def wrap(t: int, f: Callable[[], None]) -> Callable[[], None]:
        inner = f

        def fired() -> None:
            nonlocal inner
            append(t)
            inner()
            if fire[t] is not fired:        # compiled on this first call
                inner = fire[t]
                fire[t] = fired
        return fired

    for t, f in enumerate(fire):
        fire[t] = wrap(t, f)


def _drawn(t: Type) -> bool:
    """Does a value of ``t`` have a part RandomDevice draws (of a finite type)?"""
    if finite_domain(t) is not None:
        return True
    if isinstance(t, RecordT):
        return any(_drawn(ft) for _, ft in t.fields)
    if isinstance(t, ArrayT):
        return _drawn(t.element)
    return False


def random_devices(comp: Compilation,
                   device_options: dict[str, dict[str, str]]) -> dict[str, str]:
    """The devices bound to RandomDevice: those with an output of finite type (or a part of
    one) and those given a ``values`` option. The others (float measurements: a simulated
    arm, wheels echoing their set points) keep their own binding, which the runs need to
    move at all; one without a binding measures its initial values (ConstantDevice)."""
    assert comp.system is not None
    out: dict[str, str] = {}
    for d in comp.system.devices():
        given = any("values" in opts for pattern, opts in device_options.items()
                    if fnmatchcase(d.id, pattern))
        if given or any(_drawn(b.type) for b in d.outputs):
            out[d.id] = RANDOM_DEVICE
        elif d.binding is None:        # nothing to run it with: its initial values
            out[d.id] = CONSTANT_DEVICE
    return out


def random_run(comp: Compilation, seed: int, max_steps: int, until: float,
               seconds: float, deadline: Callable[[], float],
               stop_requested: Callable[[], bool],
               device_options: dict[str, dict[str, str]] | None = None,
               stall_periods: int = STALL_PERIODS) -> RunOutcome:
    """Run the specification once with ``seed``, until ``max_steps`` firings, simulated time
    ``until``, a stop of the run (deadlock, stall, error, termination), ``seconds`` of
    wall-clock time from its first firing (the set-up not counted), the wall-clock
    ``deadline()`` (``time.monotonic()``, asked once the set-up is done) or
    ``stop_requested()``."""
    options: dict[str, dict[str, str]] = {"*": {"seed": str(seed)}}
    for pattern, given in (device_options or {}).items():
        options.setdefault(pattern, {}).update(given)
    config = RunConfig(base_dir=Path(comp.path).resolve().parent,
                       devices=random_devices(comp, device_options or {}),
                       device_options=options)
    try:
        rt = build_runtime(comp, config)
    except SetupError as e:
        raise RunSetupError("; ".join(f"{d.code} {d.message}" for d in e.diagnostics)) from e

    ends = float("inf")

    def watch(snapshot: Snapshot) -> None:
        if time.monotonic() > ends or stop_requested():
            raise StopSimulation(OUT_OF_TIME, "the falsifier's time is up")

    sequence: array[int] = array("i")
    sim = Simulator(rt, SimOptions(mode="deterministic", seed=seed, max_steps=max_steps,
                                   until=until, macros=False, progress=watch,
                                   progress_interval=0.05, stall_periods=stall_periods))
    _recording(sim.fire, sequence)
    ends = min(deadline(), time.monotonic() + seconds)
    result = sim.run()
    return RunOutcome(seed, result.reason, result.message, result.steps, result.time,
                      sequence, tuple(t.name for t in rt.net.transitions),
                      tuple(sorted(sim.stalled)),
                      tuple(d.code for d in result.diagnostics))
