"""Run generated ROS 2 launch files without the ROS launch system.

``launch`` and ``launch_ros`` are not on PyPI, so a ROS 2 installed from PyPI wheels has no
``ros2 launch``. This runner executes a launch file's ``generate_launch_description()`` with
stand-ins for ``launch.LaunchDescription`` and ``launch_ros.actions.Node`` that record their
arguments, then starts one process per ``Node`` exactly as ``ros2 launch`` would:

    <prefix of PACKAGE>/lib/PACKAGE/EXECUTABLE [ARGUMENTS] --ros-args
        -r __node:=NAME -r __ns:=/NAMESPACE [-r FROM:=TO ...] --params-file FILE ...

It understands the subset of the launch API the generator emits and refuses anything else:
``Node`` (package, executable, name, namespace, parameters, arguments, remappings, output),
``DeclareLaunchArgument`` (name, default_value, description), ``SetEnvironmentVariable``
(name, value: it applies to the nodes after it), and the substitutions
``LaunchConfiguration`` (a launch argument's value) and ``EnvironmentVariable`` (name,
default_value), also as values of a parameters dict (``parameters=[FILE, {NAME: VALUE}]``:
given to the node as ``-p NAME:=VALUE``, read as YAML). Launch arguments are given as
``NAME:=VALUE`` after the files, as to ``ros2 launch``. It depends on the standard library
only, so any Python 3.11 can run it in the environment of a built workspace (``. install/setup.bash``):

    python -m rssm_dsl.ros2.launch_runner install/PKG/share/PKG/launch/AGENT.launch.py ...
    python -m rssm_dsl.ros2.launch_runner install/S_bringup/share/S_bringup/launch/system.launch.py domain_id:=7
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
from dataclasses import field
from pathlib import Path
from typing import Any

from rssm_core.records import dataclass

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


@dataclass(frozen=True)
class Context:
    """What substitutions are evaluated against: the launch arguments' values and the
    environment the nodes will get."""

    arguments: dict[str, str]
    env: dict[str, str]


class Substitution:
    def perform(self, context: Context) -> str:
        raise NotImplementedError


@dataclass(frozen=True)
class LaunchConfiguration(Substitution):
    name: str

    def perform(self, context: Context) -> str:
        if self.name not in context.arguments:
            raise LaunchError(f"launch argument '{self.name}' is not declared before its use")
        return context.arguments[self.name]


@dataclass(frozen=True)
class EnvironmentVariable(Substitution):
    name: str
    default_value: Any = ""

    def perform(self, context: Context) -> str:
        value = context.env.get(self.name)
        return value if value is not None else text(self.default_value, context)


def text(value: Any, context: Context) -> str:
    """A launch value: a string, a substitution, or a list of them (concatenated)."""
    if isinstance(value, Substitution):
        return value.perform(context)
    if isinstance(value, list | tuple):
        return "".join(text(v, context) for v in value)
    if isinstance(value, str):
        return value
    raise LaunchError(f"a launch value must be a string or a substitution, not "
                      f"{type(value).__name__}")


@dataclass(frozen=True)
class DeclareLaunchArgument:
    name: str
    default_value: Any = None
    description: str = ""


@dataclass(frozen=True)
class SetEnvironmentVariable:
    name: Any
    value: Any


def _check_kwargs(what: str, kwargs: dict[str, Any], allowed: set[str]) -> None:
    unknown = set(kwargs) - allowed
    if unknown:
        raise LaunchError(f"{what}({', '.join(sorted(unknown))}=...) is not supported by the "
                          "launch runner")


def _declare(name: str, **kwargs: Any) -> DeclareLaunchArgument:
    _check_kwargs("DeclareLaunchArgument", kwargs, {"default_value", "description"})
    return DeclareLaunchArgument(str(name), kwargs.get("default_value"),
                                 str(kwargs.get("description", "")))


def _set_env(name: Any, value: Any, **kwargs: Any) -> SetEnvironmentVariable:
    _check_kwargs("SetEnvironmentVariable", kwargs, set())
    return SetEnvironmentVariable(name, value)


def _configuration(name: str, **kwargs: Any) -> LaunchConfiguration:
    _check_kwargs("LaunchConfiguration", kwargs, set())
    return LaunchConfiguration(str(name))


def _environment(name: str, **kwargs: Any) -> EnvironmentVariable:
    _check_kwargs("EnvironmentVariable", kwargs, {"default_value"})
    return EnvironmentVariable(str(name), kwargs.get("default_value", ""))


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
    launch_actions = types.ModuleType("launch.actions")
    launch_actions.DeclareLaunchArgument = _declare  # type: ignore[attr-defined]
    launch_actions.SetEnvironmentVariable = _set_env  # type: ignore[attr-defined]
    substitutions = types.ModuleType("launch.substitutions")
    substitutions.LaunchConfiguration = _configuration  # type: ignore[attr-defined]
    substitutions.EnvironmentVariable = _environment  # type: ignore[attr-defined]
    launch.actions = launch_actions  # type: ignore[attr-defined]
    launch.substitutions = substitutions  # type: ignore[attr-defined]
    launch_ros = types.ModuleType("launch_ros")
    actions = types.ModuleType("launch_ros.actions")
    actions.Node = _node  # type: ignore[attr-defined]
    launch_ros.actions = actions  # type: ignore[attr-defined]
    mods = {"launch": launch, "launch.actions": launch_actions,
            "launch.substitutions": substitutions, "launch_ros": launch_ros,
            "launch_ros.actions": actions}
    if importlib.util.find_spec("ament_index_python") is None:
        ament = types.ModuleType("ament_index_python")
        packages = types.ModuleType("ament_index_python.packages")
        packages.get_package_prefix = lambda p: str(package_prefix(p))  # type: ignore[attr-defined]
        packages.get_package_share_directory = (  # type: ignore[attr-defined]
            lambda p: str(package_prefix(p) / "share" / p))
        ament.packages = packages  # type: ignore[attr-defined]
        mods |= {"ament_index_python": ament, "ament_index_python.packages": packages}
    return mods


Action = NodeAction | DeclareLaunchArgument | SetEnvironmentVariable


def load_launch_file(path: Path) -> list[NodeAction]:
    """The nodes a launch file describes (its generate_launch_description() is run)."""
    return [a for a in load_actions(path) if isinstance(a, NodeAction)]


def load_actions(path: Path) -> list[Action]:
    """The actions a launch file describes, in order (its generate_launch_description() is
    run)."""
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
    actions: list[Action] = []
    for entity in description.entities:
        if not isinstance(entity, NodeAction | DeclareLaunchArgument | SetEnvironmentVariable):
            raise LaunchError(f"{path}: only Node, DeclareLaunchArgument and "
                              f"SetEnvironmentVariable actions are supported, not "
                              f"{type(entity).__name__}")
        actions.append(entity)
    return actions


def plan(files: Sequence[Path], arguments: dict[str, str] | None = None,
         env: dict[str, str] | None = None) -> list[tuple[NodeAction, dict[str, str]]]:
    """Every node of the launch files and the environment it is started with: the launch
    arguments (``arguments`` over the declared defaults) evaluated, the environment
    variables set before it applied."""
    given = dict(arguments or {})
    context = Context({}, dict(os.environ if env is None else env))
    out: list[tuple[NodeAction, dict[str, str]]] = []
    declared: set[str] = set()
    for f in files:
        for action in load_actions(f):
            if isinstance(action, DeclareLaunchArgument):
                declared.add(action.name)
                if action.name in given:
                    context.arguments[action.name] = given[action.name]
                elif action.default_value is not None:
                    context.arguments[action.name] = text(action.default_value, context)
                else:
                    raise LaunchError(f"launch argument '{action.name}' has no default: "
                                      f"give it as {action.name}:=VALUE")
            elif isinstance(action, SetEnvironmentVariable):
                context.env[text(action.name, context)] = text(action.value, context)
            else:
                action.parameters = [_parameters(p, context) for p in action.parameters]
                out.append((action, dict(context.env)))
    unknown = sorted(set(given) - declared)
    if unknown:
        raise LaunchError(f"launch argument(s) {', '.join(unknown)} not declared by the "
                          "launch file(s)")
    return out


def _parameters(entry: Any, context: Context) -> Any:
    """A Node's parameters entry with its substitutions performed: a file, or a dict whose
    values may be substitutions (their text goes to rcl, which reads it as YAML, as
    launch_ros does: ``"true"`` is a bool)."""
    if not isinstance(entry, dict):
        return text(entry, context) if isinstance(entry, Substitution) else entry
    return {str(k): text(v, context) if isinstance(v, Substitution | list | tuple) else v
            for k, v in entry.items()}


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
        log_dir: Path | None = None, params: Sequence[str] = (), dry_run: bool = False,
        arguments: dict[str, str] | None = None) -> int:
    planned = plan(files, arguments)
    cmds = [(n, command(n, _extra(params, n.fqn)), env) for n, env in planned]
    if dry_run:
        for n, cmd, env in cmds:
            changed = {k: v for k, v in env.items() if os.environ.get(k) != v}
            print(json.dumps({"node": n.fqn, "command": cmd, "env": changed}))
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
        for n, cmd, env in cmds:
            out: Any = None
            if log_dir is not None:
                log_dir.mkdir(parents=True, exist_ok=True)
                out = open(log_dir / (n.fqn.strip("/").replace("/", ".") + ".log"), "wb")  # noqa: SIM115
                logs.append(out)
            procs.append((n, subprocess.Popen(cmd, env=env, stdout=out,
                                              stderr=subprocess.STDOUT
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
    ap.add_argument("files", nargs="+",
                    help="launch files (*.launch.py), then launch arguments NAME:=VALUE")
    ap.add_argument("--duration", type=float, help="stop the nodes after this many seconds")
    ap.add_argument("--grace", type=float, default=10.0,
                    help="seconds between SIGINT and SIGKILL when stopping")
    ap.add_argument("--log-dir", type=Path, help="write each node's output to a file here")
    ap.add_argument("-p", dest="params", action="append", default=[],
                    metavar="NODE:NAME:=VALUE", help="set a parameter of a node (or *)")
    ap.add_argument("--dry-run", action="store_true", help="print the commands, start nothing")
    args = ap.parse_args(argv)
    files = [Path(f) for f in args.files if ":=" not in f]
    arguments = dict(f.split(":=", 1) for f in args.files if ":=" in f)
    try:
        return run(files, args.duration, args.grace, args.log_dir, args.params,
                   args.dry_run, arguments)
    except LaunchError as e:
        print(f"launch_runner: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
