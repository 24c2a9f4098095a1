"""A device node: a real effector E or receptor R bound to a Python class (the device type's
``binding "module:Class"``), run as the compiler's device net runs it: every period receive
the inputs (each per its mode), ``step(dt)``, ``measure()``, send the outputs (each per its
mode). The class has the interface of rssm_dsl.interp.device (``receive``, ``step``,
``measure``, ``close``) and is built with a spec of the same fields; when rssmc is installed
in the ROS 2 Python environment it gets rssm_dsl's own DeviceSpec (with rssm_dsl types), so
the standard library's devices work unchanged.

A device type without a binding gets no node: its vendor's driver is expected to speak the
same topics (docs/ros2.md).

Time: ``step(dt)`` gets the time that passed on the node's clock since the previous step
(monotonic, or simulated with ``use_sim_time``), so a device paces its process against that
clock. With ``use_sim_time``, a class that simulates its process (``simulation = True``) makes
its node the system's clock instead (runtime/simclock.py): each step is exactly one period of
simulated time, published on ``/clock``.
"""

from __future__ import annotations

import contextlib
import importlib
import sys
from collections.abc import Callable, Iterator, Mapping
from dataclasses import field
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node

from rssm_core.records import dataclass
from rssm_core.values import Desc, MeasurementError, converter, measured_values

from .bindings import load
from .channels import ChannelSpec
from .loop import Loop
from .params import ParamSpec, SetupError, declare, read_params, runtime_params
from .simclock import SimClock, is_simulation, wait_for_system

EXIT_OK, EXIT_FAILED, EXIT_SETUP = 0, 1, 2


@dataclass(frozen=True)
class DeviceNodeSpec:
    id: str                                   # "a1.E.lwr"
    name: str
    device_type: str
    kind: str                                 # "effector" | "receptor"
    source: str
    node: str
    namespace: str
    frequency: float | None
    binding: tuple[str, str]                  # (module, Class)
    inputs: tuple[tuple[str, Desc], ...]      # every input buffer and its type
    outputs: tuple[tuple[str, Desc], ...]
    channels_in: tuple[ChannelSpec, ...]      # the connected ones
    channels_out: tuple[ChannelSpec, ...]
    initial: Mapping[str, Any]                # buffer -> initial value (JSON-like)
    params: tuple[ParamSpec, ...]
    package: str = ""                         # the ROS package installing the node


@dataclass(frozen=True)
class DeviceSpec:
    """What a device class is told about itself (fields of rssm_dsl.interp.device.DeviceSpec;
    types are value descriptors here)."""

    id: str
    name: str
    device_type: str
    kind: str
    frequency: float | None
    inputs: Mapping[str, Any]
    outputs: Mapping[str, Any]
    initial: Mapping[str, Any]
    params: Mapping[str, Any] = field(default_factory=dict)
    options: Mapping[str, str] = field(default_factory=dict)
    base_dir: Path = Path(".")


def _rssm_type(d: Desc) -> Any:
    from rssm_dsl.semantics import types as T

    if d[0] == "array":
        return T.ArrayT(_rssm_type(d[1]), d[2])
    if d[0] == "record":
        return T.RecordT(d[1], tuple((n, _rssm_type(fd)) for n, fd in d[2]))
    if d[0] == "enum":
        return T.EnumT(d[1], tuple(d[2]))
    if d[0] == "range":
        return T.RangeT(d[1], d[2])
    return T.SCALARS[d[0]]


def device_spec(spec: DeviceNodeSpec, initial: Mapping[str, Any], params: Mapping[str, Any],
                options: Mapping[str, str], base_dir: Path) -> Any:
    """rssm_dsl's DeviceSpec when rssmc is importable, else this module's."""
    try:
        from rssm_dsl.interp.device import DeviceSpec as RssmDeviceSpec
    except ImportError:
        return DeviceSpec(spec.id, spec.name, spec.device_type, spec.kind, spec.frequency,
                          dict(spec.inputs), dict(spec.outputs), initial, params, options,
                          base_dir)
    return RssmDeviceSpec(spec.id, spec.name, spec.device_type, spec.kind, spec.frequency,
                          {n: _rssm_type(d) for n, d in spec.inputs},
                          {n: _rssm_type(d) for n, d in spec.outputs}, initial, params,
                          options, base_dir)


DATA_DIR = "data"       # the folder of the package's share folder holding the devices' files


def package_data_dir(package: str) -> Path:
    """``<share folder of package>/data``: where the generator installs the files a device
    reads (a replayed CSV file), found through the ament index, never the current folder."""
    try:
        packages = importlib.import_module("ament_index_python.packages")
        return Path(packages.get_package_share_directory(package)) / DATA_DIR
    except Exception as e:
        raise SetupError(f"cannot find the share folder of package '{package}' ({e}); set "
                         "parameter rssm.base_dir") from e


def device_options(node: Node, package: str = "") -> tuple[dict[str, str], Path]:
    """Parameters rssm.options ("KEY=VALUE;KEY=VALUE", what `rssmc simulate --device-option`
    gives) and rssm.base_dir (the folder relative files are read from: empty, the default,
    for the package's ``share/<package>/data`` folder, where the generator installed the
    device's files; a relative folder is taken relative to the package's share folder; never
    the current folder)."""
    from rcl_interfaces.msg import ParameterDescriptor

    text = node.declare_parameter("rssm.options", "",
                                  ParameterDescriptor(dynamic_typing=True)).value
    base = node.declare_parameter("rssm.base_dir", "",
                                  ParameterDescriptor(dynamic_typing=True)).value
    if not isinstance(text, str) or not isinstance(base, str):
        raise SetupError("parameters rssm.options and rssm.base_dir are strings")
    options: dict[str, str] = {}
    for item in filter(None, (x.strip() for x in text.split(";"))):
        key, sep, value = item.partition("=")
        if not sep:
            raise SetupError(f"rssm.options: '{item}' is not KEY=VALUE")
        options[key.strip()] = value.strip()
    if base and Path(base).is_absolute():
        return options, Path(base)
    if not package:
        raise SetupError("parameter rssm.base_dir must be an absolute folder (the node does "
                         "not know its package)")
    data = package_data_dir(package)
    return options, data.parent / base if base else data


