"""The table of expectations (expectations.py) on the verifier's state space: the full
reachability graph of the flat net of each test system, asked the structural question each
row amounts to. The net has no data and no time: the situations are markings (the consumer's
token where its receive starts, with the channel's `full` or `empty` place marked), waiting
is "no transition of the receive page is enabled", reading is "the receive operation's place
is marked", a lost sample is a send that fires while `full` is marked; the order of the
pattern and of the arrangements are monitors run along every firing sequence.

What the verifier does not model: time and frequencies (every interleaving is there), values
(conditions are free choices, so a row about which value is read or which switch holds is
checked as "the expected run is one of the net's runs"), operation failures (run-time events;
those rows are skipped with the reason). new(x) is tracked in the state (the net has places
for it, rssm_dsl/verify/datanet.py): the rows' new(x) column is checked along every firing
sequence (test_mode_row_new)."""

from __future__ import annotations

from functools import cache
from pathlib import Path

import pytest

from rssm_dsl.hpn.flat import FlatTransition, Role
from rssm_dsl.verify import Verdict
from tests.semantics import systems
from tests.semantics.expectations import (
    ARRANGEMENT_ROWS,
    ENDING_ROWS,
    MODE_ROWS,
    PAIRS,
    PATTERN_ROWS,
    SWITCH_ROWS,
    SWITCH_SEQUENCE,
    ArrangementRow,
    EndingRow,
    Mode,
    ModeRow,
    PatternRow,
    Reads,
    Situation,
    SwitchRow,
)
from tests.semantics.netview import (
    ChannelView,
    case_new,
    channel_of,
    channel_view,
    function_join,
    of_subsystem,
)
from tests.semantics.verify_runner import Monitor, StateSpace, state_space, verdict


