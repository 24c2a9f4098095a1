"""Robot descriptions: which model file, which joints, which end-effector frame.

A robot is an entry of a TOML table, found by the name a specification gives it (the member of
an enum parameter ``robot`` of the device type, e.g. ``Robot.panda``):

.. code-block:: toml

    [panda]
    model = "robot-data:panda_description/urdf/panda.urdf"   # MJCF (.xml) or URDF (.urdf)
    joints = ["panda_joint1", "panda_joint2", ...]           # actuated, in the order of q
    ee = "panda_hand_tcp"                                    # a site, or a body / URDF link
    q0 = [0.0, -0.785, ...]                                  # start pose (rad), optional
    armature = 0.1                                           # kg m^2, scalar or per joint
    torque_limits = [87.0, ...]                              # N m, optional
    collisions = true                                        # URDF: keep collision geoms

The tables searched, first match wins: ``robots.toml`` in the specification's folder, then the
standard library's (this folder). A model path is resolved relative to the folder of the table
that names it (never the working directory); ``robot-data:REL`` names a file of the package
``example-robot-data`` (``pip install 'rssmc[robots]'``), ``rssm_stdlib:REL`` a file of the
standard library.

The same description gives both models: MuJoCo (:func:`build_mujoco`; the listed joints keep
their degrees of freedom and get one torque motor each, every other joint is removed, so the
links it moved are welded to their parent; URDF visuals are dropped, and so are its collision
elements unless ``collisions = true``: then its meshes are read, ``package://NAME/...`` from
a folder NAME above the URDF or from example-robot-data's share folder) and Pinocchio
(:func:`build_pinocchio`; the other joints locked at 0).
"""

from __future__ import annotations

import functools
import importlib.metadata
import math
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rssm_core.records import dataclass

Vector = NDArray[np.float64]

STDLIB_DIR = Path(__file__).resolve().parent.parent
TABLE_NAME = "robots.toml"
EE_SITE = "rssm_ee"
"""The site added to the MuJoCo model at the end-effector frame (when ``ee`` is a body)."""
INSTALL_HINT = "pip install 'rssmc[robots]'"


class RobotModelError(Exception):
    """A robot description or its model file is unusable; the message says what and where."""


@dataclass(frozen=True)
class RobotDescription:
    name: str
    model: Path                       # absolute path of the MJCF or URDF file
    joints: tuple[str, ...]
    ee: str
    q0: tuple[float, ...]
    armature: tuple[float, ...]
    torque_limits: tuple[float, ...]  # inf: unlimited
    timestep: float
    table: Path                       # the TOML file that describes it
    collisions: bool = False          # URDF: keep its collision elements (contacts)

    @property
    def is_urdf(self) -> bool:
        return self.model.suffix.lower() == ".urdf"

    @property
    def dof(self) -> int:
        return len(self.joints)


