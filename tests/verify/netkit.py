"""Hand-built FlatNets for the verifier tests: a small builder and a few net families."""

from __future__ import annotations

import random
from collections.abc import Iterable

from rssm_dsl.hpn.flat import FlatNet, FlatPlace, FlatTransition, Role
from rssm_dsl.source import Span

FILE = "test.rssm"


class NetBuilder:
    """Add places and transitions by name; ``build`` numbers them in creation order."""

    def __init__(self, system: str = "sys") -> None:
        self.system = system
        self.places: list[FlatPlace] = []
        self.transitions: list[FlatTransition] = []
        self.marked: set[int] = set()
        self.index: dict[str, int] = {}
        self.line = 0

    def _span(self) -> Span:
        self.line += 1
        return Span(FILE, self.line, 1, self.line, 10)

    def place(self, name: str, marked: bool = False, subsystem: str | None = None,
              behaviour: str | None = None, channel: str | None = None,
              label: str | None = None) -> int:
        if name in self.index:
            raise ValueError(f"duplicate place {name}")
        i = len(self.places)
        self.places.append(FlatPlace(
            index=i, name=name, label=label or name, span=self._span(), origin=(name,),
            subsystem=subsystem, behaviour=behaviour, channel=channel))
        self.index[name] = i
        if marked:
            self.marked.add(i)
        return i

    def p(self, name: str, **kw: object) -> int:
        """The place ``name``, created on first use."""
        if name in self.index:
            return self.index[name]
        return self.place(name, **kw)  # type: ignore[arg-type]

    def transition(self, name: str, pre: Iterable[int | str], post: Iterable[int | str],
                   role: Role = Role.STRUCTURE, subsystem: str | None = None,
                   behaviour: str | None = None, channel: str | None = None,
                   label: str | None = None) -> int:
        i = len(self.transitions)
        pre_i = tuple(sorted({self._idx(x) for x in pre}))
        post_i = tuple(sorted({self._idx(x) for x in post}))
        self.transitions.append(FlatTransition(
            index=i, name=name, label=label or name, span=self._span(), pre=pre_i,
            post=post_i, role=role, subsystem=subsystem, behaviour=behaviour, channel=channel))
        return i

    def _idx(self, x: int | str) -> int:
        return x if isinstance(x, int) else self.p(x)

    def build(self, final: Iterable[int | str] = (), subsystems: Iterable[str] = ()) -> FlatNet:
        return FlatNet(
            system=self.system, places=tuple(self.places), transitions=tuple(self.transitions),
            initial=frozenset(self.marked), final=frozenset(self._idx(x) for x in final),
            subsystems=tuple(subsystems))


# --- communication modes (docs/semantics.md#communication-modes) -----------------------

def channel(b: NetBuilder, ch: str) -> tuple[int, int]:
    """The fused places of channel ``ch``: (full, empty), initially empty."""
    full = b.place(f"{ch}.full", channel=ch)
    empty = b.place(f"{ch}.empty", marked=True, channel=ch)
    return full, empty


def send(b: NetBuilder, sub: str, ch: str, blocking: bool, src: str, dst: str) -> None:
    """Producer side of ``ch`` from place ``src`` to place ``dst`` (both of ``sub``)."""
    full, empty = b.index[f"{ch}.full"], b.index[f"{ch}.empty"]
    op = b.p(f"{sub}.snd.{ch}.op", subsystem=sub)
    kw = {"subsystem": sub, "channel": ch}
    if blocking:
        wait = b.p(f"{sub}.snd.{ch}.wait", subsystem=sub)
        b.transition(f"{sub}.snd.{ch}", [src, empty], [op], Role.SEND, **kw)
        b.transition(f"{sub}.snd.{ch}.done", [op], [wait, full], Role.SEND, **kw)
        b.transition(f"{sub}.snd.{ch}.ack", [wait, empty], [dst, empty], Role.SEND, **kw)
    else:
        b.transition(f"{sub}.snd.{ch}", [src, empty], [op], Role.SEND, **kw)
        b.transition(f"{sub}.snd.{ch}.overwrite", [src, full], [op], Role.SEND, **kw)
        b.transition(f"{sub}.snd.{ch}.done", [op], [dst, full], Role.SEND, **kw)


def receive(b: NetBuilder, sub: str, ch: str, blocking: bool, src: str, dst: str) -> None:
    full, empty = b.index[f"{ch}.full"], b.index[f"{ch}.empty"]
    op = b.p(f"{sub}.rcv.{ch}.op", subsystem=sub)
    kw = {"subsystem": sub, "channel": ch}
    b.transition(f"{sub}.rcv.{ch}", [src, full], [op], Role.RECEIVE, **kw)
    b.transition(f"{sub}.rcv.{ch}.done", [op], [dst, empty], Role.RECEIVE, **kw)
    if not blocking:
        b.transition(f"{sub}.rcv.{ch}.nothing", [src, empty], [dst, empty], Role.RECEIVE, **kw)