@pytest.fixture(scope="module")
def work(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("semantics-verify")


@cache
def _space(work: Path, name: str, text: str) -> StateSpace:
    return state_space(systems.write(work, name, text))


def mode_space(work: Path, producer: Mode, consumer: Mode) -> tuple[StateSpace, ChannelView]:
    name = producer.letter + consumer.letter
    space = _space(work, f"modes_{name}",
                   systems.system("modes", systems.mode_agent(name, producer, consumer)))
    return space, channel_view(space.net, channel_of(space.net, f"{name}.e.sink", "data"))


def _consumes_arrival(space: StateSpace, ch: ChannelView) -> list[int]:
    """The receive page's transitions that take the token from where the receive starts."""
    return [t.index for t in space.net.transitions if set(t.pre) & ch.rcv_arrive]


@pytest.mark.parametrize("pair", PAIRS, ids=lambda p: p[0].letter + p[1].letter)
def test_mode_system_is_safe_and_deadlock_free(work: Path, pair: tuple[Mode, Mode]) -> None:
    space, _ = mode_space(work, *pair)
    report = verdict(space)
    assert report.verdict is Verdict.VERIFIED, report
    assert report.states == len(space.markings)


@pytest.mark.parametrize("row", MODE_ROWS, ids=lambda r: r.id)
def test_mode_row(work: Path, row: ModeRow) -> None:
    space, ch = mode_space(work, row.producer, row.consumer)
    leave = _consumes_arrival(space, ch)
    # the channel is one slot: in every state exactly one of `full`, `empty` and the places
    # of its send and receive operations (which hold the channel's token while they run) is
    # marked, so a send and a receive of one channel never overlap
    slot = [ch.full, ch.empty, *ch.send_ops, *ch.rcv_ops]
    assert all(sum(space.marked(s, p) for p in slot) == 1 for s in range(len(space.markings)))
    # the receive operation runs only by taking from `full`
    assert all(space.marked(src, ch.full) for src, _, _ in space.firings(ch.take))
    # a blocking producer never leaves its send page while its sample is not taken; a
    # non-blocking one does
    left_untaken = any(space.marked(dst, ch.full) for _, _, dst in space.firings(ch.send_done))
    assert left_untaken == (not row.producer_waits)
    # a send that fires while `full` is marked replaces a sample nobody took
    overwrites = [e for e in space.firings(ch.send_start) if space.marked(e[0], ch.full)]

    if row.situation is Situation.OVERWRITTEN:
        assert bool(overwrites) == row.arises == row.lost
        return
    assert row.arises
    full = row.situation is Situation.WAITING
    looks = space.states_where(lambda s: space.any_marked(s, ch.rcv_arrive)
                               and space.marked(s, ch.full if full else ch.empty))
    assert looks, f"the consumer never reaches its receive with {row.situation.value}"
    can_go_on = {s: any(space.enabled(s, t) for t in leave) for s in looks}
    assert set(can_go_on.values()) == {not row.consumer_waits}, "waiting"
    # what completes the receive from such a state: a take (the receive operation runs) or
    # the "nothing new" transition (it keeps its previous value)
    passes = [t for t in leave if t in ch.pass_empty]
    from_looks = {t for s in looks for t in leave if space.enabled(s, t)}
    if row.reads is Reads.PREVIOUS:
        assert from_looks and from_looks <= set(passes), from_looks
    elif row.consumer_waits:
        # it waits; whatever lets it go on is a take of the next sample
        assert all(t in ch.take for _, t, _ in space.firings(leave))
    else:
        assert from_looks and from_looks <= ch.take, from_looks
    if full:
        # a non-blocking consumer never takes "nothing new" while `full` is marked
        assert not any(space.marked(src, ch.full) for src, _, _ in space.firings(ch.pass_empty))


def _new_monitor(space: StateSpace, ch: ChannelView) -> tuple[dict[int, bool], set[int],
                                                                 set[int]]:
    consumer = ch.consumer
    cases = {t.index: case_new(space.comp, t)[0] for t in of_subsystem(space.net, consumer,
                                                                          Role.CASE)}
    ops = {t.index for t in space.net.transitions if set(t.post) & ch.rcv_ops}
    return cases, ops, set(function_join(space.net, consumer))


@pytest.mark.parametrize("row", [r for r in MODE_ROWS if r.new is not None], ids=lambda r: r.id)
def test_mode_row_new(work: Path, row: ModeRow) -> None:
    """new(x) as the consumer's next transition function sees it is true exactly when the
    receive operation ran since the previous transition function (a monitor along every
    firing sequence: monitor state 1 = the receive operation ran since the last join)."""
    space, ch = mode_space(work, row.producer, row.consumer)
    cases, ops, joins = _new_monitor(space, ch)
    assert cases and ops and joins

    def monitor(q: int, t: int) -> int | None:
        if t in ops:
            return 1
        if t in joins:
            return 0
        if t in cases and cases[t] != bool(q) and cases[t] != row.new:
            return None   # the data case the row excludes: new(x) is row.new after this
        return q

    assert not space.bad_paths(monitor)


# ---------------------------------------------------------------------------- the pattern


def _order_monitor(order: list[set[int]], reset: set[int]) -> Monitor:
    """Accepts the firing sequences in which, between two transitions of ``reset``, no
    transition of ``order[k]`` fires before one of ``order[k - 1]`` has (k >= 1)."""

    def monitor(q: int, t: int) -> int | None:
        for k, group in enumerate(order):
            if t in group:
                if k > q:
                    return None
                q = max(q, k + 1)
                break
        return 0 if t in reset else q

    return monitor


@pytest.mark.parametrize("row", PATTERN_ROWS, ids=lambda r: r.id)
def test_pattern_row(work: Path, row: PatternRow) -> None:
    space, ch = mode_space(work, Mode.NONBLOCKING, Mode.NONBLOCKING)
    net = space.net
    if row.id == "compute-then-send":
        owner, first, then = ch.producer, set(function_join(net, ch.producer)), set(ch.send_start)
    elif row.id == "receive-then-use":
        # the receive operation comes after the transition function of its iteration (so its
        # value is used by the next one)
        owner = ch.consumer
        first = set(function_join(net, owner))
        then = {t.index for t in net.transitions if set(t.post) & ch.rcv_ops}
    else:
        assert row.id == "receive-then-conditions"
        owner, first = ch.consumer, set(ch.rcv_done)
        then = {t.index for t in of_subsystem(net, owner, Role.ITERATION)}
    assert first and then
    reset = {t.index for t in of_subsystem(net, owner, Role.ITERATION)}
    assert not space.bad_paths(_order_monitor([first, then], reset))
    assert space.firings(then), "never happens"


# ---------------------------------------------------------------------------- arrangements


def _arrangement_space(work: Path, row: ArrangementRow
                       ) -> tuple[StateSpace, ChannelView, ChannelView, str]:
    agents = systems.RECEIVE_AGENTS if row.side == "receive" else systems.SEND_AGENTS
    name = next(a for a, arr in agents.items() if arr == row.arrangement)
    make = systems.receive_agent if row.side == "receive" else systems.send_agent
    space = _space(work, f"arr_{name}", systems.system("arr", make(name, row.arrangement)))
    net = space.net
    if row.side == "receive":
        a = channel_view(net, channel_of(net, f"{name}.c", "a"))
        b = channel_view(net, channel_of(net, f"{name}.c", "b"))
        return space, a, b, a.consumer
    a = channel_view(net, channel_of(net, f"{name}.e.ea", "a"))
    b = channel_view(net, channel_of(net, f"{name}.e.eb", "b"))
    return space, a, b, a.producer


@pytest.mark.parametrize("row", ARRANGEMENT_ROWS, ids=lambda r: r.id)
def test_arrangement_row(work: Path, row: ArrangementRow) -> None:
    space, a, b, owner = _arrangement_space(work, row)
    net = space.net
    receive = row.side == "receive"
    enter = {"a": a.into_arrival(net) if receive else a.into_send(net),
             "b": b.into_arrival(net) if receive else b.into_send(net)}
    done = {"a": a.rcv_done if receive else a.send_done,
            "b": b.rcv_done if receive else b.send_done}
    iterations = {t.index for t in of_subsystem(net, owner, Role.ITERATION)}
    if row.order is not None:
        first, second = row.order
        monitor = _order_monitor([set(done[first]), set(enter[second])], iterations)
        assert not space.bad_paths(monitor)
    # places of a's page (where it waits: for its data, for its take); not new(x)'s, which
    # belong to no page of the subsystem alone
    inner_a = ({q for t in net.transitions if t.channel == a.id and t.subsystem == owner
                for q in t.pre if q not in (a.full, a.empty)
                and net.places[q].subsystem == owner})
    b_while_a = any(space.any_marked(src, inner_a) for src, _, _ in space.firings(done["b"]))
    assert b_while_a == row.b_while_a_waits


# ---------------------------------------------------------------------------- switching


@pytest.fixture(scope="module")
def switching(work: Path) -> StateSpace:
    return _space(work, "switching", systems.system("sw", systems.switching_agent()))


def _behaviour_places(space: StateSpace, subsystem: str) -> dict[str, set[int]]:
    out: dict[str, set[int]] = {}
    for p in space.net.places:
        if p.subsystem == subsystem and p.behaviour is not None:
            out.setdefault(p.behaviour, set()).add(p.index)
    return out


@pytest.mark.parametrize("row", SWITCH_ROWS, ids=lambda r: r.id)
def test_switch_row(switching: StateSpace, row: SwitchRow) -> None:
    """Structure: a switch fires only from the place where the ended behaviour's page ends
    (after its `t_out`, which follows the receive page), with the subsystem's token nowhere
    else in that page. Data: the expected sequence of behaviours is a path of the state space
    that ends the subsystem (the verifier does not evaluate the integer conditions, so
    it has other paths too: an over-approximation)."""
    switches_end_behaviours(switching, "sw.c")
    assert expected_run(switching, "sw.c", [(f, t) for f, t, _ in SWITCH_SEQUENCE])


def _switches(space: StateSpace, sub: str) -> list[FlatTransition]:
    """The switches between behaviours (not the initial one)."""
    net = space.net
    return [t for t in of_subsystem(net, sub, Role.SWITCH)
            if any(net.places[q].behaviour is not None for q in t.pre)]


def switches_end_behaviours(space: StateSpace, sub: str) -> None:
    net = space.net
    places = _behaviour_places(space, sub)
    ends = of_subsystem(net, sub, Role.ITERATION)
    switches = _switches(space, sub)
    assert switches
    for t in switches:
        (src,) = t.pre
        beh = net.places[src].behaviour
        assert beh is not None
        fed_by = [u for u in ends if src in u.post]
        assert len(fed_by) == 1 and fed_by[0].behaviour == beh, t.name   # t_out, one
        for s, _, _ in space.firings([t.index]):
            marked = {q for q in places[beh] if space.marked(s, q)}
            assert marked == {src}, (t.name, marked)


def expected_run(space: StateSpace, sub: str, sequence: list[tuple[str, str | None]]) -> bool:
    """The behaviours switch in ``sequence`` (None: end) on some path, which ends the
    subsystem (its end place marked, every other of its places empty)."""
    net = space.net
    by_switch: dict[tuple[str, str | None], set[int]] = {}
    for t in _switches(space, sub):
        (src,) = t.pre
        target = next((net.places[q].behaviour for q in t.post), None)
        by_switch.setdefault((net.places[src].behaviour or "", target), set()).add(t.index)
    expected = [by_switch[step] for step in sequence]
    others = {t for ts in by_switch.values() for t in ts}

    def monitor(q: int, t: int) -> int | None:
        if q < len(expected) and t in expected[q]:
            return q + 1
        return None if t in others else q

    reached = _reachable_with(space, monitor)
    mine = {p.index for p in net.places if p.subsystem == sub}
    (end,) = {q for t in _switches(space, sub) for q in t.post
              if net.places[q].behaviour is None}
    ended = space.states_where(lambda s: {p for p in mine if space.marked(s, p)} == {end})
    return any((s, len(expected)) in reached for s in ended)


def _reachable_with(space: StateSpace, monitor: Monitor) -> set[tuple[int, int]]:
    out: dict[int, list[tuple[int, int]]] = {}
    for src, t, dst in space.edges:
        out.setdefault(src, []).append((t, dst))
    seen = {(0, 0)}
    todo = [(0, 0)]
    while todo:
        s, q = todo.pop()
        for t, dst in out.get(s, []):
            q2 = monitor(q, t)
            if q2 is not None and (dst, q2) not in seen:
                seen.add((dst, q2))
                todo.append((dst, q2))
    return seen


# ---------------------------------------------------------------------------- ending


@pytest.mark.parametrize("row", ENDING_ROWS, ids=lambda r: r.id)
def test_ending_row(work: Path, row: EndingRow) -> None:
    """An error condition ends its behaviour like a terminal one (through the behaviour's one
    `t_out`), and the run through the error path is a path of the state space."""
    if row.id == "unhandled-failure-stops":
        pytest.skip("operation failures are run-time events: the net does not model them")
    if row.id == "error-condition-path":
        space = _space(work, "errh", systems.system("e", systems.error_agent("errh", True)))
        sub, path = "errh.c", [("divide", "check"), ("check", None)]
    elif row.id == "failing-condition-is-an-error":
        space = _space(work, "errt", systems.system("e", systems.failing_condition_agent()))
        sub, path = "errt.c", [("divide", "check"), ("check", None)]
    else:
        space = _space(work, "errv", systems.system("e", systems.error_value_agent()))
        sub, path = "errv.c", [("watch", "alarm"), ("alarm", None)]
    switches_end_behaviours(space, sub)
    assert expected_run(space, sub, path)
    report = verdict(space)
    assert report.verdict is Verdict.VERIFIED, report
    assert report.unreachable_behaviours == (), report.unreachable_behaviours
