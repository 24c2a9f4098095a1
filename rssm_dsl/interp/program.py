"""Bind the flattened HPN to what it means: operations on places, conditions on transitions.

:func:`build_runtime` takes a compiled specification and returns a :class:`Runtime`: the
flat net plus, per flat place, the operation run when it receives a token, and per flat
transition its guard (its condition, ``None`` = true), its gate (the ticker of a paced
subsystem or device, for the transitions that start an iteration) and its effect (the
bookkeeping done when it fires). Expressions are compiled once (:mod:`compile_expr`); external
operations and device classes are resolved once (:mod:`rssm_dsl.bindings`). Every problem
that prevents the run is collected and raised as one :class:`SetupError`.

What the elements mean (the RSSM HPN paper, section IV; docs/semantics.md, "One iteration"
and "Communication modes"):

| IR element                                  | run-time meaning                               |
|---------------------------------------------|------------------------------------------------|
| place of a data case ``p[j,v,w,psi,varpi]`` | run the case's statements (partial function)   |
| transition ``t[j,v,w,psi,varpi]``           | guard: new(x) of the split inputs equal the    |
|                                             | case's (rssm_dsl/semantics/cases.py)           |
| fork / join of ``P^f``                      | freeze new(x) / commit the memory version       |
| ``p[j,v,w,2]``                              | ``i := i + 1``                                  |
| ``t[j,v,w,4]`` / ``t[j,v,w,out]``           | guard: not (f^tau or f^eps) / f^tau or f^eps   |
| ``t[j,v,alpha]``                            | guard: the switch's initial condition f^sigma   |
| ``p[...,snd,rho,op]`` / ``p[...,rcv,kappa,op]`` | copy buffer -> channel slot / slot -> buffer |
| ``p^E[j,h,op]``                             | the device steps and measures                  |
"""

from __future__ import annotations

import functools
from collections import defaultdict
from collections.abc import Callable
from dataclasses import field
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

from rssm_core.records import dataclass
from rssm_core.values import MeasurementError, measured_values
from rssm_dsl.bindings import BindingError, binding_dirs, callable_arity_problem, resolve
from rssm_dsl.diagnostics import Diagnostic, Related
from rssm_dsl.hpn.flat import FlatNet, FlatPlace, FlatTransition
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import HPN, CondKind, Operation, OpKind, PageKind
from rssm_dsl.interp.channels import ChannelState
from rssm_dsl.interp.clock import SimClock, Ticker, WallClock
from rssm_dsl.interp.compile_expr import ExprCompiler
from rssm_dsl.interp.device import Device as DeviceImpl
from rssm_dsl.interp.device import DeviceConfigError, DeviceSpec
from rssm_dsl.interp.errors import EvalError, SetupError
from rssm_dsl.interp.initial import InitialValues
from rssm_dsl.interp.state import BehaviourState, DeviceState, SubsystemState
from rssm_dsl.interp.trace import TraceWriter
from rssm_dsl.interp.values import converter, to_json
from rssm_dsl.pipeline import Compilation
from rssm_dsl.semantics import cases as case_rule
from rssm_dsl.semantics.model import Device, Extern, Subsystem, System
from rssm_dsl.semantics.typecheck import Symbol, owner_symbols
from rssm_dsl.semantics.types import BOOL
from rssm_dsl.source import Span

Op = Callable[[], None]
Guard = Callable[[], bool]
Effect = Callable[[], object]      # what it returns is not used


@dataclass
class RunConfig:
    """What the bindings depend on: where user modules live and which devices to use."""

    base_dir: Path = Path(".")
    devices: dict[str, str] = field(default_factory=dict)  # id or pattern -> "module:Class"
    device_options: dict[str, dict[str, str]] = field(default_factory=dict)
    wall_clock: bool = False


