"""Run the Python of a generated ROS 2 node without ROS: the node module the generator writes
(rssmc ros2) is executed with stand-ins for the modules that need rclpy (the workspace's
runtime package, interfaces package and standard message packages); everything else it
imports (the value semantics shipped with the workspace) is the real thing. A small driver
then runs the node's behaviour pattern the way the runtime's Runner does for a subsystem
without channels: the iteration function of the current behaviour, the terminal and error
conditions, the switch.

The node module's contract with its runtime (see rssm_dsl/ros2/runtime/subsystem.py):
``SPEC = SubsystemSpec(..., initial=..., behaviours={name: BehaviourSpec(name, iterate,
switch, functions, conditions, has_error)}, init=...)``; an iteration function calls
``r.begin()``, ``r.partial(case, st, stage)``, ``r.commit(stage)``, ``r.send(...)``,
``r.increment()``, ``r.receive(...)``, ``r.conditions(table)``; a switch function returns
the next behaviour (None: end) or raises NoSwitch. A failing operation raises; the runtime
turns an exception that is not its OperationError into E802, and so does this driver."""

from __future__ import annotations

import builtins
import importlib.util
import types
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rssm_dsl.ros2.generator import generate, write_workspace
from rssm_dsl.ros2.stdtypes import PACKAGES
from tests.semantics.netview import compile_spec


def _runtime_end_conditions() -> Callable[..., dict[str, bool]] | None:
    """The end-of-iteration conditions as the runtime computes them (rssm_core, shipped with
    the workspace), or None in a tree without it (the driver's own copy of the rule then)."""
    try:
        module = importlib.import_module("rssm_core.iteration")
    except ImportError:
        return None
    fn: Callable[..., dict[str, bool]] | None = getattr(module, "end_conditions", None)
    return fn


_end_conditions = _runtime_end_conditions()


class _Record:
    """Stands in for a runtime class: keeps its arguments."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.args = args
        self.kwargs = kwargs


class NoSwitch(Exception):
    pass


class _StubModule(types.ModuleType):
    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        if name == "NoSwitch":
            return NoSwitch
        if name == "msg":
            return _StubModule(f"{self.__name__}.msg")
        return _Record


@dataclass
class NodeRun:
    behaviours: list[str] = field(default_factory=list)       # in the order entered
    iterations: dict[str, int] = field(default_factory=dict)
    switches: list[tuple[str, str | None, dict[str, bool]]] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)             # codes of failed operations
    stopped: str | None = None      # the code that stopped the node (no error condition)
    state: Any = None

    def var(self, name: str) -> Any:
        return getattr(self.state, "v_" + name)


class _Driver:
    """The run loop of rssm_dsl/ros2/runtime/subsystem.py (Runner), for a subsystem without
    channels: no waiting, no ROS."""

    def __init__(self, state: Any) -> None:
        self.state = state
        self.failed: str | None = None

    def begin(self) -> int:
        return 0

    def _fail(self, e: Exception) -> None:
        self.failed = self.failed or str(getattr(e, "code", "E802"))

    def partial(self, case: tuple[int, Any], st: Any, stage: dict[str, Any]) -> None:
        _, fn = case
        if fn is None:
            return
        try:
            fn(st, stage)
        except Exception as e:
            self.failed = self.failed or str(getattr(e, "code", "E802"))

    def commit(self, stage: Mapping[str, Any]) -> None:
        for name, value in stage.items():
            setattr(self.state, name, value)

    def send(self, arrangement: Any) -> Iterator[None]:
        """Sends go nowhere (non-blocking sends only: a blocking one would need ROS)."""
        return iter(())

    def receive(self, arrangement: Any) -> Iterator[None]:
        assert arrangement is None, "a subsystem that receives needs ROS"
        return iter(())

    def increment(self) -> None:
        return None

    def conditions(self, table: tuple[tuple[str, str, Any], ...]) -> dict[str, bool]:
        if _end_conditions is not None:       # the runtime's own rule, when it has one
            return _end_conditions(table, self.state, self.failed is not None, self._fail)
        values: dict[str, bool] = {}
        for name, _, predicate in table:
            try:
                values[name] = bool(predicate(self.state))
            except Exception as e:
                self.failed = self.failed or str(getattr(e, "code", "E802"))
                values[name] = False
        if self.failed is not None:
            for name, kind, _ in table:
                if kind == "error":
                    values[name] = True
        return values


def node_module(spec: Path, work: Path, subsystem_file: str) -> dict[str, Any]:
    """Generate the workspace of ``spec`` into ``work`` and execute the node module
    ``subsystem_file`` (a path under the workspace's src, e.g. 'v_a/v_a/node_c.py')."""
    comp = compile_spec(spec)
    ws = generate(comp)
    assert not isinstance(ws, list), ws
    src = work / "src"
    write_workspace(ws, src)
    system = comp.system.name if comp.system is not None else ""
    # the workspace's packages, and the standard message packages of the data topics
    stubbed = (f"{system}_interfaces", f"{system}_runtime", *PACKAGES)
    real_import = builtins.__import__

    def importer(name: str, globals: Any = None, locals: Any = None,
                 fromlist: Any = (), level: int = 0) -> Any:
        if name.split(".")[0] in stubbed:
            shipped = src / name.split(".")[0] / Path(*name.split(".")).with_suffix(".py")
            if name.endswith(".values") and shipped.is_file():    # the value semantics
                loaded = importlib.util.spec_from_file_location(name, shipped)
                assert loaded is not None and loaded.loader is not None
                module = importlib.util.module_from_spec(loaded)
                loaded.loader.exec_module(module)
                return module
            return _StubModule(name)
        return real_import(name, globals, locals, fromlist, level)

    ns: dict[str, Any] = {"__name__": "generated_node",
                          "__builtins__": {**vars(builtins), "__import__": importer}}
    path = src / subsystem_file
    exec(compile(path.read_text(encoding="utf-8"), str(path), "exec"), ns)
    return ns


def _drive(iteration: Any) -> dict[str, bool]:
    """The conditions an iteration function returns (a generator that yields while an
    operation waits, which none does here; see test_iteration_functions_are_generators)."""
    if not isinstance(iteration, types.GeneratorType):
        return dict(iteration)
    try:
        while True:
            next(iteration)
    except StopIteration as stop:
        return dict(stop.value)


def run_node(ns: Mapping[str, Any], max_iterations: int = 100) -> NodeRun:
    spec = ns["SPEC"].kwargs
    params = {p.args[0]: p.args[2] for p in spec["params"]}
    behaviours = {name: b.args for name, b in spec["behaviours"].items()}
    state = spec["init"](params)
    out = NodeRun(state=state)
    current: str | None = spec["initial"]
    for _ in range(max_iterations):
        if current is None:
            return out
        if not out.behaviours or out.behaviours[-1] != current:
            out.behaviours.append(current)
        _, iterate, switch, _, _, has_error = behaviours[current]
        driver = _Driver(state)
        conds = _drive(iterate(driver))
        if driver.failed is not None:
            out.errors.append(driver.failed)
            if not has_error:         # the node stops in the failing iteration
                out.stopped = driver.failed
                return out
        out.iterations[current] = out.iterations.get(current, 0) + 1
        if not any(conds.values()):
            continue
        target = switch(state, conds)
        out.switches.append((current, target, dict(conds)))
        current = target
    return out
