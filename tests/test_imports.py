"""Every module imports on its own, in a fresh interpreter: no import cycle hides behind
the order in which the rest of the test suite happens to import things."""

from __future__ import annotations

import pkgutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import rssm_core
import rssm_dsl

# Copied into the generated ROS 2 workspaces (the rssm_runtime package) and imported there,
# next to rclpy; rssmc itself never imports them, and rclpy is not installed here.
SKIPPED = ("rssm_dsl.ros2.runtime",)


def _walk(prefix: str, path: list[str]) -> list[str]:
    """The modules of a package, found on disk: nothing is imported in this process."""
    names: list[str] = []
    for info in pkgutil.iter_modules(path, prefix=f"{prefix}."):
        if info.name in SKIPPED:
            continue
        names.append(info.name)
        if info.ispkg:
            names += _walk(info.name, [str(Path(p) / info.name.rpartition(".")[2]) for p in path])
    return names


def _modules() -> list[str]:
    names: list[str] = []
    for package in (rssm_dsl, rssm_core):
        names += [package.__name__, *_walk(package.__name__, list(package.__path__))]
    return sorted(names)


def _import_alone(name: str) -> tuple[str, int, str]:
    done = subprocess.run([sys.executable, "-c", f"import {name}"], capture_output=True,
                          text=True, timeout=120)
    return name, done.returncode, done.stderr


def test_the_walk_finds_the_modules() -> None:
    names = _modules()
    assert {"rssm_dsl.cli", "rssm_dsl.commands.compile", "rssm_core"} <= set(names)
    assert not any(n.startswith("rssm_dsl.ros2.runtime") for n in names)


def test_every_module_imports_alone() -> None:
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(_import_alone, _modules()))
    failures = [f"{name} (exit {code}):\n{err.strip()}" for name, code, err in results if code]
    assert not failures, "modules that do not import on their own:\n\n" + "\n\n".join(failures)