def loop(b: NetBuilder, sub: str, start: str, end: str) -> None:
    """The iteration transition of ``sub``: from ``end`` back to ``start``."""
    b.transition(f"{sub}.iterate", [end], [start], Role.ITERATION, subsystem=sub,
                 behaviour=f"{sub}.main")


def mode_pair(producer_blocking: bool, consumer_blocking: bool) -> FlatNet:
    """A producer loop sending on ``ch`` and a consumer loop receiving from it."""
    b = NetBuilder("pair")
    channel(b, "ch")
    b.place("prod.a", marked=True, subsystem="prod", behaviour="prod.main")
    b.place("prod.b", subsystem="prod", behaviour="prod.main")
    b.place("cons.a", marked=True, subsystem="cons", behaviour="cons.main")
    b.place("cons.b", subsystem="cons", behaviour="cons.main")
    send(b, "prod", "ch", producer_blocking, "prod.a", "prod.b")
    loop(b, "prod", "prod.a", "prod.b")
    receive(b, "cons", "ch", consumer_blocking, "cons.a", "cons.b")
    loop(b, "cons", "cons.a", "cons.b")
    return b.build(subsystems=("prod", "cons"))


def send_send_deadlock(third: bool = False) -> FlatNet:
    """A and B each send blocking to the other before receiving: both end up waiting.

    With ``third``, an independent process C loops forever: no global deadlock, but A and B
    lose progress.
    """
    b = NetBuilder("sendsend")
    channel(b, "ab")
    channel(b, "ba")
    for sub, out, inp in (("A", "ab", "ba"), ("B", "ba", "ab")):
        b.place(f"{sub}.s0", marked=True, subsystem=sub)
        b.place(f"{sub}.s1", subsystem=sub)
        b.place(f"{sub}.s2", subsystem=sub)
        send(b, sub, out, True, f"{sub}.s0", f"{sub}.s1")
        receive(b, sub, inp, True, f"{sub}.s1", f"{sub}.s2")
        loop(b, sub, f"{sub}.s0", f"{sub}.s2")
    subs = ["A", "B"]
    if third:
        b.place("C.s0", marked=True, subsystem="C")
        b.place("C.s1", subsystem="C")
        b.transition("C.work", ["C.s0"], ["C.s1"], subsystem="C")
        loop(b, "C", "C.s0", "C.s1")
        subs.append("C")
    return b.build(subsystems=subs)


def starved_consumer() -> FlatNet:
    """A producer that sends once and then loops forever without sending: C starves."""
    b = NetBuilder("starve")
    channel(b, "ch")
    b.place("P.s0", marked=True, subsystem="P")
    b.place("P.s1", subsystem="P")
    b.place("P.s2", subsystem="P")
    send(b, "P", "ch", False, "P.s0", "P.s1")
    b.transition("P.idle", ["P.s1"], ["P.s2"], subsystem="P")
    b.transition("P.spin", ["P.s2"], ["P.s1"], Role.ITERATION, subsystem="P")
    b.place("C.s0", marked=True, subsystem="C")
    b.place("C.s1", subsystem="C")
    receive(b, "C", "ch", True, "C.s0", "C.s1")
    loop(b, "C", "C.s0", "C.s1")
    return b.build(subsystems=("P", "C"))


def terminating_pipeline(n: int = 3) -> FlatNet:
    """``n`` workers fork from a start place, each runs once, join into the final place."""
    b = NetBuilder("pipe")
    b.place("start", marked=True)
    b.place("end")
    for i in range(n):
        b.place(f"w{i}.a", subsystem=f"w{i}")
        b.place(f"w{i}.b", subsystem=f"w{i}")
    b.transition("t_in", ["start"], [f"w{i}.a" for i in range(n)])
    for i in range(n):
        b.transition(f"w{i}.run", [f"w{i}.a"], [f"w{i}.b"], Role.ITERATION, subsystem=f"w{i}")
    b.transition("t_out", [f"w{i}.b" for i in range(n)], ["end"])
    return b.build(final=["end"], subsystems=[f"w{i}" for i in range(n)])


def unsafe_net() -> FlatNet:
    """Two parallel branches both put a token into the same place."""
    b = NetBuilder("unsafe")
    b.place("s", marked=True)
    b.transition("fork", ["s"], ["a", "b"])
    b.transition("ta", ["a"], ["x"])
    b.transition("tb", ["b"], ["x"])
    b.transition("tx", ["x"], ["y"])
    return b.build()


# --- random nets ----------------------------------------------------------------------