@dataclass(frozen=True, eq=False)
class CaseGroup:
    """The data-availability sublayer of one partial function P^f_{j,v,w,psi}: from its input
    place exactly one case transition fires (the one whose new(x) combination is the
    subsystem's), then the case's operation, then its `done` transition to the output place.
    ``table[select(mask)]`` gives, for the new(x) ``mask`` of the subsystem (bit k:
    new(x_k)), the case's transition, place, operation and `done` transition: the table is
    ordered by varpi over the ``split`` inputs (rssm_dsl/semantics/cases.py)."""

    state: SubsystemState
    in_place: int
    out_place: int
    table: tuple[tuple[int, int, Op | None, int], ...]
    split: tuple[int, ...] = ()
    select: Callable[[int], int] = field(default=case_rule.selector(()))


@dataclass(eq=False)
class Runtime:
    """The flat net with its operations, guards, gates and effects, and the run state."""

    comp: Compilation
    system: System
    hpn: HPN
    net: FlatNet
    subsystems: dict[str, SubsystemState]
    devices: dict[str, DeviceState]
    channels: dict[str, ChannelState]
    ops: list[Op | None]
    op_owner: list[SubsystemState | DeviceState | None]
    guards: list[Guard | None]
    gates: list[Ticker | None]
    effects: list[Effect | None]
    clock: SimClock | WallClock
    tracer: TraceWriter | None = None
    step: int = 0
    case_groups: dict[int, CaseGroup] = field(default_factory=dict)   # by input place

    def time(self) -> float:
        return self.clock.now() / 1e9

    def emit(self, event: dict[str, Any]) -> None:
        if self.tracer is not None:
            event["step"] = self.step
            event["time"] = self.clock.now() / 1e9
            self.tracer.emit(event)

    def close_devices(self) -> list[str]:
        problems: list[str] = []
        for d in self.devices.values():
            try:
                d.impl.close()
            except (Exception, SystemExit) as e:
                problems.append(f"{d.id}: close() raised {type(e).__name__}: {e}")
        return problems


