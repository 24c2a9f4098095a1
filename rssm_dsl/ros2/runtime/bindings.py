"""Load the Python side of a specification in a node: external operations (``extern``) and
device classes, each named ``module:attribute``. The generator ships the modules found next
to the specification or in rssmc's standard library inside the workspace's runtime package;
other modules must be installed in the Python environment ROS 2 runs in."""

from __future__ import annotations

import importlib
from typing import Any

from .params import SetupError

# Python modules of the standard library's physics (the MuJoCo-bound devices and their
# controllers' Pinocchio externs) and what installs them in the ROS venv
_PINNED = "pip install -r rssm_dsl/ros2/requirements-physics.txt (of rssmc)"
PHYSICS_PACKAGES = {"mujoco": _PINNED, "pinocchio": _PINNED,
                    "example_robot_data": "pip install example-robot-data"}


def load(module: str, attribute: str, what: str) -> Any:
    """The object ``module:attribute`` names (the attribute may be dotted)."""
    try:
        obj: Any = importlib.import_module(module)
    except ImportError as e:
        top = (e.name or "").split(".")[0]
        if top in PHYSICS_PACKAGES and top != module.split(".")[0]:
            raise SetupError(f"{what}: module '{module}' needs '{top}', which is not installed "
                             f"in the Python environment of ROS 2: {PHYSICS_PACKAGES[top]}"
                             ) from e
        raise SetupError(f"{what}: cannot import module '{module}': {e} (install the package "
                         "that provides it in the Python environment of ROS 2)") from e
    except Exception as e:
        raise SetupError(f"{what}: importing '{module}' failed: {type(e).__name__}: {e}") from e
    for part in attribute.split("."):
        if not hasattr(obj, part):
            raise SetupError(f"{what}: module '{module}' has no attribute '{attribute}'")
        obj = getattr(obj, part)
    if not callable(obj):
        raise SetupError(f"{what}: '{module}:{attribute}' is not callable")
    return obj
