"""The run loop of a subsystem node: the paper's behaviour pattern on ROS 2.

The generated node module describes its subsystem (:class:`SubsystemSpec`): the state, one
*iteration function* per behaviour, which the generator writes in the order of the steps of
the behaviour's page in the HPN (rssm_dsl.hpn.pattern; a send or receive line is left out
when the behaviour has no such arrangement):

    mask = r.begin()                      # new(x) of every input, frozen for P^f
    r.partial(psi, CASES[row], st, stage)   # each partial function from the pre-state; row:
                                          # new(x) of the inputs its cases split, as bits
                                          # (rssm_dsl.semantics.cases.bits of mask)
    r.commit(stage)                       # memory s^{i+1} and the outputs; new(x) cleared
    yield from r.send(SEND)               # the send arrangement
    r.increment()                         # i := i + 1
    yield from r.receive(RECEIVE)         # the receive arrangement
    return r.conditions(CONDITIONS)       # terminal and error conditions

and one *switch function* per behaviour (the first initial condition that holds, in
declaration order, ``otherwise`` last). :class:`Runner` drives them: it waits for the tick of
the subsystem's timer before each iteration, spins the node while an operation waits (a
blocking send for its acknowledgement, a blocking receive for a fresh sample), switches
behaviours, publishes the diagnostics topic ``~/rssm/diagnostics`` and, when asked, writes a
trace of every iteration (JSON lines).

Exit codes: 0 the subsystem ended (or was interrupted), 1 an operation failed and the
behaviour had no error condition, 2 the node could not start (binding, parameter), 3 no
initial condition of any next behaviour held when a behaviour ended.
"""

from __future__ import annotations

import contextlib
import os
import sys
import time
from collections.abc import Callable, Generator, Iterator, Mapping
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from rssm_core.iteration import Condition, NewFlags, end_conditions
from rssm_core.records import dataclass
from rssm_core.trace import SOURCE_NODE, TraceWriter, start_event
from rssm_core.values import OperationError

from .channels import ChannelSpec, time_msg
from .loop import WAIT_SLICE, Arrangement, Loop
from .params import ParamSpec, RuntimeParams, SetupError, read_params, runtime_params

DIAGNOSTICS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                             reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
EXIT_OK, EXIT_FAILED, EXIT_SETUP, EXIT_NO_SWITCH = 0, 1, 2, 3

Iteration = Generator[None, None, dict[str, bool]]
Case = tuple[int, Callable[[Any, dict[str, Any]], None] | None]   # (varpi, function)


class NoSwitch(Exception):
    """No initial condition of a next behaviour holds."""


@dataclass(frozen=True)
class BehaviourSpec:
    name: str
    iterate: Callable[[Runner], Iteration]
    switch: Callable[[Any, Mapping[str, bool]], str | None]
    functions: tuple[str, ...]        # targets of the partial functions, psi = 1, 2, ...
    conditions: tuple[str, ...]
    has_error: bool


@dataclass(frozen=True)
class SubsystemSpec:
    id: str                           # "a1.c"
    source: str                       # the specification file it was generated from
    node: str                         # node name and namespace (the launch file's)
    namespace: str
    frequency: float | None
    params: tuple[ParamSpec, ...]
    inputs: tuple[ChannelSpec, ...]
    outputs: tuple[ChannelSpec, ...]
    initial: str
    behaviours: Mapping[str, BehaviourSpec]
    init: Callable[[Mapping[str, Any]], Any]     # parameter values -> state
    status: Any                                   # the SubsystemStatus message class


class Trace:
    """JSON lines of what the node did (parameter rssm.trace_file or $RSSM_TRACE_DIR), in the
    trace format of :mod:`rssm_core.trace` (source ``"node"``: a header line, then the events),
    written by the core writer, flushed every half second while events come. ``file`` is the
    writer, None when the node writes no trace."""

    def __init__(self, path: Path | None) -> None:
        self.file: TraceWriter | None = None
        if path is not None:
            path.parent.mkdir(parents=True, exist_ok=True)
            self.file = TraceWriter(path, flush_every=0.5)
            self.file.emit(start_event(SOURCE_NODE))

    def emit(self, event: dict[str, Any]) -> None:
        if self.file is not None:
            self.file.emit(event)

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None


def trace_path(configured: str, spec_id: str) -> Path | None:
    if configured:
        return Path(configured)
    folder = os.environ.get("RSSM_TRACE_DIR")
    return Path(folder) / f"{spec_id}.jsonl" if folder else None