class _Builder:
    def __init__(self, comp: Compilation, config: RunConfig) -> None:
        assert comp.system is not None and comp.hpn is not None
        self.comp = comp
        self.system: System = comp.system
        self.hpn: HPN = comp.hpn
        self.net = flatten(comp.hpn)
        self.config = config
        self.diags: list[Diagnostic] = []
        self.bound: dict[str, Callable[..., Any] | None] = {}
        self.initial = InitialValues(self.system)
        self.clock: SimClock | WallClock = WallClock() if config.wall_clock else SimClock()
        self.rt: Runtime | None = None
        self.arcs_in: dict[str, set[str]] = defaultdict(set)
        self.arcs_out: dict[str, set[str]] = defaultdict(set)
        for a in self.hpn.arcs:
            self.arcs_out[a.source].add(a.target)
            self.arcs_in[a.target].add(a.source)

    # ------------------------------------------------------------------ bindings
    def _resolve_extern(self, ext: Extern, use: Span) -> Callable[..., Any] | None:
        if ext.binding in self.bound:
            return self.bound[ext.binding]
        fn: Callable[..., Any] | None = None
        related = (Related(use, f"{ext.name}() is called here"),)
        try:
            obj = resolve(ext.binding, binding_dirs(ext.span.file, self.config.base_dir))
            if not callable(obj):
                self.diags.append(Diagnostic(
                    "E801", f"\"{ext.binding}\" of extern {ext.name} is not callable", ext.span,
                    "bind the extern to a Python function", related))
            else:
                fn = obj
                why = callable_arity_problem(fn, len(ext.params))
                if why is not None:
                    self.diags.append(Diagnostic(
                        "E804", f"\"{ext.binding}\" cannot take the {len(ext.params)} "
                        f"argument(s) of extern {ext.name}: {why}", ext.span,
                        "make the Python function's parameters match the extern", related))
                    fn = None
        except BindingError as e:
            self.diags.append(Diagnostic("E801", f"extern {ext.name}: {e.message}", ext.span,
                                         e.hint, related))
        self.bound[ext.binding] = fn
        return fn

    # ------------------------------------------------------------------ subsystems
    def _subsystem(self, sub: Subsystem) -> tuple[SubsystemState, ExprCompiler]:
        env = self.initial.env(sub)
        symbols = owner_symbols(self.initial.const_symbols, sub.params, sub.memory,
                                (*sub.inputs, *sub.outputs))
        externs = {e.name: e for e in self.system.externs}
        compiler = ExprCompiler(symbols, externs, self.initial.consts, self._resolve_extern)
        behaviours: dict[str, BehaviourState] = {}
        for beh in sub.behaviours:
            conds = [(c.name, c.kind, compiler.expr(c.expr)) for c in beh.conditions]
            behaviours[beh.name] = BehaviourState(beh.name, conds)
        ticker = Ticker(sub.id, sub.frequency) if sub.frequency else None
        state = SubsystemState(sub, env, behaviours, ticker, tuple(b.name for b in sub.inputs))
        return state, compiler

    def _device(self, d: Device) -> DeviceState | None:
        env = self.initial.env(d)
        ticker = Ticker(d.id, d.frequency) if d.frequency else None
        binding = _chosen(self.config.devices, d.id) or d.binding
        if binding is None:
            self.diags.append(Diagnostic(
                "E801", f"device {d.id} ({d.device_type}) has no binding", d.span,
                f"add `binding \"module:Class\"` to device {d.device_type}, or run with "
                f"--device {d.id}=rssm_stdlib.devices.constant:ConstantDevice"))
            return None
        try:
            declared = d.binding_span.file if d.binding_span is not None else None
            cls = resolve(binding, binding_dirs(declared, self.config.base_dir))
        except BindingError as e:
            self.diags.append(Diagnostic(
                "E801", f"device {d.id} ({d.device_type}): {e.message}", d.span,
                (e.hint or "") + f"; or choose another class with --device {d.id}=module:Class"))
            return None
        spec = DeviceSpec(
            id=d.id, name=d.name, device_type=d.device_type, kind=d.kind, frequency=d.frequency,
            inputs={b.name: b.type for b in d.inputs}, outputs={b.name: b.type for b in d.outputs},
            initial={b.name: env[b.name] for b in (*d.inputs, *d.outputs) if b.name in env},
            params={p.name: env[p.name] for p in d.params if p.name in env},
            options={k: v for pattern, opts in self.config.device_options.items()
                     if fnmatchcase(d.id, pattern) for k, v in opts.items()},
            base_dir=self.config.base_dir,
        )
        if not callable(cls):
            self.diags.append(Diagnostic("E801", f"\"{binding}\" of device {d.id} is not a class",
                                         d.span))
            return None
        try:
            impl = cls(spec)
        except DeviceConfigError as e:
            self.diags.append(Diagnostic("E801", f"device {d.id} ({binding}): {e}", d.span,
                                         "see --device-option ID:KEY=VALUE"))
            return None
        except (Exception, SystemExit) as e:
            self.diags.append(Diagnostic(
                "E802", f"device {d.id} ({binding}) failed to start: {type(e).__name__}: {e}",
                d.span))
            return None
        if not isinstance(impl, DeviceImpl):
            self.diags.append(Diagnostic(
                "E804", f"\"{binding}\" of device {d.id} lacks receive/step/measure/close",
                d.span, "derive it from rssm_dsl.interp.device.DeviceBase"))
            return None
        return DeviceState(d, env, impl, ticker)

    # ------------------------------------------------------------------ build
    def build(self) -> Runtime:
        self.diags += self.initial.diagnostics
        subs: dict[str, SubsystemState] = {}
        compilers: dict[str, ExprCompiler] = {}
        for sub in self.system.subsystems():
            subs[sub.id], compilers[sub.id] = self._subsystem(sub)
        devs: dict[str, DeviceState] = {}
        for d in self.system.devices():
            ds = self._device(d)
            if ds is not None:
                devs[d.id] = ds
        owners: dict[str, SubsystemState | DeviceState] = {**subs, **devs}
        channels: dict[str, ChannelState] = {}
        for ch in self.system.channels:
            prod = owners.get(ch.producer.owner)
            initial = prod.vars.get(ch.producer.name) if prod is not None else None
            channels[ch.id] = ChannelState(ch, initial)
        n_p, n_t = len(self.net.places), len(self.net.transitions)
        rt = Runtime(self.comp, self.system, self.hpn, self.net, subs, devs, channels,
                     [None] * n_p, [None] * n_p, [None] * n_t, [None] * n_t, [None] * n_t,
                     self.clock)
        self.rt = rt
        cases: dict[tuple[str, str, str, int], Op] = {}
        for fp in self.net.places:
            if fp.operation is None:
                continue
            op = self.hpn.places[fp.operation].operation
            assert op is not None
            owner = owners.get(op.subsystem)
            if owner is None:     # a device that failed to build: already reported
                continue
            rt.op_owner[fp.index] = owner
            rt.ops[fp.index] = self._op(rt, fp, op, owner, compilers, cases)
        for ft in self.net.transitions:
            self._transition(rt, ft, subs, devs, compilers)
        self._case_groups(rt, subs)
        if self.diags:
            rt.close_devices()
            raise SetupError(self.diags)
        return rt

    # ------------------------------------------------------------------ operations
    def _op(self, rt: Runtime, fp: FlatPlace, op: Operation,
            owner: SubsystemState | DeviceState, compilers: dict[str, ExprCompiler],
            cases: dict[tuple[str, str, str, int], Op]) -> Op | None:
        match op.kind:
            case OpKind.CASE:
                assert isinstance(owner, SubsystemState)
                return None if op.void else self._case(owner, op, compilers[owner.id], cases)
            case OpKind.INCREMENT:
                assert isinstance(owner, SubsystemState) and op.behaviour is not None
                return _increment(owner, owner.behaviours[op.behaviour])
            case OpKind.SEND:
                assert op.channel is not None and op.target is not None
                return _send(rt, owner, op.target, rt.channels[op.channel], fp)
            case OpKind.RECEIVE:
                assert op.channel is not None and op.target is not None
                return _receive(rt, owner, op.target, rt.channels[op.channel], fp)
            case OpKind.DEVICE:
                assert isinstance(owner, DeviceState)
                return _device_step(rt, owner, fp.span)
        return None

    def _case(self, s: SubsystemState, op: Operation, compiler: ExprCompiler,
              cache: dict[tuple[str, str, str, int], Op]) -> Op | None:
        assert op.behaviour is not None and op.target is not None and op.case is not None
        beh = s.model.behaviour(op.behaviour)
        pf = next(f for f in beh.functions if f.target == op.target)
        case = next(c for c in pf.cases if c.index == op.case)
        key = (s.id, op.behaviour, op.target, case.source_case if case.source_case is not None
               else -case.index)
        if key in cache:
            return cache[key]
        run, _ = compiler.case(case.body)
        # run(variables, stage): a partial object calls it without a frame of its own
        partial_function: Op = functools.partial(run, s.vars, s.stage)
        cache[key] = partial_function
        return partial_function

    def _case_groups(self, rt: Runtime, subs: dict[str, SubsystemState]) -> None:
        index = {p.name: p.index for p in self.net.places}
        tindex = {t.name: t.index for t in self.net.transitions}
        net = self.net
        for page in self.hpn.pages.values():
            s = subs.get(page.owner)
            if page.kind is not PageKind.PARTIAL or s is None:
                continue
            p_in, p_out = index[page.in_place], index[page.out_place]
            rows: dict[int, tuple[int, int, Op | None, int]] = {}
            splits: set[tuple[int, ...]] = set()
            ok = True
            for t in self.hpn.index().net(page.id).transitions:
                cond = t.condition
                if cond is None or cond.kind is not CondKind.CASE:
                    continue
                assert cond.new is not None
                row = case_rule.number_of(cond.new) - 1
                splits.add(case_rule.split_of(cond.new))
                ft = net.transitions[tindex[t.id]]
                if ft.pre != (p_in,) or len(ft.post) != 1 or row in rows or len(splits) > 1:
                    ok = False
                    break
                place = ft.post[0]
                done = [net.transitions[u] for u in net.rule.consumers[place]
                        if net.transitions[u].pre == (place,)]
                if len(done) != 1 or done[0].post != (p_out,) or rt.effects[ft.index] \
                        or rt.effects[done[0].index]:
                    ok = False
                    break
                rows[row] = (ft.index, place, rt.ops[place], done[0].index)
            split = next(iter(splits), ())
            size = 1 << len(split)
            if ok and sorted(rows) == list(range(size)):
                rt.case_groups[p_in] = CaseGroup(s, p_in, p_out,
                                                 tuple(rows[m] for m in range(size)), split,
                                                 case_rule.selector(split))

    # ------------------------------------------------------------------ transitions
    def _transition(self, rt: Runtime, ft: FlatTransition, subs: dict[str, SubsystemState],
                    devs: dict[str, DeviceState], compilers: dict[str, ExprCompiler]) -> None:
        t = self.hpn.transitions[ft.name]
        page = self.hpn.pages[t.page]
        starts = page.in_place in self.arcs_in[t.id]
        ends = page.out_place in self.arcs_out[t.id]
        i = ft.index
        if page.kind is PageKind.DEVICE:
            dev = devs.get(page.owner)
            if dev is not None and (starts or ft.role.value == "iteration"):
                rt.gates[i] = dev.ticker
            return
        s = subs.get(page.owner)
        if s is None:
            return
        cond = t.condition
        match page.kind:
            case PageKind.PARTIAL if cond is not None and cond.kind is CondKind.CASE:
                assert cond.new is not None
                varpi, split = case_rule.number_of(cond.new), case_rule.split_of(cond.new)
                if split:
                    rt.guards[i] = lambda: case_rule.case_number(s.new_mask, split) == varpi
            case PageKind.FUNCTION if starts:
                rt.effects[i] = _freeze_new(s)
            case PageKind.FUNCTION if ends:
                rt.effects[i] = _commit(s)
            case PageKind.BEHAVIOUR:
                self._behaviour_transition(rt, i, s, starts, cond)
            case PageKind.SUBSYSTEM:
                self._switch_transition(rt, ft, s, starts, compilers[s.id])

    def _behaviour_transition(self, rt: Runtime, i: int, s: SubsystemState, starts: bool,
                              cond: Any) -> None:
        if starts:
            rt.gates[i] = s.ticker
            return
        if cond is None:
            return
        if cond.kind is CondKind.CONTINUE:
            rt.gates[i] = s.ticker
            rt.effects[i] = _next_iteration(s)
            if cond.constant is not True:
                rt.guards[i] = lambda: not s.stop()
                ft = rt.net.transitions[i]     # t_4 and t_out leave the same place
                if ft.behaviour is not None:
                    s.condition_places[ft.behaviour] = rt.net.places[ft.pre[0]].name
                if s.condition_failed is None:
                    s.condition_failed = _condition_failed(rt, s)
        elif cond.kind is CondKind.STOP:
            rt.effects[i] = _behaviour_ends(s)
            if cond.constant is not True:
                rt.guards[i] = s.stop

    def _switch_transition(self, rt: Runtime, ft: FlatTransition, s: SubsystemState,
                           starts: bool, compiler: ExprCompiler) -> None:
        i = ft.index
        sub = s.model
        if starts:
            initial = next(sw.target for sw in sub.switches if sw.source is None)
            rt.effects[i] = _enter(rt, s, initial, ft)
            return
        t = self.hpn.transitions[ft.name]
        assert t.condition is not None and t.condition.switch is not None
        sw = next(x for x in sub.switches if x.index == t.condition.switch)
        assert sw.source is not None
        rt.effects[i] = _switch(rt, s, sw.source, sw.target, t.condition.text, ft)
        source = sub.behaviour(sw.source)

        def guard_of(expr: Any) -> Guard:
            special = {c.name: _getter(s, c.name) for c in source.conditions}
            sc = ExprCompiler(compiler.symbols, compiler.externs, compiler.consts,
                              self._resolve_extern, special)
            sc.extra_symbols = {c.name: Symbol("condition", BOOL, c.span)
                                for c in source.conditions}
            fn = sc.expr(expr)
            env = s.vars
            return lambda: bool(fn(env))

        # the first switch (in the order sub.switches_from gives) whose condition holds
        order = sub.switches_from(sw.source)
        earlier = [guard_of(x.condition) for x in order[:order.index(sw)]
                   if x.condition is not None]
        if sw.condition is not None:
            own = guard_of(sw.condition)
            rt.guards[i] = (lambda: own() and not any(g() for g in earlier)) if earlier else own
        elif earlier:
            rt.guards[i] = lambda: not any(g() for g in earlier)