def robot_data_dir() -> Path:
    """The ``robots`` folder of the package example-robot-data (RobotModelError without it)."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise RobotModelError(f"the package example-robot-data is not installed: "
                              f"{INSTALL_HINT}") from None
    folder = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    if not folder.is_dir():
        raise RobotModelError(f"example-robot-data has no folder {folder}")
    return folder


def resolve_model_path(text: str, base: Path) -> Path:
    """The model file named by ``text`` in a table of the folder ``base``."""
    if text.startswith("robot-data:"):
        path = robot_data_dir() / text.removeprefix("robot-data:")
    elif text.startswith("rssm_stdlib:"):
        path = STDLIB_DIR / text.removeprefix("rssm_stdlib:")
    else:
        path = Path(text).expanduser()
        if not path.is_absolute():
            path = base / path
    if not path.is_file():
        raise RobotModelError(f"model file {text!r} not found (looked for {path})")
    if path.suffix.lower() not in (".xml", ".urdf"):
        raise RobotModelError(f"model file {path}: expected an MJCF .xml or a .urdf file")
    return path


def _floats(entry: dict[str, Any], key: str, n: int, default: float, where: str,
            ) -> tuple[float, ...]:
    value = entry.get(key, default)
    if isinstance(value, int | float) and not isinstance(value, bool):
        return (float(value),) * n
    if (isinstance(value, list) and len(value) == n
            and all(isinstance(x, int | float) and not isinstance(x, bool) for x in value)):
        return tuple(float(x) for x in value)
    raise RobotModelError(f"{where}: {key} must be a number or a list of {n} numbers")


@functools.cache
def _read_table(path: Path) -> dict[str, Any]:
    try:
        with path.open("rb") as f:
            return tomllib.load(f)
    except (OSError, tomllib.TOMLDecodeError) as e:
        raise RobotModelError(f"{path}: {e}") from None


def describe(name: str, entry: dict[str, Any], table: Path) -> RobotDescription:
    """The description of robot ``name`` from its table entry (checks the shape only)."""
    where = f"{table} [{name}]"
    if not isinstance(entry, dict):
        raise RobotModelError(f"{where}: expected a table")
    unknown = set(entry) - {"model", "joints", "ee", "q0", "armature", "torque_limits",
                            "timestep", "collisions"}
    if unknown:
        raise RobotModelError(f"{where}: unknown keys {', '.join(sorted(unknown))}")
    model, joints, ee = entry.get("model"), entry.get("joints"), entry.get("ee")
    if not isinstance(model, str):
        raise RobotModelError(f"{where}: model must be a file name")
    if (not isinstance(joints, list) or not joints
            or not all(isinstance(j, str) for j in joints)):
        raise RobotModelError(f"{where}: joints must be a non-empty list of joint names")
    if len(set(joints)) != len(joints):
        raise RobotModelError(f"{where}: a joint is listed twice")
    if not isinstance(ee, str):
        raise RobotModelError(f"{where}: ee must name a site, body or link")
    n = len(joints)
    collisions = entry.get("collisions", False)
    if not isinstance(collisions, bool):
        raise RobotModelError(f"{where}: collisions must be true or false")
    timestep = entry.get("timestep", 0.001)
    if not isinstance(timestep, float | int) or not 0 < timestep <= 0.1:
        raise RobotModelError(f"{where}: timestep must be in (0, 0.1] s")
    return RobotDescription(
        name=name, model=resolve_model_path(model, table.parent), joints=tuple(joints), ee=ee,
        q0=_floats(entry, "q0", n, 0.0, where),
        armature=_floats(entry, "armature", n, 0.0, where),
        torque_limits=_floats(entry, "torque_limits", n, math.inf, where),
        timestep=float(timestep), table=table, collisions=collisions)


def find_robot(name: str, spec_dir: Path | None) -> RobotDescription:
    """Robot ``name`` from ``spec_dir/robots.toml`` or the standard library's table."""
    tables = [spec_dir / TABLE_NAME] if spec_dir is not None else []
    tables.append(STDLIB_DIR / "robots" / TABLE_NAME)
    for table in tables:
        if table.is_file():
            entries = _read_table(table.resolve())
            if name in entries:
                return describe(name, entries[name], table.resolve())
    looked = " and ".join(str(t) for t in tables)
    raise RobotModelError(f"no robot {name!r} in {looked}")


# --- MuJoCo ---------------------------------------------------------------------------------

def resolve_mesh(filename: str, urdf: Path) -> Path:
    """The mesh file a URDF names: ``package://NAME/REST`` in a folder NAME above the URDF or
    in example-robot-data's share folder, a ``file://`` or plain path relative to the URDF."""
    if filename.startswith("package://"):
        package, _, rest = filename.removeprefix("package://").partition("/")
        candidates = [folder / rest for folder in urdf.parents if folder.name == package]
        if package == "example-robot-data":
            candidates.append(robot_data_dir().parent / rest)
        for candidate in candidates:
            if candidate.is_file():
                return candidate
        raise RobotModelError(f"{urdf}: mesh {filename!r} not found (no folder {package} "
                              "above the URDF holds it)")
    path = Path(filename.removeprefix("file://"))
    path = path if path.is_absolute() else urdf.parent / path
    if not path.is_file():
        raise RobotModelError(f"{urdf}: mesh {filename!r} not found (looked for {path})")
    return path