class Runner(Loop):
    """Runs one subsystem on one node (see the module docstring)."""

    def __init__(self, node: Node, executor: SingleThreadedExecutor, spec: SubsystemSpec,
                 rt: RuntimeParams, values: Mapping[str, Any]) -> None:
        super().__init__(node, executor, spec.inputs, spec.outputs, rt.rate_hz,
                         rt.resend_period)
        self.spec, self.rt = spec, rt
        self.state = spec.init(values)
        self.input_names = tuple(c.buffer for c in spec.inputs)
        self.new = NewFlags(len(spec.inputs))
        self.i = 0
        self.behaviour: str | None = None
        self.counts = {name: 0 for name in spec.behaviours}
        self.entered_at = 0
        self.switches = 0
        self.failed: OperationError | None = None
        self.cases: list[int] = []
        self.received: dict[str, Any] = {}
        self.sent: dict[str, int] = {}
        self.conds: dict[str, bool] = {}
        self.diag = node.create_publisher(spec.status, "~/rssm/diagnostics", DIAGNOSTICS_QOS)
        self.last_diag = 0.0
        self.trace = Trace(trace_path(rt.trace_file, spec.id))
        self.started = self.now()

    # ------------------------------------------------------------------ the pattern
    def begin(self) -> int:
        """Start an iteration: freeze new(x) of the inputs (bit k = input k)."""
        mask = self.new.freeze()
        self.cases = []
        self.received = {}
        self.sent = {}
        return mask

    def partial(self, case: Case, st: Any, stage: dict[str, Any]) -> None:
        """One partial transition function: the data-availability case chosen by new(x)."""
        varpi, fn = case
        self.cases.append(varpi)
        if fn is None:
            return
        try:
            fn(st, stage)
        except Exception as e:
            self._failed(e)

    def commit(self, stage: dict[str, Any]) -> None:
        """The join of P^f: the new memory and outputs become the state; new(x) is cleared."""
        st = self.state
        for name, value in stage.items():
            setattr(st, name, value)
        self.new.used()

    def send(self, arrangement: Arrangement) -> Iterator[None]:
        yield from self.arranged(arrangement, self._send_one)

    def _send_one(self, buffer: str) -> Iterator[None]:
        box = self.outboxes[buffer]
        yield from box.send(getattr(self.state, "v_" + buffer))
        self.sent[buffer] = box.seq

    def increment(self) -> None:
        self.i += 1
        assert self.behaviour is not None
        self.counts[self.behaviour] += 1

    def receive(self, arrangement: Arrangement) -> Iterator[None]:
        yield from self.arranged(arrangement, self._receive_one)

    def _receive_one(self, buffer: str) -> Iterator[None]:
        taken, value = yield from self.take(buffer)
        if not taken:
            return
        setattr(self.state, "v_" + buffer, value)
        self.new.received(self.input_names.index(buffer))
        if self.trace.file is not None:
            self.received[buffer] = {"seq": self.inboxes[buffer].taken_seq, "value": value}

    def conditions(self, table: tuple[Condition, ...]) -> dict[str, bool]:
        """The terminal and error conditions at the end of the iteration."""
        return end_conditions(table, self.state, self.failed is not None, self._failed)

    def _failed(self, e: Exception) -> None:
        err = e if isinstance(e, OperationError) else OperationError(
            "E802", f"{type(e).__name__}: {e}", self.spec.id)
        assert self.behaviour is not None
        beh = self.spec.behaviours[self.behaviour]
        self.trace.emit({"event": "error", "i": self.i, "behaviour": self.behaviour,
                         "code": err.code, "message": err.message, "where": err.where,
                         "handled": beh.has_error})
        if not beh.has_error:
            self.publish("error", message=str(err))
            raise err
        self.log.warning(f"{err} (behaviour {self.behaviour} takes its error condition)")
        if self.failed is None:
            self.failed = err

    # ------------------------------------------------------------------ behaviours
    def enter(self, behaviour: str, previous: str | None) -> None:
        self.behaviour = behaviour
        self.entered_at = self.i
        event = "enter" if previous is None else "switch"
        self.trace.emit({"event": event, "from": previous, "to": behaviour, "i": self.i,
                         "conditions": self.conds})
        self.publish(event, previous=previous)

    def run(self) -> int:
        self.wait_for_peers()
        self.enter(self.spec.initial, None)
        while True:
            assert self.behaviour is not None
            beh = self.spec.behaviours[self.behaviour]
            self.wait_tick()
            self.conds = self.drive(beh.iterate(self))
            self.failed = None
            self._iteration_done(beh)
            if not any(self.conds.values()):
                continue
            try:
                target = beh.switch(self.state, self.conds)
            except NoSwitch:
                self.log.error(f"behaviour {beh.name} of {self.spec.id} ended with conditions "
                               f"{self.conds}, but no initial condition of a next behaviour "
                               "holds")
                self.publish("error", message="no switch condition holds")
                return EXIT_NO_SWITCH
            self.switches += 1
            if target is None:
                self.trace.emit({"event": "switch", "from": beh.name, "to": None, "i": self.i,
                                 "conditions": self.conds})
                self.behaviour = None
                self.publish("end", previous=beh.name)
                return EXIT_OK
            self.enter(target, beh.name)

    def _iteration_done(self, beh: BehaviourSpec) -> None:
        if self.trace.file is not None:
            self.trace.emit({
                "event": "iteration", "i": self.i, "behaviour": beh.name,
                "new": self.new.values(),
                "cases": self.cases, "sent": self.sent, "received": self.received,
                "conditions": self.conds, "t": round(self.now() - self.started, 6)})
        now = time.monotonic()
        if now - self.last_diag >= self.rt.diagnostics_period:
            self.publish("iteration")

    def publish(self, event: str, previous: str | None = None, message: str = "") -> None:
        self.last_diag = time.monotonic()
        msg = self.spec.status()
        msg.subsystem = self.spec.id
        msg.event = event
        msg.behaviour = self.behaviour or ""
        msg.previous_behaviour = previous or ""
        msg.iteration = self.i
        msg.behaviour_iterations = self.i - self.entered_at
        msg.switches = self.switches
        msg.behaviours = list(self.counts)
        msg.behaviour_counts = list(self.counts.values())
        msg.inputs = list(self.input_names)
        msg.new_data = self.new.values()
        beh = self.spec.behaviours.get(self.behaviour or previous or "")
        msg.partial_functions = list(beh.functions) if beh is not None else []
        msg.data_cases = list(self.cases) if beh is not None else []
        msg.conditions = list(self.conds)
        msg.condition_values = list(self.conds.values())
        msg.overruns = self.overruns
        msg.overwritten = [self.inboxes[n].overwritten for n in self.input_names]
        msg.message = message
        # the tick of the last iteration (a switch happens at the end of one), before the
        # first one the clock
        ns = self.tick_ns if self.first_ns is not None else self.clock.now().nanoseconds
        msg.stamp = time_msg(ns)
        self.diag.publish(msg)

    def close(self) -> None:
        """Close the trace; let the reliable writers deliver what they hold (last samples,
        acks, diagnostics) before the node goes away (not possible after Ctrl-C)."""
        from rclpy.duration import Duration

        self.trace.close()
        if rclpy.ok():
            self.flush(0.5)
            self.diag.wait_for_all_acked(Duration(seconds=0.5))
            end = time.monotonic() + self.rt.linger
            while self.behaviour is None and rclpy.ok() and time.monotonic() < end:
                self.spin(min(WAIT_SLICE, max(0.0, end - time.monotonic())))


def run_subsystem(spec: SubsystemSpec, bind: Callable[[], None],
                  args: list[str] | None = None) -> int:
    """Entry point of a generated subsystem node: returns the exit code."""
    rclpy.init(args=args)
    node = Node(spec.node, namespace=spec.namespace)
    log = node.get_logger()
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    runner: Runner | None = None
    code = EXIT_OK
    try:
        bind()
        rt = runtime_params(node, spec.frequency)
        values = read_params(node, spec.params)
        runner = Runner(node, executor, spec, rt, values)
        code = runner.run()
    except SetupError as e:
        log.fatal(f"{spec.id} cannot start: {e}")
        code = EXIT_SETUP
    except OperationError as e:
        log.fatal(f"{spec.id}: operation failed: {e}")
        code = EXIT_FAILED
    except (KeyboardInterrupt, ExternalShutdownException):
        code = EXIT_OK
    finally:
        if runner is not None:
            with contextlib.suppress(Exception):  # already shutting down
                runner.close()
        executor.shutdown(timeout_sec=0)
        node.destroy_node()
        rclpy.try_shutdown()
    return code


def main_subsystem(spec: SubsystemSpec, bind: Callable[[], None]) -> None:
    sys.exit(run_subsystem(spec, bind, sys.argv))