def _condition_failed(rt: Runtime, s: SubsystemState) -> Callable[[EvalError], None]:
    """A terminal or error condition failed to evaluate at the end of an iteration, in a
    behaviour with an error condition: recorded as an operation's failure is, at the place
    where the behaviour's conditions are tested."""
    def record(err: EvalError) -> None:
        place = s.condition_places.get(s.behaviour or "", "")
        rt.emit({"event": "error", "code": err.code, "message": err.message,
                 "span": str(err.span), "subsystem": s.id, "place": place, "handled": True})
    return record


def _getter(s: SubsystemState, name: str) -> Callable[[], Any]:
    return lambda: s.last_conds.get(name, False)


# ---------------------------------------------------------------- effects of transitions


def _freeze_new(s: SubsystemState) -> Effect:
    """new(x) of every input, frozen for the data cases of the transition function (the
    bound method itself; the mask it returns is read from ``s.new`` by the data cases)."""
    return s.new.freeze


def _commit(s: SubsystemState) -> Effect:
    """The join of P^f: the staged memory and outputs become the state; new(x) is used."""
    stage, variables, used = s.stage, s.vars, s.new.used

    def commit() -> None:
        if stage:
            variables.update(stage)
            stage.clear()
        used()
    return commit


def _next_iteration(s: SubsystemState) -> Effect:
    def next_iteration() -> None:
        s.conds = None
        s.failed = None
        s.completed += 1
    return next_iteration


