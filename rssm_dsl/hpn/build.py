"""Build the five-layer HPN of a system (paper IV), plus the device nets that close it.

Communication modes: a channel is two fused places, `1` (full: data not yet taken) and `2`
(empty), `2` marked at start; its one token lies in one of them or in the operation place of
the send or receive moving the data. Every mode page is built from the nets of
rssm_core.modes (send_net / receive_net).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import field, replace
from functools import cache

from rssm_core.modes import Mode, Slot, Step, receive_net, send_net
from rssm_core.modes import Transition as ModeTransition
from rssm_core.records import dataclass
from rssm_dsl.hpn import names as N
from rssm_dsl.hpn.flat import Role
from rssm_dsl.hpn.ir import (
    HPN,
    SYSTEM_SCOPE,
    Arc,
    Condition,
    CondKind,
    FusionName,
    FusionSet,
    Name,
    Operation,
    OpKind,
    Page,
    PageKind,
    Part,
    Place,
    Scope,
    Transition,
)
from rssm_dsl.semantics.behaviours import combination_text
from rssm_dsl.semantics.model import (
    Arrangement,
    ArrLeaf,
    ArrPar,
    ArrSeq,
    Behaviour,
    Buffer,
    Channel,
    Device,
    PartialFunction,
    Subsystem,
    System,
)
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import expr_text, stmt_text


@dataclass
class _Endpoint:
    """One side of a channel as seen from a subsystem or device: its fused places."""

    full: list[str] = field(default_factory=list)
    empty: list[str] = field(default_factory=list)


@dataclass
class _Tables:
    """The HPN's tables while it is built: plain containers, which the HPN takes over at the
    end (its own tables count their changes for its index; nothing indexes a half-built net)."""

    pages: dict[str, Page] = field(default_factory=dict)
    places: dict[str, Place] = field(default_factory=dict)
    transitions: dict[str, Transition] = field(default_factory=dict)
    arcs: list[Arc] = field(default_factory=list)
    fusions: dict[str, FusionSet] = field(default_factory=dict)
    devices: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class _Owner:
    """A subsystem or a device, as the builder needs it."""

    id: str
    sup: str            # "" for designed subsystems, "^E"/"^R" for devices
    j: str
    v: str
    inputs: tuple[Buffer, ...]
    outputs: tuple[Buffer, ...]


class HpnBuilder:
    def __init__(self, system: System) -> None:
        self.s = system
        self.h = _Tables()
        self.channel_of: dict[str, Channel] = {}
        for ch in system.channels:
            self.channel_of[ch.producer.qualified] = ch
            self.channel_of[ch.consumer.qualified] = ch
        self.ends: dict[tuple[str, str], _Endpoint] = {}  # (channel id, side) -> fused places
        self._bodies: dict[int, str] = {}
        self._scopes: dict[str, Scope] = {}  # page id -> where it lies

    # ------------------------------------------------------------------ primitives
    # Elements are named by `names` (N.place(...), ...); the primitives give each name its
    # scope (the page it lies on), store it as the element's key and return the printed id.
    def _page(self, name: Name, kind: PageKind, parent: str | None, span: Span, label: str,
              owner: str, in_id: Name, out_id: Name, behaviour: str | None = None,
              initial: bool = False) -> str:
        above = self._scopes[parent] if parent is not None else SYSTEM_SCOPE
        scope = above.below(kind, name.within(above).local)
        key = name.within(scope)
        pid = key.text
        self._scopes[pid] = scope
        self.h.pages[pid] = Page(pid, kind, parent, in_id.text, out_id.text, span, label, owner,
                                 behaviour, key)
        self._place(in_id, pid, span, f"{label}: start", initial=initial)
        self._place(out_id, pid, span, f"{label}: end")
        return pid

    def _place(self, name: Name, page: str, span: Span, label: str, op: Operation | None = None,
               initial: bool = False, fusion: str | None = None) -> str:
        key = name.within(self._scopes[page])
        pid = key.text
        assert pid not in self.h.places, pid
        self.h.places[pid] = Place(pid, page, span, label, op, fusion, initial, key)
        return pid

    def _trans(self, name: Name, page: str, span: Span, label: str, role: Role = Role.STRUCTURE,
               cond: Condition | None = None) -> str:
        key = name.within(self._scopes[page])
        tid = key.text
        assert tid not in self.h.transitions, tid
        self.h.transitions[tid] = Transition(tid, page, span, label, role, cond, key)
        return tid

    def _arcs(self, page: str, sources: Sequence[str | Name], t: str | Name,
              targets: Sequence[str | Name]) -> None:
        tid = t if isinstance(t, str) else t.text
        arcs = self.h.arcs
        for s in sources:
            arcs.append(Arc(page, s if isinstance(s, str) else s.text, tid))
        for d in targets:
            arcs.append(Arc(page, tid, d if isinstance(d, str) else d.text))

    # ------------------------------------------------------------------ layers 1-3
    def build(self) -> HPN:
        s = self.s
        root = self._page(N.system_page(), PageKind.SYSTEM, None, s.span, f"system {s.name}",
                          s.name, N.place("in"), N.place("out"), initial=True)
        agent_pages = [self._agent(a.name, a.designator, a.subsystems, a.span, root)
                       for a in s.agents]
        self._trans(N.transition("in"), root, s.span, f"system {s.name} starts")
        self._trans(N.transition("out"), root, s.span, f"system {s.name} ends")
        self._arcs(root, [N.place("in")], N.transition("in"), agent_pages)
        self._arcs(root, agent_pages, N.transition("out"), [N.place("out")])
        for a in s.agents:
            for d in a.devices:
                self._device(d, a.designator)
        self._fusions()
        h = self.h
        return HPN(s.name, root, h.pages, h.places, h.transitions, h.arcs, h.fusions, h.devices)

    def _agent(self, name: str, j: str, subsystems: tuple[Subsystem, ...], span: Span,
               parent: str) -> str:
        pid = self._page(N.page(j), PageKind.AGENT, parent, span, f"agent {name}", name,
                         N.place(j, "in"), N.place(j, "out"))
        sub_pages = [self._subsystem(sub, j, pid) for sub in subsystems]
        t_in = self._trans(N.transition(j, "in"), pid, span, f"agent {name} starts")
        t_out = self._trans(N.transition(j, "out"), pid, span, f"agent {name} ends")
        self._arcs(pid, [N.place(j, "in")], t_in, sub_pages)
        self._arcs(pid, sub_pages, t_out, [N.place(j, "out")])
        return pid

    def _owner(self, sub: Subsystem | Device, j: str) -> _Owner:
        sup = "" if isinstance(sub, Subsystem) else f"^{sub.letter}"
        return _Owner(sub.id, sup, j, sub.name, sub.inputs, sub.outputs)

    def _subsystem(self, sub: Subsystem, j: str, parent: str) -> str:
        v = sub.name
        pid = self._page(N.page(j, v), PageKind.SUBSYSTEM, parent, sub.span, sub.id, sub.id,
                         N.place(j, v, "in"), N.place(j, v, "out"))
        owner = self._owner(sub, j)
        pages = {b.name: self._behaviour(sub, owner, b, pid) for b in sub.behaviours}
        for sw in sub.switches:
            if sw.source is None:
                t = self._trans(N.transition(j, v, "in"), pid, sw.span,
                                f"{sub.id} starts in behaviour {sw.target}", Role.SWITCH)
                self._arcs(pid, [N.place(j, v, "in")], t, [pages[str(sw.target)]])
                continue
            text = "otherwise" if sw.condition is None else expr_text(sw.condition)
            constant = (sw.condition.value if isinstance(sw.condition, ast.Literal)
                        and isinstance(sw.condition.value, bool) else None)
            cond = Condition(CondKind.SWITCH, sub.id, text, sw.source, switch=sw.index,
                             constant=True if sw.condition is None else constant)
            target = pages[sw.target] if sw.target is not None else N.place(j, v, "out")
            where = f"behaviour {sw.target}" if sw.target is not None else "the end"
            t = self._trans(N.transition(j, v, sw.index), pid, sw.span,
                            f"{sub.id} switches from {sw.source} to {where} [{text}]",
                            Role.SWITCH, cond)
            self._arcs(pid, [pages[sw.source]], t, [target])
        return pid

    # ------------------------------------------------------------------ layer 4
    def _behaviour(self, sub: Subsystem, o: _Owner, b: Behaviour, parent: str) -> str:
        j, v, w = o.j, o.v, b.name
        who = f"{sub.id} ({w})"
        pid = self._page(N.page(j, v, w, sup="^B"), PageKind.BEHAVIOUR, parent, b.span,
                         f"{sub.id} behaviour {w}", sub.id, N.place(j, v, w, "in"),
                         N.place(j, v, w, "out"), w)
        p2 = self._place(N.place(j, v, w, 2), pid, b.span, f"{who} i := i + 1",
                         Operation(OpKind.INCREMENT, sub.id, "i := i + 1", w))
        f_page = self._function(sub, o, b, pid)
        snd = self._comm(o, b.send, "snd", pid, b.span, w) if b.send is not None else None
        rcv = self._comm(o, b.receive, "rcv", pid, b.span, w) if b.receive is not None else None
        self._arcs(pid, [N.place(j, v, w, "in")],
                   self._trans(N.transition(j, v, w, "in"), pid, b.span, f"{who} begins"),
                   [f_page])
        t1 = self._trans(N.transition(j, v, w, 1), pid, b.span, f"{who} has computed f")
        if snd is not None:
            self._arcs(pid, [f_page], t1, [snd])
            t2 = self._trans(N.transition(j, v, w, 2), pid, b.span, f"{who} has sent")
            self._arcs(pid, [snd], t2, [p2])
        else:
            self._arcs(pid, [f_page], t1, [p2])
        last = p2
        if rcv is not None:
            t3 = self._trans(N.transition(j, v, w, 3), pid, b.span, f"{who} receives")
            self._arcs(pid, [p2], t3, [rcv])
            last = rcv
        conds = b.conditions
        stop_text = " or ".join(c.name for c in conds) or "false"
        live = [c for c in conds if not c.never]
        always = any(isinstance(c.expr, ast.Literal) and c.expr.value is True for c in conds)
        t4 = self._trans(
            N.transition(j, v, w, 4), pid, b.span, f"{who} iterates",
            Role.ITERATION, Condition(CondKind.CONTINUE, sub.id, f"not ({stop_text})", w,
                                      constant=False if always else (True if not live else None)),
        )
        self._arcs(pid, [last], t4, [f_page])
        t_out = self._trans(
            N.transition(j, v, w, "out"), pid, b.span, f"{who} ends [{stop_text}]",
            Role.ITERATION, Condition(CondKind.STOP, sub.id, stop_text, w,
                                      constant=True if always else (False if not live else None)),
        )
        self._arcs(pid, [last], t_out, [N.place(j, v, w, "out")])
        return pid

    # ------------------------------------------------------------------ layer 5: f
    def _function(self, sub: Subsystem, o: _Owner, b: Behaviour, parent: str) -> str:
        j, v, w = o.j, o.v, b.name
        pid = self._page(N.page(j, v, w, sup="^f"), PageKind.FUNCTION, parent, b.span,
                         f"{sub.id} ({w}) transition function", sub.id,
                         N.place(j, v, w, "f", "in"), N.place(j, v, w, "f", "out"), w)
        parts = [self._partial(sub, o, b, pf, pid) for pf in b.functions]
        fork = self._trans(N.transition(j, v, w, "f", "in"), pid, b.span,
                           f"{sub.id} ({w}) starts its partial functions")
        join = self._trans(N.transition(j, v, w, "f", "out"), pid, b.span,
                           f"{sub.id} ({w}) has computed every partial function")
        self._arcs(pid, [N.place(j, v, w, "f", "in")], fork, parts)
        self._arcs(pid, parts, join, [N.place(j, v, w, "f", "out")])
        return pid

    def _partial(self, sub: Subsystem, o: _Owner, b: Behaviour, pf: PartialFunction,
                 parent: str) -> str:
        j, v, w, psi = o.j, o.v, b.name, pf.index
        who = f"{sub.id} ({w})"
        pid = self._page(N.page(j, v, w, psi, sup="^f"), PageKind.PARTIAL, parent, pf.span,
                         f"{who} partial function for {pf.target}", sub.id,
                         N.place(j, v, w, psi, "in"), N.place(j, v, w, psi, "out"), w)
        inputs = tuple(x.name for x in sub.inputs)
        for case in pf.cases:
            when = combination_text(inputs, case.new)
            body = self._body_text(case.body)
            op = Operation(OpKind.CASE, sub.id, body, w, pf.target, case.index, void=case.void)
            p = self._place(N.place(j, v, w, psi, case.index), pid, case.span,
                            f"{who} {pf.target}: {body}", op)
            t_case = self._trans(
                N.transition(j, v, w, psi, case.index), pid, case.span,
                f"{who} computes {pf.target} when {when}", Role.CASE,
                Condition(CondKind.CASE, sub.id, when, w, new=case.new),
            )
            self._arcs(pid, [N.place(j, v, w, psi, "in")], t_case, [p])
            t_done = self._trans(N.transition(j, v, w, psi, case.index, "out"), pid, case.span,
                                 f"{who} has computed {pf.target}")
            self._arcs(pid, [p], t_done, [N.place(j, v, w, psi, "out")])
        return pid

    def _body_text(self, body: tuple[ast.Stmt, ...]) -> str:
        key = id(body)
        text = self._bodies.get(key)
        if text is None:
            text = self._bodies[key] = "; ".join(stmt_text(st) for st in body) or "skip"
        return text

    # ------------------------------------------------------------------ layer 5: snd/rcv
    def _comm(self, o: _Owner, arr: Arrangement, verb: str, parent: str, span: Span,
              w: str | None) -> str:
        """The arrangement sublayer page (P_snd / P_rcv) and its per-buffer mode pages."""
        base = (o.j, o.v, w, verb) if w is not None else (o.j, o.v, verb)
        who = f"{o.id} ({w})" if w is not None else o.id
        kind = PageKind.SEND if verb == "snd" else PageKind.RECEIVE
        pid = self._page(N.page(*base, sup=o.sup or "^B"), kind, parent, span,
                         f"{who} {'sends' if verb == 'snd' else 'receives'}", o.id,
                         N.place(*base, "in", sup=o.sup), N.place(*base, "out", sup=o.sup), w)
        buffers = o.outputs if verb == "snd" else o.inputs
        index = {b.name: i for i, b in enumerate(buffers, start=1)}
        named: dict[str, Buffer] = {}
        for b in buffers:
            named.setdefault(b.name, b)
        counter = [0]

        def internal(span: Span) -> str:
            counter[0] += 1
            return self._trans(N.transition(*base, f"a{counter[0]}", sup=o.sup), pid, span,
                               f"{who} continues {'sending' if verb == 'snd' else 'receiving'}")

        def emit(a: Arrangement) -> tuple[list[str], list[str]]:
            match a:
                case ArrLeaf():
                    buf = named[a.buffer]        # (a scan per leaf: quadratic in them)
                    page = self._mode_page(o, buf, verb, index[a.buffer], pid, base, who, w)
                    return [page], [page]
                case ArrPar():
                    starts: list[str] = []
                    ends: list[str] = []
                    for item in a.items:
                        s, e = emit(item)
                        starts += s
                        ends += e
                    return starts, ends
                case ArrSeq():
                    first_s, prev_e = emit(a.items[0])
                    for item in a.items[1:]:
                        s, e = emit(item)
                        self._arcs(pid, prev_e, internal(item.span), s)
                        prev_e = e
                    return first_s, prev_e

        starts, ends = emit(arr)
        t_in = self._trans(N.transition(*base, "in", sup=o.sup), pid, span, f"{who} starts "
                           f"{'sending' if verb == 'snd' else 'receiving'}")
        t_out = self._trans(N.transition(*base, "out", sup=o.sup), pid, span, f"{who} has "
                            f"{'sent' if verb == 'snd' else 'received'} everything")
        self._arcs(pid, [N.place(*base, "in", sup=o.sup)], t_in, starts)
        self._arcs(pid, ends, t_out, [N.place(*base, "out", sup=o.sup)])
        return pid

    def _mode_page(self, o: _Owner, buf: Buffer, verb: str, k: int, parent: str,
                   base: tuple[Part, ...], who: str, w: str | None) -> str:
        ch = self.channel_of.get(buf.qualified)
        kind = PageKind.SEND_BUFFER if verb == "snd" else PageKind.RECEIVE_BUFFER
        pb = (*base, k)
        sup = o.sup
        pid = self._page(N.page(*pb, sup=sup or "^B"), kind, parent, buf.span,
                         f"{who} {'sends' if verb == 'snd' else 'receives'} {buf.name} "
                         f"({buf.mode.value})", o.id, N.place(*pb, "in", sup=sup),
                         N.place(*pb, "out", sup=sup), w)
        p_in, p_out = N.place(*pb, "in", sup=sup).text, N.place(*pb, "out", sup=sup).text
        if ch is None:  # an unconnected device buffer: the page passes straight through
            self._arcs(pid, [p_in], self._trans(N.transition(*pb, 1, sup=sup), pid, buf.span,
                                                f"{who} skips unconnected {buf.name}"), [p_out])
            return pid
        side = "producer" if verb == "snd" else "consumer"
        ends = self.ends.setdefault((ch.id, side), _Endpoint())
        chan = f"channel {ch.producer.qualified} -> {ch.consumer.qualified}"
        full = self._place(N.place(*pb, 1, sup=sup), pid, buf.span, f"{chan}: full")
        empty = self._place(N.place(*pb, 2, sup=sup), pid, buf.span, f"{chan}: empty")
        ends.full.append(full)
        ends.empty.append(empty)
        op_kind = OpKind.SEND if verb == "snd" else OpKind.RECEIVE
        op = self._place(N.place(*pb, "op", sup=sup), pid, buf.span,
                         f"{who} {'sends' if verb == 'snd' else 'receives'} {buf.name}",
                         Operation(op_kind, o.id, f"{verb} {buf.name}", w, buf.name,
                                   channel=ch.id))

        mode = buf.mode

        def label(step: Step) -> str:      # (only those of the steps of this mode's net)
            match step:
                case Step.START_SEND:
                    return f"starts sending {buf.name} ({mode.value}, {chan} empty)"
                case Step.OVERWRITE:
                    return f"overwrites unread {buf.name} (nonblocking)"
                case Step.SENT:
                    return f"has sent {buf.name}"
                case Step.SENT_WAIT:
                    return f"has sent {buf.name}, waits until it is taken"
                case Step.SEEN_TAKEN:
                    return f"sees {buf.name} taken (blocking)"
                case Step.TAKE:
                    return f"takes new {buf.name} ({mode.value})"
                case Step.RECEIVED:
                    return f"has received {buf.name}"
                case Step.NOTHING_NEW:
                    return f"finds no new {buf.name} (nonblocking)"
            raise ValueError(step)
        places = {Slot.IN: p_in, Slot.OUT: p_out, Slot.OP: op, Slot.FULL: full,
                  Slot.EMPTY: empty}

        def place(slot: Slot) -> str:
            if slot not in places:            # Slot.WAIT, made when first needed
                places[slot] = self._place(
                    N.place(*pb, "wait", sup=sup), pid, buf.span,
                    f"{who} waits in blocking send of {buf.name} on {chan}")
            return places[slot]

        role = Role.SEND if verb == "snd" else Role.RECEIVE
        for tr in _mode_net(verb, mode):
            inputs = [place(x) for x in tr.inputs]
            outputs = [place(x) for x in tr.outputs]
            tid = self._trans(N.transition(*pb, tr.number, sup=sup), pid, buf.span,
                              f"{who} {label(tr.step)}", role)
            self._arcs(pid, inputs, tid, outputs)
        return pid

    # ------------------------------------------------------------------ devices
    def _device(self, d: Device, j: str) -> None:
        o = self._owner(d, j)
        sup, v = o.sup, d.name
        label = f"device {d.id} ({d.device_type})"
        pid = self._page(N.page(j, v, sup=sup), PageKind.DEVICE, None, d.span, label, d.id,
                         N.place(j, v, "in", sup=sup), N.place(j, v, "out", sup=sup),
                         initial=True)
        self.h.devices.append(pid)
        op = self._place(N.place(j, v, "op", sup=sup), pid, d.span, f"{d.id} steps",
                         Operation(OpKind.DEVICE, d.id, f"step {d.device_type}"))

        def seq(buffers: tuple[Buffer, ...]) -> Arrangement:
            leaves = tuple(ArrLeaf(b.name, b.span) for b in buffers)
            return leaves[0] if len(leaves) == 1 else ArrSeq(leaves, d.span)

        rcv = self._comm(o, seq(d.inputs), "rcv", pid, d.span, None) if d.inputs else None
        snd = self._comm(o, seq(d.outputs), "snd", pid, d.span, None) if d.outputs else None
        first = rcv or op
        self._arcs(pid, [N.place(j, v, "in", sup=sup)],
                   self._trans(N.transition(j, v, "in", sup=sup), pid, d.span, f"{d.id} starts",
                               Role.DEVICE), [first])
        if rcv is not None:
            self._arcs(pid, [rcv], self._trans(N.transition(j, v, 1, sup=sup), pid, d.span,
                                               f"{d.id} has received", Role.DEVICE), [op])
        last = op
        if snd is not None:
            self._arcs(pid, [op], self._trans(N.transition(j, v, 2, sup=sup), pid, d.span,
                                              f"{d.id} has stepped", Role.DEVICE), [snd])
            last = snd
        self._arcs(pid, [last], self._trans(N.transition(j, v, 4, sup=sup), pid, d.span,
                                            f"{d.id} loops", Role.ITERATION), [first])

    # ------------------------------------------------------------------ fusion sets
    def _fusions(self) -> None:
        by_id: dict[str, Subsystem | Device] = {s.id: s for s in self.s.subsystems()}
        by_id.update({d.id: d for d in self.s.devices()})
        j_of = {x: a.designator for a in self.s.agents
                for x in [s.id for s in a.subsystems] + [d.id for d in a.devices]}
        # a buffer's position among its owner's outputs (rho) or inputs (kappa), from 1; by
        # owner, made once (a scan per channel was quadratic in the buffers of a subsystem)
        positions: dict[tuple[str, bool], dict[str, int]] = {}

        def position(x: Subsystem | Device, name: str, output: bool) -> int:
            table = positions.get((x.id, output))
            if table is None:
                table = positions[(x.id, output)] = {}
                for i, b in enumerate(x.outputs if output else x.inputs, start=1):
                    table.setdefault(b.name, i)
            return table[name]

        for ch in self.s.channels:
            prod, cons = by_id[ch.producer.owner], by_id[ch.consumer.owner]
            rho = position(prod, ch.producer.name, output=True)
            kappa = position(cons, ch.consumer.name, output=False)
            p_ends = self.ends.get((ch.id, "producer"), _Endpoint())
            c_ends = self.ends.get((ch.id, "consumer"), _Endpoint())
            chan = f"channel {ch.producer.qualified} -> {ch.consumer.qualified} ({ch.modes})"
            for which, members, initial, state in (
                (FusionName.FULL, p_ends.full + c_ends.full, False, "full"),
                (FusionName.EMPTY, p_ends.empty + c_ends.empty, True, "empty"),
            ):
                key = N.fusion((j_of[prod.id], j_of[cons.id]), (_v(prod), _v(cons)),
                               (rho, kappa), which)
                fid = key.text
                self.h.fusions[fid] = FusionSet(fid, f"{chan}: {state}", ch.id, tuple(members),
                                                initial, ch.producer.span, key)
                for m in members:
                    self.h.places[m] = replace(self.h.places[m], fusion=fid, initial=initial)


def _v(x: Subsystem | Device) -> str:
    """The designator in a fused place's name: v for a subsystem, E.h / R.l for a device."""
    return x.name if isinstance(x, Subsystem) else f"{x.letter}.{x.name}"


@cache
def _mode_net(verb: str, mode: Mode) -> tuple[ModeTransition, ...]:
    """The transitions of a mode page (made once per verb and mode, not once per buffer)."""
    return send_net(mode) if verb == "snd" else receive_net(mode)


def build_hpn(system: System) -> HPN:
    return HpnBuilder(system).build()