def _urdf_for_mujoco(path: Path, collisions: bool = False) -> tuple[str, dict[str, float]]:
    """The URDF without visuals (and without collisions unless ``collisions``: meshes then
    named by absolute paths), with static links kept as bodies (so any link can be the end
    effector); and the joints' effort limits."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError) as e:
        raise RobotModelError(f"{path}: {e}") from None
    for link in root.iter("link"):
        for tag in ("visual",) if collisions else ("visual", "collision"):
            for element in link.findall(tag):
                link.remove(element)
    if collisions:
        for mesh in root.iter("mesh"):
            mesh.set("filename", str(resolve_mesh(mesh.get("filename", ""), path)))
    for old in root.findall("mujoco"):
        root.remove(old)
    extension = ET.SubElement(root, "mujoco")
    ET.SubElement(extension, "compiler", fusestatic="false", discardvisual="true",
                  strippath="false")
    efforts: dict[str, float] = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is not None and limit.get("effort") is not None:
            efforts[joint.get("name", "")] = float(limit.get("effort", "inf"))
    return ET.tostring(root, encoding="unicode"), efforts


def build_mujoco(robot: RobotDescription) -> tuple[Any, Vector, Vector]:
    """The MuJoCo model of ``robot`` and its torque limits (low, high), one motor per listed
    joint in the listed order, the end-effector site :data:`EE_SITE` (or ``ee`` itself when it
    is a site)."""
    import mujoco  # type: ignore[import-untyped]

    efforts: dict[str, float] = {}
    try:
        if robot.is_urdf:
            text, efforts = _urdf_for_mujoco(robot.model, robot.collisions)
            spec = mujoco.MjSpec.from_string(text)
        else:
            spec = mujoco.MjSpec.from_file(str(robot.model))
    except ValueError as e:
        raise RobotModelError(f"{robot.model}: MuJoCo cannot read it: {e}") from None
    names = [j.name for j in spec.joints]
    missing = [j for j in robot.joints if j not in names]
    if missing:
        raise RobotModelError(f"{robot.model}: no joint {', '.join(map(repr, missing))} "
                              f"(joints: {', '.join(names)})")
    frcrange: dict[str, tuple[float, float]] = {}
    for joint in list(spec.joints):
        if joint.name not in robot.joints:
            spec.delete(joint)
        elif joint.type not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE):
            raise RobotModelError(f"{robot.model}: joint {joint.name!r} is not a hinge or "
                                  "slide joint")
        elif joint.actfrclimited == mujoco.mjtLimited.mjLIMITED_TRUE:
            frcrange[joint.name] = (float(joint.actfrcrange[0]), float(joint.actfrcrange[1]))
    for equality in list(spec.equalities):          # mimic joints of removed fingers, ...
        spec.delete(equality)
    for actuator in list(spec.actuators):
        spec.delete(actuator)
    low = np.empty(robot.dof)
    high = np.empty(robot.dof)
    for i, name in enumerate(robot.joints):
        joint = spec.joint(name)
        joint.armature = joint.armature + robot.armature[i]
        limit = robot.torque_limits[i]
        if math.isinf(limit) and name in efforts and efforts[name] > 0:
            limit = efforts[name]
        lo, hi = (-limit, limit) if not math.isinf(limit) else frcrange.get(
            name, (-math.inf, math.inf))
        low[i], high[i] = lo, hi
        motor = spec.add_actuator()
        motor.name = f"rssm_{name}"
        motor.target = name
        motor.trntype = mujoco.mjtTrn.mjTRN_JOINT
        # a direct torque motor whatever the model's defaults say (the device clips)
        motor.dyntype = mujoco.mjtDyn.mjDYN_NONE
        motor.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        motor.biastype = mujoco.mjtBias.mjBIAS_NONE
        motor.gainprm = np.eye(1, 10).ravel()
        motor.biasprm = np.zeros(10)
        motor.gear = np.eye(1, 6).ravel()
        motor.ctrllimited = mujoco.mjtLimited.mjLIMITED_FALSE
        motor.forcelimited = mujoco.mjtLimited.mjLIMITED_FALSE
    sites = {s.name for s in spec.sites}
    if robot.ee not in sites:
        body = next((b for b in spec.bodies if b.name == robot.ee), None)
        if body is None:
            raise RobotModelError(f"{robot.model}: no site, body or link {robot.ee!r}")
        body.add_site().name = EE_SITE
    spec.option.timestep = robot.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    try:
        model = spec.compile()
    except ValueError as e:
        raise RobotModelError(f"{robot.model}: MuJoCo cannot compile it: {e}") from None
    return model, low, high


def ee_site_name(robot: RobotDescription, model: Any) -> str:
    import mujoco

    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, robot.ee) >= 0:
        return robot.ee
    return EE_SITE


# --- Pinocchio ------------------------------------------------------------------------------

def build_pinocchio(robot: RobotDescription) -> tuple[Any, int]:
    """The Pinocchio model of ``robot`` (joints other than the listed ones locked at 0, the
    listed ones in the listed order) and the id of the end-effector frame."""
    import pinocchio as pin  # type: ignore[import-untyped]

    try:
        if robot.is_urdf:
            full = pin.buildModelFromUrdf(str(robot.model))
        else:
            full = pin.buildModelFromMJCF(str(robot.model))
    except (ValueError, RuntimeError) as e:
        raise RobotModelError(f"{robot.model}: Pinocchio cannot read it: {e}") from None
    names = list(full.names)[1:]
    missing = [j for j in robot.joints if j not in names]
    if missing:
        raise RobotModelError(f"{robot.model}: no joint {', '.join(map(repr, missing))} "
                              f"(joints: {', '.join(names)})")
    lock = [full.getJointId(n) for n in names if n not in robot.joints]
    model = pin.buildReducedModel(full, lock, pin.neutral(full)) if lock else full
    order = [model.getJointId(n) for n in robot.joints]
    if order != sorted(order) or any(model.joints[j].nv != 1 for j in order):
        raise RobotModelError(f"{robot.model}: the joints must be 1-dof joints listed from "
                              "the base outwards")
    if not model.existFrame(robot.ee):
        raise RobotModelError(f"{robot.model}: no frame {robot.ee!r} for Pinocchio")
    model.armature = model.armature + np.asarray(robot.armature)
    return model, int(model.getFrameId(robot.ee))