def _behaviour_ends(s: SubsystemState) -> Effect:
    def behaviour_ends() -> None:
        if s.conds is None:      # a constant-true stop condition: nothing was evaluated
            s.evaluate_conditions()
        s.last_conds = s.conds or {}
        s.conds = None
        s.failed = None
        s.completed += 1
    return behaviour_ends


def _enter(rt: Runtime, s: SubsystemState, initial: str | None, ft: FlatTransition) -> Effect:
    def enter() -> None:
        s.behaviour = initial
        s.started = True
        if rt.tracer is not None:
            rt.emit({"event": "enter", "subsystem": s.id, "behaviour": initial,
                     "transition": ft.name, "span": str(ft.span)})
    return enter


def _switch(rt: Runtime, s: SubsystemState, source: str, target: str | None, text: str,
            ft: FlatTransition) -> Effect:
    def switch() -> None:
        s.behaviour = target
        s.switches += 1
        if target is None:
            s.ended = True
        if rt.tracer is not None:
            rt.emit({"event": "switch", "subsystem": s.id, "from": source, "to": target,
                     "condition": text, "conditions": dict(s.last_conds),
                     "transition": ft.name, "span": str(ft.span)})
    return switch


# ---------------------------------------------------------------- operations of places


def _increment(s: SubsystemState, b: BehaviourState) -> Op:
    def increment() -> None:
        s.i += 1
        b.iterations += 1
    return increment