def random_product(seed: int, machines: int = 3, states: int = 4, shared: int = 2,
                   sync: float = 0.5, raw: float = 0.0, final: bool = False,
                   read: float = 0.0) -> FlatNet:
    """State machines (one token each) synchronised on shared places.

    Each machine is a random strongly connected graph of local states. Shared resources are
    complementary place pairs (``r``/``r.free``): a transition may take a resource (consume
    ``r.free``, produce ``r``) or give it back; with probability ``raw`` a transition instead
    produces a plain shared place without checking it, which may make the net unsafe; with
    probability ``read`` it only tests one of the pair (takes it and puts it back, as a
    tracked value is read). Some transitions are ITERATION transitions of their machine.
    """
    rng = random.Random(seed)
    b = NetBuilder(f"rnd{seed}")
    for r in range(shared):
        b.place(f"r{r}")
        b.place(f"r{r}.free", marked=True)
    raws = []
    for m in range(machines):
        sub = f"m{m}"
        for s in range(states):
            b.place(f"{sub}.s{s}", marked=(s == 0), subsystem=sub, behaviour=f"{sub}.b{s % 2}")
        edges = [(s, (s + 1) % states) for s in range(states)]
        for _ in range(rng.randint(0, states)):
            edges.append((rng.randrange(states), rng.randrange(states)))
        for k, (s, d) in enumerate(edges):
            pre: list[int | str] = [f"{sub}.s{s}"]
            post: list[int | str] = [f"{sub}.s{d}"]
            if shared and rng.random() < sync:
                r = rng.randrange(shared)
                if rng.random() < raw:
                    name = f"x{r}"
                    if name not in b.index:
                        raws.append(b.place(name))
                    (post if rng.random() < 0.5 else pre).append(name)
                elif read and rng.random() < read:
                    tested = f"r{r}" if rng.random() < 0.5 else f"r{r}.free"
                    pre.append(tested)
                    post.append(tested)
                elif rng.random() < 0.5:
                    pre.append(f"r{r}.free")
                    post.append(f"r{r}")
                else:
                    pre.append(f"r{r}")
                    post.append(f"r{r}.free")
            role = Role.ITERATION if d == 0 and s != d else Role.STRUCTURE
            b.transition(f"{sub}.t{k}", pre, post, role, subsystem=sub,
                         behaviour=f"{sub}.b{s % 2}")
    fin: list[int | str] = []
    if final:
        b.place("done")
        b.transition("finish", [f"m{m}.s{states - 1}" for m in range(machines)], ["done"])
        fin = ["done"]
    return b.build(final=fin, subsystems=[f"m{m}" for m in range(machines)])


def ring(n: int, tokens: int = 1, length: int = 3) -> FlatNet:
    """Dining-philosophers-like ring: n processes, each needs its two neighbouring forks."""
    b = NetBuilder(f"ring{n}")
    for i in range(n):
        b.place(f"f{i}", marked=True)
    for i in range(n):
        sub = f"ph{i}"
        left, right = f"f{i}", f"f{(i + 1) % n}"
        for s in range(length + 2):
            b.place(f"{sub}.s{s}", marked=(s == 0), subsystem=sub)
        b.transition(f"{sub}.take_left", [f"{sub}.s0", left], [f"{sub}.s1"], subsystem=sub)
        b.transition(f"{sub}.take_right", [f"{sub}.s1", right], [f"{sub}.s2"], subsystem=sub)
        for s in range(2, length + 1):
            b.transition(f"{sub}.eat{s}", [f"{sub}.s{s}"], [f"{sub}.s{s + 1}"], subsystem=sub)
        b.transition(f"{sub}.release", [f"{sub}.s{length + 1}"], [f"{sub}.s0", left, right],
                     Role.ITERATION, subsystem=sub)
    return b.build(subsystems=[f"ph{i}" for i in range(n)])


def pipeline_ring(stages: int, modes: str = "BB", work: int = 2) -> FlatNet:
    """``stages`` looping subsystems passing data around a ring of channels.

    Each stage receives from its left channel, works ``work`` steps, sends to its right
    channel. ``modes`` is the (producer, consumer) mode pair, 'B' blocking / 'N' non-blocking.
    Stage 0 starts by sending, so the ring does not deadlock in the blocking modes.
    """
    b = NetBuilder(f"pring{stages}")
    pb, cb = modes[0] == "B", modes[1] == "B"
    for i in range(stages):
        channel(b, f"c{i}")
    for i in range(stages):
        sub = f"st{i}"
        names = [f"{sub}.s{k}" for k in range(work + 3)]
        for k, name in enumerate(names):
            b.place(name, marked=(k == 0), subsystem=sub, behaviour=f"{sub}.run")
        left, right = f"c{(i - 1) % stages}", f"c{i}"
        if i == 0:
            send(b, sub, right, pb, names[0], names[1])
            for k in range(1, work + 1):
                b.transition(f"{sub}.w{k}", [names[k]], [names[k + 1]], subsystem=sub)
            receive(b, sub, left, cb, names[work + 1], names[work + 2])
        else:
            receive(b, sub, left, cb, names[0], names[1])
            for k in range(1, work + 1):
                b.transition(f"{sub}.w{k}", [names[k]], [names[k + 1]], subsystem=sub)
            send(b, sub, right, pb, names[work + 1], names[work + 2])
        loop(b, sub, names[0], names[-1])
    return b.build(subsystems=[f"st{i}" for i in range(stages)])


