"""Find the experiment's parts in a compiled system: the simulated LWR4+ (a device of type
``LWR4Plus``, or any device bound to the MuJoCo LWR4+ class), the virtual effector that sends
it torques, and the channel of Cartesian set points that effector tracks (a record with a
``position: float[3]`` field, and optionally ``velocity: float[3]``) with the subsystem that
produces them (the control subsystem c of the paper)."""

from __future__ import annotations

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.semantics.model import Channel, Device, Subsystem, System
from rssm_dsl.semantics.types import BOOL, FLOAT, ArrayT, RecordT, Type

DEVICE_TYPE = "LWR4Plus"
DEVICE_BINDING = "rssm_stdlib.lwr4plus.device:MujocoLwr4Device"
DAMPING_PARAM = "damp_velocity_error"


@dataclass(frozen=True)
class Rig:
    device: str                # "a1.E.lwr"
    effector: str              # "a1.e.lwr": sends the device its torques
    control: str               # "a1.c": produces the set points the effector tracks
    setpoint_channel: str      # channel id, "a1.c.cmd->a1.e.lwr.setpoint"
    has_velocity: bool         # the set point carries a velocity (first-order hold)
    control_frequency: float | None
    device_frequency: float | None


def _vec3(t: Type | None) -> bool:
    return isinstance(t, ArrayT) and t.element == FLOAT and t.size == 3


def _field(t: Type, name: str) -> Type | None:
    return t.field(name) if isinstance(t, RecordT) else None


def is_setpoint(t: Type) -> bool:
    """A record with a ``position: float[3]`` field."""
    return _vec3(_field(t, "position"))


def find_rig(system: System) -> Rig | Diagnostic:
    """The rig of the experiment, or an E870 diagnostic saying what is missing."""
    devices = [d for d in system.devices()
               if d.device_type == DEVICE_TYPE or d.binding == DEVICE_BINDING]
    if not devices:
        return Diagnostic(
            "E870", f"system {system.name} has no simulated robot for `rssmc run`: no LWR4+ "
            "device and no device bound to the MuJoCo arm of the robots module",
            system.span, "declare `real effector NAME: LWR4Plus` (import lwr4plus), or a "
            "device type with `binding \"rssm_stdlib.robots.device:MujocoArmDevice\"` (any "
            "arm, joint space); `rssmc simulate` runs any system")
    device: Device = devices[0]
    subsystems: dict[str, Subsystem] = {s.id: s for s in system.subsystems()}
    feeding = [ch for ch in system.channels
               if ch.consumer.owner == device.id and ch.producer.owner in subsystems]
    if not feeding:
        return Diagnostic(
            "E870", f"no virtual effector sends commands to the LWR4+ {device.id}", device.span,
            "connect an effector's output (e.g. `output torque: JointVec7 to E.lwr`) to it")
    effector = subsystems[feeding[0].producer.owner]
    setpoints: list[Channel] = [
        ch for ch in system.channels
        if ch.consumer.owner == effector.id and ch.producer.owner in subsystems
        and is_setpoint(ch.consumer.type)]
    if not setpoints:
        return Diagnostic(
            "E870", f"{effector.id} receives no Cartesian set points from another subsystem",
            effector.span, "the experiment measures how the arm tracks the set points (a "
            "record with `position: Vec3`, e.g. CartesianSetpoint) that the effector receives "
            "from the control subsystem")
    ch = setpoints[0]
    control = subsystems[ch.producer.owner]
    return Rig(device=device.id, effector=effector.id, control=control.id,
               setpoint_channel=ch.id,
               has_velocity=_vec3(_field(ch.consumer.type, "velocity")),
               control_frequency=control.frequency, device_frequency=device.frequency)


def damping_param(system: System, rig: Rig) -> bool:
    """Whether the effector declares the ``damp_velocity_error: bool`` parameter."""
    effector = next(s for s in system.subsystems() if s.id == rig.effector)
    return any(p.name == DAMPING_PARAM and p.type == BOOL for p in effector.params)