def _send(rt: Runtime, owner: SubsystemState | DeviceState, buffer: str, ch: ChannelState,
          fp: FlatPlace) -> Op:
    variables = owner.vars
    sid, name, span = owner.id, fp.name, str(fp.span)
    put = ch.put

    def send() -> None:
        value = variables[buffer]
        overwrote = put(value)
        if rt.tracer is not None:
            rt.emit({"event": "send", "subsystem": sid, "buffer": buffer, "channel": ch.id,
                     "value": to_json(value), "overwrote": overwrote, "place": name,
                     "span": span})
    return send


def _receive(rt: Runtime, owner: SubsystemState | DeviceState, buffer: str,
             ch: ChannelState, fp: FlatPlace) -> Op:
    variables = owner.vars
    sid, name, span = owner.id, fp.name, str(fp.span)
    if isinstance(owner, SubsystemState):
        received, k = owner.new.received, owner.inputs.index(buffer)
        take = ch.take

        def receive() -> None:
            value = take()
            variables[buffer] = value
            received(k)
            if rt.tracer is not None:
                rt.emit({"event": "receive", "subsystem": sid, "buffer": buffer,
                         "channel": ch.id, "value": to_json(value), "place": name,
                         "span": span})
        return receive
    impl = owner.impl
    dspan = owner.model.span
    device_take = ch.take

    def device_receive() -> None:
        value = device_take()
        variables[buffer] = value
        if rt.tracer is not None:
            rt.emit({"event": "receive", "subsystem": sid, "buffer": buffer, "channel": ch.id,
                     "value": to_json(value), "place": name, "span": span})
        try:
            impl.receive(buffer, value)
        except (Exception, SystemExit) as e:
            raise EvalError("E802", f"device {sid}: receive({buffer!r}) raised "
                            f"{type(e).__name__}: {e}", dspan) from e
    return device_receive


