"""What a random run found, confirmed in the flat net as the verifier sees it (conditions on
data as free choices), and turned into a firing sequence of the verifier's kind.

* **deadlock**: the run's firings, replayed by the firing rule from the initial marking, end
  in a marking that is not final and where no transition is enabled. (A run that stops
  because no *condition* holds among the enabled transitions is not a deadlock of the net.)
* **unsafe firing**: the firings are safe but for the last one, which double-marks a place.
* **loss of progress** (an E809 stall of subsystem ``s``): from the marking ``m`` where the
  run stopped, every marking reachable in the net (every schedule, every outcome of every
  free choice; explored whole, ``max_states`` at most) lets ``s`` complete no iteration, and
  none is a deadlock, while ``s`` is unfinished in ``m``. That is the verifier's own
  definition of a loss of progress at ``m`` (verify/progress.py, condition 1-3), so the
  strong fairness it assumes holds for the cycle printed: every continuation from ``m``,
  fair or not, starves ``s``. The cycle is one of a terminal component reachable from ``m``,
  found as the verifier finds its own.

The run's prefix is printed *shortened*: a shortest path to its last marking along the moves
the run made (the run itself may be tens of thousands of firings long), so it is a firing
sequence of the net that visits no marking twice; replayed, a few of its conditions on data
may not hold (`"forced"` in the trace), as in the verifier's own counterexamples.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from rssm_core.records import dataclass
from rssm_dsl.verify.budget import Budget, LimitReached
from rssm_dsl.verify.netbits import NetBits
from rssm_dsl.verify.progress import live_places, shortest_path, terminal_component
from rssm_dsl.verify.statespace import SearchResult, explore_full


@dataclass(frozen=True)
class Finding:
    """A violation confirmed in the net: kind ``deadlock``, ``unsafe`` or ``progress``;
    steps, to_cycle and cycle are transition indices of the verifier's net; markings are
    place masks."""

    kind: str
    steps: tuple[int, ...]
    marking: int                         # reached by steps (unsafe: before the last step)
    subsystem: str | None = None
    to_cycle: tuple[int, ...] = ()
    cycle: tuple[int, ...] = ()
    cycle_marking: int = 0
    doubled: int = 0                     # unsafe: the places marked twice


class NotConfirmed(Exception):
    """What a run showed is not a violation of the net (the message says why)."""


def markings(nb: NetBits, sequence: Sequence[int]) -> list[int]:
    """The markings along ``sequence`` from the initial one (len(sequence) + 1 of them);
    NotConfirmed at a step that is not enabled."""
    pre, post = nb.pre, nb.post
    m = nb.initial
    out = [m]
    for k, t in enumerate(sequence):
        if m & pre[t] != pre[t]:
            raise NotConfirmed(f"step {k + 1} of the run ({nb.net.transitions[t].name}) is "
                               "not enabled in the net")
        m = (m & ~pre[t]) | post[t]
        out.append(m)
    return out


def loop_erased(sequence: Sequence[int], marks: Sequence[int]) -> tuple[int, ...]:
    """A shortest firing sequence from the first marking of ``marks`` to its last one along
    the moves the run made (each firing ``sequence[k]`` from ``marks[k]`` to
    ``marks[k + 1]``, taken from any visit of ``marks[k]``): the run without its loops and
    detours."""
    goal = marks[-1]
    succ: dict[int, dict[int, int]] = {}
    for t, a, b in zip(sequence, marks, marks[1:], strict=False):
        succ.setdefault(a, {}).setdefault(t, b)
    parent: dict[int, tuple[int, int]] = {marks[0]: (-1, -1)}
    frontier = [marks[0]]
    while frontier and goal not in parent:
        nxt: list[int] = []
        for a in frontier:
            for t, b in succ.get(a, {}).items():
                if b not in parent:
                    parent[b] = (a, t)
                    nxt.append(b)
        frontier = nxt
    path: list[int] = []
    m = goal
    while parent[m][0] != -1:
        m, t = parent[m]
        path.append(t)
    return tuple(reversed(path))


def confirm_deadlock(nb: NetBits, sequence: Sequence[int]) -> Finding:
    marks = markings(nb, sequence)
    end = marks[-1]
    if nb.is_final(end):
        raise NotConfirmed("the run ended in the final marking")
    enabled = nb.enabled(end)
    if enabled:
        raise NotConfirmed(f"no condition held among {len(enabled)} enabled transition(s) "
                           "(the verifier takes conditions on data as free choices: not a "
                           "deadlock of the net)")
    return Finding("deadlock", loop_erased(sequence, marks), end)


def confirm_unsafe(nb: NetBits, sequence: Sequence[int]) -> Finding:
    if not sequence:
        raise NotConfirmed("no firing")
    marks = markings(nb, sequence[:-1])
    last, before = sequence[-1], marks[-1]
    if before & nb.pre[last] != nb.pre[last]:
        raise NotConfirmed("the last firing is not enabled in the net")
    doubled = nb.unsafe_places(before, last)
    if not doubled or any(nb.unsafe_places(m, t) for m, t in zip(marks, sequence[:-1],
                                                                   strict=False)):
        raise NotConfirmed("the firings are not safe up to the last one only")
    return Finding("unsafe", (*loop_erased(sequence[:-1], marks), last), before,
                   doubled=doubled)


def may_fire(nb: NetBits, marking: int) -> int:
    """The transitions that can fire in some firing sequence from ``marking`` (as a mask),
    over-approximated: a transition whose input places can all be marked, each at some
    time, might fire (tokens are not consumed in this closure)."""
    marked, fired = marking, 0
    pre, post = nb.pre, nb.post
    changed = True
    while changed:
        changed = False
        for t in range(nb.ntrans):
            if not fired >> t & 1 and marked & pre[t] == pre[t]:
                fired |= 1 << t
                marked |= post[t]
                changed = True
    return fired


def _run_cycle(marks: Sequence[int], start: int) -> tuple[int, int] | None:
    """A cycle of the run after ``start``: ``(i, j)`` with ``marks[i] == marks[j]``, ``i`` the
    first marking from ``start`` on that comes back, ``j`` its last visit (the longest such
    cycle: it takes every move the rest of the system kept making)."""
    last: dict[int, int] = {}
    for k in range(start, len(marks)):
        last[marks[k]] = k
    for i in range(start, len(marks)):
        if last[marks[i]] > i:
            return i, last[marks[i]]
    return None


def confirm_stall(nb: NetBits, sequence: Sequence[int], subsystem: str, budget: Budget,
                  max_states: int) -> tuple[Finding, str | None]:
    """The loss of progress of ``subsystem`` at the marking the run stopped in (see the
    module docstring), and a caveat (None: none); NotConfirmed when it is not one."""
    marks = markings(nb, sequence)
    point = marks[-1]
    if not point & live_places(nb.net, subsystem):
        raise NotConfirmed(f"{subsystem} has finished there")
    iterations = nb.iteration_mask(subsystem)
    if not iterations:
        raise NotConfirmed(f"{subsystem} has no ITERATION transition")
    search = explore_full(dataclasses.replace(nb, initial=point), max_states=max_states,
                          budget=budget)
    if search.complete and search.graph is not None:
        return _exact(nb, sequence, marks, subsystem, iterations, search, budget), None
    # too many markings from there: no iteration of the subsystem can follow, whatever
    # fires (the closure), and the run's own cycle after its last iteration shows the rest
    # running on
    if may_fire(nb, point) & iterations:
        raise NotConfirmed(f"the markings reachable from where {subsystem} stalled were not "
                           f"all explored ({search.stopped or 'incomplete'}) and it may "
                           "iterate again")
    last = max((k + 1 for k, t in enumerate(sequence) if iterations >> t & 1), default=0)
    found = next((c for c in [_run_cycle(marks, last)] if c is not None and not
                  may_fire(nb, marks[c[0]]) & iterations), None)
    if found is None:
        raise NotConfirmed(f"the run repeats no marking after {subsystem}'s last iteration")
    i, j = found
    caveat = (f"{subsystem} can never iterate again from where it stalled, whatever fires "
              "(so under any fairness); that no deadlock is reachable from there is not "
              f"shown: the markings from there were not all explored "
              f"({search.stopped or 'incomplete'})")
    return Finding("progress", loop_erased(sequence[:i], marks[:i + 1]), marks[i], subsystem,
                   (), tuple(sequence[i:j]), marks[i]), caveat


def _exact(nb: NetBits, sequence: Sequence[int], marks: list[int], subsystem: str,
           iterations: int, search: SearchResult, budget: Budget) -> Finding:
    """The verifier's loss of progress at the run's last marking, judged on every marking
    reachable from there (``search``, complete)."""
    graph = search.graph
    assert graph is not None
    point = marks[-1]
    if search.deadlock_count:
        raise NotConfirmed(f"a deadlock is reachable from where {subsystem} stalled")
    is_it = np.zeros(nb.ntrans, dtype=np.bool_)
    is_it[[t for t in range(nb.ntrans) if iterations >> t & 1]] = True
    if bool(is_it[graph.trans].any()):
        raise NotConfirmed(f"{subsystem} can still complete an iteration from where it "
                           "stalled, with the conditions on data as free choices")
    try:
        _, component = terminal_component(graph, 0, budget)
        to_cycle, entry = shortest_path(graph, 0, component)
        goal = np.zeros(graph.size, dtype=np.bool_)
        goal[entry] = True
        cycle, _ = shortest_path(graph, entry, goal, allow_empty=False)
    except LimitReached:
        raise
    except ValueError as e:        # no cycle: cannot be, no deadlock is reachable
        raise NotConfirmed(f"no cycle found from where {subsystem} stalled: {e}") from e
    return Finding("progress", loop_erased(sequence, marks), point, subsystem, to_cycle,
                   cycle, graph.marking(entry))