def hpn_like(subsystems: int = 3, behaviours: int = 2, branches: int = 2,
             producer_blocking: bool = False, consumer_blocking: bool = True,
             finish: bool = False) -> FlatNet:
    """A net shaped like a flattened RSSM HPN, for scale and structure tests.

    A system fork starts ``subsystems`` subsystems in a ring of channels (subsystem i sends to
    i+1). Each behaviour: ``p_in`` -> fork into ``branches`` partial functions, each with two
    data-availability cases -> join -> send (mode) -> ``p_2`` -> receive (mode) -> either
    ``t_4`` back to ``p_in`` or ``t_out`` to the subsystem's switch place, from which any
    behaviour may start (``f^sigma`` free choice). With ``finish`` a subsystem may also leave
    from its switch place, and the system ends when all have left.
    """
    b = NetBuilder("hpnlike")
    b.place("sys.in", marked=True)
    subs = [f"s{i}" for i in range(subsystems)]
    for i in range(subsystems):
        channel(b, f"ch{i}")
    for s in subs:
        b.place(f"{s}.in", subsystem=s)
        b.place(f"{s}.sw", subsystem=s)
    b.transition("t_in", ["sys.in"], [f"{s}.in" for s in subs])
    for i, s in enumerate(subs):
        out_ch, in_ch = f"ch{i}", f"ch{(i - 1) % subsystems}"
        for k in range(behaviours):
            beh = f"{s}.b{k}"

            def pl(name: str, beh: str = beh) -> None:
                b.place(f"{beh}.{name}", subsystem=beh, behaviour=beh)

            def tr(name: str, pre: list[int | str], post: list[int | str],
                   role: Role = Role.STRUCTURE, beh: str = beh) -> None:
                b.transition(f"{beh}.{name}", pre, post, role, subsystem=beh, behaviour=beh)

            for name in ("in", "join", "p2", "rcv", "end"):
                pl(name)
            for j in range(branches):
                pl(f"f{j}.in")
                pl(f"f{j}.out")
            tr("fork", [f"{beh}.in"], [f"{beh}.f{j}.in" for j in range(branches)])
            for j in range(branches):
                for case in ("new", "old"):
                    tr(f"f{j}.{case}", [f"{beh}.f{j}.in"], [f"{beh}.f{j}.out"], Role.CASE)
            tr("joinf", [f"{beh}.f{j}.out" for j in range(branches)], [f"{beh}.join"])
            send(b, beh, out_ch, producer_blocking, f"{beh}.join", f"{beh}.p2")
            tr("count", [f"{beh}.p2"], [f"{beh}.rcv"])
            receive(b, beh, in_ch, consumer_blocking, f"{beh}.rcv", f"{beh}.end")
            tr("t4", [f"{beh}.end"], [f"{beh}.in"], Role.ITERATION)
            tr("tout", [f"{beh}.end"], [f"{s}.sw"], Role.ITERATION)
            b.transition(f"{s}.to_b{k}", [f"{s}.sw"], [f"{beh}.in"], Role.SWITCH, subsystem=s)
        b.transition(f"{s}.init", [f"{s}.in"], [f"{s}.b0.in"], Role.SWITCH, subsystem=s)
    fin: list[int | str] = []
    if finish:
        for s in subs:
            b.place(f"{s}.out", subsystem=s)
            b.transition(f"{s}.leave", [f"{s}.sw"], [f"{s}.out"], Role.SWITCH, subsystem=s)
        b.place("sys.out")
        b.transition("t_out", [f"{s}.out" for s in subs], ["sys.out"])
        fin = ["sys.out"]
    # pages were built with the behaviour ("s1.b0") as owner: they belong to subsystem "s1"
    return _reown(b.build(final=fin, subsystems=subs))


def _reown(net: FlatNet) -> FlatNet:
    import dataclasses

    def sub(owner: str | None) -> str | None:
        return owner.split(".")[0] if owner else owner

    places = tuple(dataclasses.replace(p, subsystem=sub(p.subsystem)) for p in net.places)
    trans = tuple(dataclasses.replace(t, subsystem=sub(t.subsystem)) for t in net.transitions)
    return dataclasses.replace(net, places=places, transitions=trans)
