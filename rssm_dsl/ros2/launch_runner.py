"""Run generated ROS 2 launch files without the ROS launch system.

``launch`` and ``launch_ros`` are not on PyPI, so a ROS 2 installed from PyPI wheels has no
``ros2 launch``. This runner executes a launch file's ``generate_launch_description()`` with
stand-ins for ``launch.LaunchDescription`` and ``launch_ros.actions.Node`` that record their
arguments, then starts one process per ``Node`` exactly as ``ros2 launch`` would:

    <prefix of PACKAGE>/lib/PACKAGE/EXECUTABLE [ARGUMENTS] --ros-args
        -r __node:=NAME -r __ns:=/NAMESPACE [-r FROM:=TO ...] --params-file FILE ...

It understands the subset of the launch API the generator emits (``Node`` with package,
executable, name, namespace, parameters, arguments, remappings, output) and refuses anything
else. It depends on the standard library only, so any Python 3.11 can run it in the
environment of a built workspace (``. install/setup.bash``):

    python -m rssm_dsl.ros2.launch_runner install/PKG/share/PKG/launch/AGENT.launch.py ...
    python rssm_dsl/ros2/launch_runner.py --dry-run FILE ...      # print the commands

Options: ``--duration S`` stops the nodes after S seconds (SIGINT, then SIGKILL after
``--grace`` seconds); ``--log-dir DIR`` writes each node's output to DIR/<namespace>.<name>.log;
``-p NODE:NAME:=VALUE`` adds a parameter to the node with the fully qualified name NODE
(``*`` for every node). The exit code is 0 when every node exited with 0, else the first
failing node's code (124 when the duration ended them).
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import signal
import subprocess
import sys
import time
import types
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

NODE_ARGS = {"package", "executable", "name", "namespace", "parameters", "arguments",
             "remappings", "output"}


class LaunchError(Exception):
    """The launch file uses what the runner does not support, or a package is missing."""


@dataclass
class NodeAction:
    """What ``launch_ros.actions.Node(...)`` was given."""

    package: str
    executable: str
    name: str | None = None
    namespace: str | None = None
    parameters: list[Any] = field(default_factory=list)
    arguments: list[str] = field(default_factory=list)
    remappings: list[tuple[str, str]] = field(default_factory=list)
    output: str = "screen"

    @property
    def fqn(self) -> str:
        ns = (self.namespace or "").strip("/")
        name = self.name or self.executable
        return f"/{ns}/{name}" if ns else f"/{name}"


class _LaunchDescription:
    def __init__(self, entities: Sequence[Any] = ()) -> None:
        self.entities = list(entities)

    def add_action(self, action: Any) -> None:
        self.entities.append(action)


def _node(**kwargs: Any) -> NodeAction:
    unknown = set(kwargs) - NODE_ARGS
    if unknown:
        raise LaunchError(f"Node({', '.join(sorted(unknown))}=...) is not supported by the "
                          "launch runner")
    if "package" not in kwargs or "executable" not in kwargs:
        raise LaunchError("Node needs package and executable")
    return NodeAction(
        str(kwargs["package"]), str(kwargs["executable"]), kwargs.get("name"),
        kwargs.get("namespace"), list(kwargs.get("parameters", ())),
        [str(a) for a in kwargs.get("arguments", ())],
        [(str(a), str(b)) for a, b in kwargs.get("remappings", ())],
        str(kwargs.get("output", "screen")))


def package_prefix(package: str) -> Path:
    """The install prefix of a package, from the ament index on AMENT_PREFIX_PATH."""
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix and (Path(prefix) / "share" / "ament_index" / "resource_index" / "packages"
                       / package).is_file():
            return Path(prefix)
    raise LaunchError(f"package '{package}' is not found on AMENT_PREFIX_PATH (build the "
                      "workspace and source install/setup.bash)")


def _stub_modules() -> dict[str, types.ModuleType]:
    launch = types.ModuleType("launch")
    launch.LaunchDescription = _LaunchDescription  # type: ignore[attr-defined]
    launch_ros = types.ModuleType("launch_ros")
    actions = types.ModuleType("launch_ros.actions")
    actions.Node = _node  # type: ignore[attr-defined]
    launch_ros.actions = actions  # type: ignore[attr-defined]
    mods = {"launch": launch, "launch_ros": launch_ros, "launch_ros.actions": actions}
    if importlib.util.find_spec("ament_index_python") is None:
        ament = types.ModuleType("ament_index_python")
        packages = types.ModuleType("ament_index_python.packages")
        packages.get_package_prefix = lambda p: str(package_prefix(p))  # type: ignore[attr-defined]
        packages.get_package_share_directory = (  # type: ignore[attr-defined]
            lambda p: str(package_prefix(p) / "share" / p))
        ament.packages = packages  # type: ignore[attr-defined]
        mods |= {"ament_index_python": ament, "ament_index_python.packages": packages}
    return mods


def load_launch_file(path: Path) -> list[NodeAction]:
    """The nodes a launch file describes (its generate_launch_description() is run)."""
    if not path.is_file():
        raise LaunchError(f"{path}: no such launch file")
    saved = {name: sys.modules.get(name) for name in _stub_modules()}
    sys.modules.update(_stub_modules())
    try:
        spec = importlib.util.spec_from_file_location(f"_launch_{abs(hash(path))}", path)
        if spec is None or spec.loader is None:
            raise LaunchError(f"cannot load {path}")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        if not hasattr(module, "generate_launch_description"):
            raise LaunchError(f"{path} has no generate_launch_description()")
        description = module.generate_launch_description()
    finally:
        for name, old in saved.items():
            if old is None:
                sys.modules.pop(name, None)
            else:
                sys.modules[name] = old
    if not isinstance(description, _LaunchDescription):
        raise LaunchError(f"{path}: generate_launch_description() must return a "
                          "LaunchDescription")
    nodes = []
    for entity in description.entities:
        if not isinstance(entity, NodeAction):
            raise LaunchError(f"{path}: only Node actions are supported, not "
                              f"{type(entity).__name__}")
        nodes.append(entity)
    return nodes


def command(node: NodeAction, extra: Sequence[str] = ()) -> list[str]:
    """The command line ``ros2 launch`` would run for a node."""
    exe = package_prefix(node.package) / "lib" / node.package / node.executable
    cmd = [str(exe), *map(str, node.arguments), "--ros-args"]
    if node.name:
        cmd += ["-r", f"__node:={node.name}"]
    if node.namespace:
        cmd += ["-r", f"__ns:=/{node.namespace.strip('/')}"]
    for src, dst in node.remappings:
        cmd += ["-r", f"{src}:={dst}"]
    for p in node.parameters:
        if isinstance(p, dict):
            for k, v in p.items():
                cmd += ["-p", f"{k}:={json.dumps(v) if not isinstance(v, str) else v}"]
        else:
            cmd += ["--params-file", str(p)]
    for e in extra:
        cmd += ["-p", e]
    return cmd


def _extra(params: Sequence[str], fqn: str) -> list[str]:
    out = []
    for item in params:
        node, sep, rest = item.partition(":")
        if not sep or ":=" not in rest:
            raise LaunchError(f"-p {item}: write NODE:NAME:=VALUE (NODE fully qualified or *)")
        if node in ("*", fqn):
            out.append(rest)
    return out


def run(files: Sequence[Path], duration: float | None = None, grace: float = 10.0,
        log_dir: Path | None = None, params: Sequence[str] = (), dry_run: bool = False) -> int:
    nodes = [n for f in files for n in load_launch_file(f)]
    cmds = [(n, command(n, _extra(params, n.fqn))) for n in nodes]
    if dry_run:
        for n, cmd in cmds:
            print(json.dumps({"node": n.fqn, "command": cmd}))
        return 0
    procs: list[tuple[NodeAction, subprocess.Popen[bytes]]] = []
    logs = []
    stopping = False

    def stop(*_: Any) -> None:
        nonlocal stopping
        stopping = True

    old_int = signal.signal(signal.SIGINT, stop)
    old_term = signal.signal(signal.SIGTERM, stop)
    try:
        for n, cmd in cmds:
            out: Any = None
            if log_dir is not None:
                log_dir.mkdir(parents=True, exist_ok=True)
                out = open(log_dir / (n.fqn.strip("/").replace("/", ".") + ".log"), "wb")  # noqa: SIM115
                logs.append(out)
            procs.append((n, subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT
                                              if out is not None else None)))
        end = None if duration is None else time.monotonic() + duration
        timed_out = False
        while not stopping and any(p.poll() is None for _, p in procs):
            if end is not None and time.monotonic() >= end:
                timed_out = True
                break
            time.sleep(0.05)
        _terminate(procs, grace)
        codes = [(n, p.returncode) for n, p in procs]
        for n, c in codes:
            print(f"[launch_runner] {n.fqn} ({n.package}/{n.executable}) exited {c}",
                  file=sys.stderr)
        if timed_out:
            return 124
        return next((c for _, c in codes if c != 0), 0)
    finally:
        _terminate(procs, grace)
        for f in logs:
            f.close()
        signal.signal(signal.SIGINT, old_int)
        signal.signal(signal.SIGTERM, old_term)


def _terminate(procs: list[tuple[NodeAction, subprocess.Popen[bytes]]], grace: float) -> None:
    """SIGINT to every node still running, SIGKILL to those still running after grace."""
    for _, p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGINT)
    end = time.monotonic() + grace
    for _, p in procs:
        try:
            p.wait(timeout=max(0.0, end - time.monotonic()))
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="launch_runner", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("files", nargs="+", type=Path, help="launch files (*.launch.py)")
    ap.add_argument("--duration", type=float, help="stop the nodes after this many seconds")
    ap.add_argument("--grace", type=float, default=10.0,
                    help="seconds between SIGINT and SIGKILL when stopping")
    ap.add_argument("--log-dir", type=Path, help="write each node's output to a file here")
    ap.add_argument("-p", dest="params", action="append", default=[],
                    metavar="NODE:NAME:=VALUE", help="set a parameter of a node (or *)")
    ap.add_argument("--dry-run", action="store_true", help="print the commands, start nothing")
    args = ap.parse_args(argv)
    try:
        return run(args.files, args.duration, args.grace, args.log_dir, args.params,
                   args.dry_run)
    except LaunchError as e:
        print(f"launch_runner: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