def _device_step(rt: Runtime, d: DeviceState, span: Span) -> Op:
    """The device operation: step the device, then check what it measures against the
    declared types of its outputs (E803) and store it. A device class that declares
    ``typed_measurements = True`` (see rssm_dsl.interp.device) has each output checked the
    first time it measures it; later values of an output already checked are stored as they
    are."""
    impl, variables = d.impl, d.vars
    clock, now_of = rt.clock, rt.clock.now
    simulated = clock if isinstance(clock, SimClock) else None   # read, not called: cheaper
    convert = {b.name: converter(b.type) for b in d.model.outputs}
    default_dt = d.ticker.period if d.ticker is not None else 0
    typed = getattr(impl, "typed_measurements", False) is True
    checked: set[str] = set()           # outputs of a typed device checked once

    def device_step() -> None:
        now = simulated.ns if simulated is not None else now_of()
        dt = default_dt if d.last_step is None else now - d.last_step
        d.last_step = now
        d.steps += 1
        try:
            impl.step(dt / 1e9)
            measured = impl.measure()
        except (Exception, SystemExit) as e:     # sys.exit() in a device fails its step
            raise EvalError("E802", f"device {d.id} failed to step: {type(e).__name__}: {e}",
                            span) from e
        if typed and checked.issuperset(measured):
            variables.update(measured)
            return
        try:
            variables.update(measured_values(convert, measured))
        except MeasurementError as e:
            raise EvalError("E803", f"device {d.id} {e.message}", span,
                            "return the declared type (see rssm_dsl.interp.values)"
                            if e.wrong_type else None) from None
        if typed:
            checked.update(measured)
    return device_step


def _chosen(bindings: dict[str, str], device: str) -> str | None:
    """The binding given for a device: by its id, else by the first matching pattern."""
    if device in bindings:
        return bindings[device]
    return next((b for pattern, b in bindings.items() if fnmatchcase(device, pattern)), None)


def build_runtime(comp: Compilation, config: RunConfig | None = None) -> Runtime:
    """Bind a compiled specification for a run; raises SetupError listing every problem."""
    if comp.system is None or comp.hpn is None or not comp.ok:
        raise ValueError("build_runtime needs a specification that compiled without errors")
    return _Builder(comp, config or RunConfig(base_dir=comp.path.parent)).build()