class DeviceRunner(Loop):
    def __init__(self, node: Node, executor: SingleThreadedExecutor, spec: DeviceNodeSpec,
                 impl: Any, rate_hz: float, resend_period: float,
                 initial: dict[str, Any]) -> None:
        super().__init__(node, executor, spec.channels_in, spec.channels_out, rate_hz,
                         resend_period)
        self.spec, self.impl, self.values = spec, impl, initial
        self.convert: dict[str, Callable[[Any], Any]] = {
            n: converter(d) for n, d in spec.outputs}
        self.steps = 0
        self.last_step: float | None = None
        self.sim: SimClock | None = None
        self.system_nodes = 1                     # the clock waits for them (simclock.py)

    def keep_time(self, real_time_factor: float) -> None:
        """Be the clock of the simulated system (see runtime/simclock.py)."""
        if self.timer is not None:
            self.node.destroy_timer(self.timer)
            self.timer = None
        sim = self.sim = SimClock(self.node, self.period, real_time_factor)
        for box in self.outboxes.values():
            box.clock = sim.now_ns
        self.log.info(f"{self.spec.id} is the clock of the simulation (/clock), "
                      f"{real_time_factor:g} simulated s per wall-clock s")

    def run(self) -> int:
        self.wait_for_peers()
        ins = tuple(("buf", c.buffer) for c in self.spec.channels_in)
        outs = tuple(("buf", c.buffer) for c in self.spec.channels_out)
        sim = self.sim
        if sim is not None:
            sim.check_alone(self.node)
            wait_for_system(self.node, self.system_nodes, sim, self.spin)
            sim.publish()                  # time 0: the other nodes' timers start from it
        while True:
            if sim is None:
                self.wait_tick()
            else:
                sim.wait(self.spin)
            if ins:
                self.drive(self.arranged(("seq", ins), self._receive_one))
            self._step()
            if outs:
                self.drive(self.arranged(("seq", outs), self._send_one))
            if sim is not None:
                sim.publish()

    def _receive_one(self, buffer: str) -> Iterator[None]:
        taken, value = yield from self.take(buffer)
        if taken:
            self.values[buffer] = value
            self.impl.receive(buffer, value)

    def _send_one(self, buffer: str) -> Iterator[None]:
        yield from self.outboxes[buffer].send(self.values[buffer])

    def _step(self) -> None:
        if self.sim is not None:
            dt = self.period
            self.sim.advance()
        else:
            now = self.now()
            dt = (self.period if self.last_step is None else now - self.last_step)
            self.last_step = now
        self.steps += 1
        self.impl.step(dt)
        measured = self.impl.measure()
        try:                  # every measurement, whatever typed_measurements says
            self.values.update(measured_values(self.convert, measured))
        except MeasurementError as e:
            raise SetupError(f"device {self.spec.id} {e.message} [E803]") from None


def run_device(spec: DeviceNodeSpec, args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    node = Node(spec.node, namespace=spec.namespace)
    log = node.get_logger()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    impl: Any = None
    runner: DeviceRunner | None = None
    code = EXIT_OK
    try:
        rt = runtime_params(node, spec.frequency)
        params = read_params(node, spec.params)
        types = dict(spec.inputs) | dict(spec.outputs)
        initial = {n: converter(types[n])(v) for n, v in spec.initial.items()}
        options, base_dir = device_options(node, spec.package)
        cls = load(spec.binding[0], spec.binding[1], f"device {spec.id}")
        try:
            impl = cls(device_spec(spec, dict(initial), params, options, base_dir))
        except Exception as e:
            raise SetupError(f"{spec.binding[0]}:{spec.binding[1]} failed to start: "
                             f"{type(e).__name__}: {e}") from e
        runner = DeviceRunner(node, executor, spec, impl, rt.rate_hz, rt.resend_period,
                              initial)
        factor = declare(node, "rssm.real_time_factor", 1.0)
        nodes = declare(node, "rssm.system_nodes", 1)
        if isinstance(nodes, bool) or not isinstance(nodes, int) or nodes < 1:
            raise SetupError(f"parameter rssm.system_nodes must be an int >= 1, not {nodes!r}")
        runner.system_nodes = nodes
        if runner.sim_time and is_simulation(impl):
            runner.keep_time(factor if isinstance(factor, int | float) else -1.0)
        code = runner.run()
    except SetupError as e:
        log.fatal(f"{spec.id}: {e}")
        code = EXIT_SETUP if runner is None else EXIT_FAILED
    except (KeyboardInterrupt, ExternalShutdownException):
        code = EXIT_OK
    except Exception as e:
        log.fatal(f"{spec.id}: the device failed: {type(e).__name__}: {e} [E802]")
        code = EXIT_FAILED
    finally:
        if runner is not None and rclpy.ok():
            with contextlib.suppress(Exception):  # already shutting down
                runner.flush(0.5)
        if impl is not None:
            with contextlib.suppress(Exception):  # already shutting down
                impl.close()
        executor.shutdown(timeout_sec=0)
        node.destroy_node()
        rclpy.try_shutdown()
    return code


def main_device(spec: DeviceNodeSpec) -> None:
    sys.exit(run_device(spec, sys.argv))
