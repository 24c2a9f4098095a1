"""Minimal semi-positive place invariants (P-semiflows) and what they prove.

A P-semiflow is a vector ``y >= 0``, ``y != 0``, with ``y . C = 0`` for the incidence matrix
``C``: the weighted token count ``y . m`` is the same in every reachable marking. The minimal
ones (minimal support; they are the extreme rays of the cone of semiflows) are computed with
the Farkas algorithm in the Martinez-Silva form: start from ``[C | I]``, eliminate one
transition column at a time by combining each row with a positive entry with each row with a
negative entry, and keep only the combinations of *adjacent* rows (the combinatorial test of
the double description method: rows ``a`` and ``b`` are combined only if no third row has a
support inside the union of ``supp(a)`` and ``supp(b)``), so that every intermediate row is an
extreme ray and no non-minimal or duplicate row is ever stored. Arithmetic is exact: int64
with an overflow guard that switches to Python integers.

The number of minimal semiflows can grow exponentially (a choice between two parallel blocks
multiplies their branch counts), so the computation stops at ``max_rows`` intermediate rows, at
its own deadline, when the next step's matrices would not fit under the run's memory limit, or
when the run's budget stops it (``budget.py``), with a message. Rows that no longer touch
any remaining column are already final minimal semiflows, so an interrupted run still returns
the ones it completed (``complete`` is then false) and they still prove what they prove.

Safeness: a semiflow ``y`` with ``y_p > 0`` bounds place ``p`` by ``floor(y . m0 / y_p)``, so
``p`` is safe when ``y . m0 < 2 y_p`` (for a 0/1 semiflow: it carries one token). When every
place is bounded this way the net is safe without exploring a single state.
"""

from __future__ import annotations

import math
import time
from dataclasses import field

import numpy as np
import numpy.typing as npt

from rssm_core.records import dataclass
from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.verify.budget import Budget, LimitReached, format_size

IntMatrix = npt.NDArray[np.int64] | npt.NDArray[np.object_]

DEFAULT_MAX_ROWS = 20_000
MAX_CELLS = 1 << 24                 # places x (places + transitions): beyond, not computed
_SAFE_MAGNITUDE = 1 << 62
_PAIR_CELLS = 1 << 24               # rows x pairs per adjacency-test block


@dataclass(frozen=True, slots=True)
class Invariant:
    """One minimal P-semiflow: ``sum(w * m(p)) == tokens`` in every reachable marking."""

    weights: tuple[tuple[int, int], ...]   # (place index, weight > 0), by place index
    tokens: int                            # the weighted token count of the initial marking

    @property
    def support(self) -> frozenset[int]:
        return frozenset(p for p, _ in self.weights)

    def bound(self, place: int) -> int | None:
        """The bound this invariant gives on ``place``, or None if it does not cover it."""
        for p, w in self.weights:
            if p == place:
                return self.tokens // w
        return None

    def render(self, net: FlatNet, names: bool = False) -> str:
        terms = []
        for p, w in self.weights:
            place = net.places[p]
            name = place.name if names else place.label or place.name
            terms.append(name if w == 1 else f"{w}*{name}")
        return f"{' + '.join(terms)} = {self.tokens}"


@dataclass(frozen=True)
class InvariantResult:
    invariants: tuple[Invariant, ...]
    complete: bool                 # False: the computation stopped early (see message)
    message: str | None
    seconds: float
    proof: dict[int, int] = field(default_factory=dict)  # safe place -> index of its invariant

    @property
    def safe_places(self) -> frozenset[int]:
        return frozenset(self.proof)

    def proves_safe(self, nplaces: int) -> bool:
        return len(self.proof) == nplaces

    def token_flows(self) -> tuple[list[int], int]:
        """The 0/1 semiflows as place masks: those carrying one token (exactly one of
        their places is marked in every reachable marking), and the places of those
        carrying none (never marked)."""
        flows: list[int] = []
        empty = 0
        for i in self.invariants:
            if any(w != 1 for _, w in i.weights):
                continue
            mask = 0
            for p, _ in i.weights:
                mask |= 1 << p
            if i.tokens == 1:
                flows.append(mask)
            elif i.tokens == 0:
                empty |= mask
        return flows, empty

    def uncovered(self, nplaces: int) -> list[int]:
        """Places whose safeness the invariants do not prove."""
        return [p for p in range(nplaces) if p not in self.proof]


class _Stopped(Exception):
    pass


class _Limits:
    """The computation's own deadline and the run's budget."""

    def __init__(self, deadline: float | None, budget: Budget | None) -> None:
        self.deadline, self.budget = deadline, budget

    def check(self, where: str) -> None:
        """Raise ``_Stopped`` at the deadline or when the run's budget stops it."""
        if self.deadline is not None and time.monotonic() > self.deadline:
            raise _Stopped(f"time limit reached {where}")
        if self.budget is not None:
            try:
                self.budget.check()
            except LimitReached as e:
                by = "Ctrl-C" if e.stop.kind == "interrupt" else f"the run's {e.stop.kind} limit"
                raise _Stopped(f"stopped by {by} {where}") from None

    def need(self, nbytes: int, where: str) -> None:
        """Raise ``_Stopped`` when ``nbytes`` more would not fit under the memory limit (the
        run goes on without the rest of the invariants)."""
        if self.budget is not None and not self.budget.fits(nbytes):
            limit = self.budget.max_memory or 0
            raise _Stopped(f"{where}, the next step would need about {format_size(nbytes)} "
                           f"more, over the memory limit of {format_size(limit)}")


def incidence_matrix(net: FlatNet) -> npt.NDArray[np.int64]:
    """C[p, t] = post - pre (test arcs cancel out)."""
    c = np.zeros((len(net.places), len(net.transitions)), dtype=np.int64)
    for t in net.transitions:
        for p in t.pre:
            c[p, t.index] -= 1
        for p in t.post:
            c[p, t.index] += 1
    return c


def minimal_semiflows(
    c: npt.NDArray[np.int64],
    max_rows: int = DEFAULT_MAX_ROWS,
    deadline: float | None = None,
    budget: Budget | None = None,
) -> tuple[list[list[int]], bool, str | None]:
    """The minimal P-semiflows of incidence matrix ``c`` (places x transitions).

    Returns (semiflows as dense integer lists, complete, message). Each semiflow is divided by
    the gcd of its entries. When the computation stops early, only the semiflows already
    finished are returned.
    """
    nplaces, ntrans = c.shape
    limits = _Limits(deadline, budget)
    try:
        limits.need(16 * nplaces * (nplaces + ntrans), "not computed")
    except _Stopped as stop:
        return [], False, str(stop)
    a: IntMatrix = c if c.dtype == np.int64 else c.astype(np.int64)   # never written to
    y: IntMatrix = np.eye(nplaces, dtype=np.int64)
    remaining = np.flatnonzero(a.any(axis=0)).tolist() if a.size else []
    done = 0
    try:
        while remaining:
            limits.check(f"after eliminating {done} of {done + len(remaining)} transition "
                         f"columns ({a.shape[0]} intermediate rows)")
            j = _pick_column(a, remaining)
            a, y = _eliminate(a, y, j, max_rows, limits)
            remaining.remove(j)
            done += 1
            if a.shape[0] > max_rows:
                raise _Stopped(
                    f"more than {max_rows} intermediate semiflows after eliminating {done} of "
                    f"{done + len(remaining)} transition columns; this net has too many minimal "
                    f"P-semiflows to enumerate (raise the limit to try harder)")
    except _Stopped as stop:
        return [_normalise([int(v) for v in y[i]]) for i in _finished(a, remaining)], False, \
            str(stop)
    return [_normalise([int(v) for v in row]) for row in y], True, None


def _finished(a: IntMatrix, remaining: list[int]) -> list[int]:
    """The rows that touch no remaining column (already minimal semiflows)."""
    touched = np.zeros(a.shape[0], dtype=np.bool_)
    for lo in range(0, len(remaining), 256):
        touched |= (a[:, remaining[lo:lo + 256]] != 0).any(axis=1)
    return np.flatnonzero(~touched).tolist()


def _pick_column(a: IntMatrix, remaining: list[int]) -> int:
    """The column whose elimination adds the fewest rows (pos*neg - pos - neg); the first
    such in ``remaining``."""
    npos = np.count_nonzero(a > 0, axis=0)[remaining].astype(np.int64)
    nneg = np.count_nonzero(a < 0, axis=0)[remaining].astype(np.int64)
    return remaining[int(np.argmin(npos * nneg - npos - nneg))]


def _eliminate(
    a: IntMatrix, y: IntMatrix, j: int, max_rows: int, limits: _Limits,
) -> tuple[IntMatrix, IntMatrix]:
    col = a[:, j]
    pos = np.flatnonzero(col > 0)
    neg = np.flatnonzero(col < 0)
    zero = np.flatnonzero(col == 0)
    keep_a, keep_y = a[zero], y[zero]
    if len(pos) == 0 or len(neg) == 0:
        return keep_a, keep_y
    limits.need(5 * y.size, f"while eliminating column {j}")
    support = (y != 0)
    supp_f = support.astype(np.float32)
    grid_p, grid_k = np.meshgrid(pos, neg, indexing="ij")
    pi, ki = grid_p.ravel(), grid_k.ravel()
    block = max(1, _PAIR_CELLS // max(1, support.shape[0]))
    adjacent: list[npt.NDArray[np.bool_]] = []
    for start in range(0, len(pi), block):
        limits.check(f"while eliminating column {j}")
        bi, bk = pi[start:start + block], ki[start:start + block]
        outside = ~(support[bi] | support[bk])                 # pairs x places
        # rows whose support lies inside the union: no weight outside it
        inside = (supp_f @ outside.T.astype(np.float32)) == 0  # rows x pairs
        adjacent.append(inside.sum(axis=0) == 2)
        kept = sum(int(x.sum()) for x in adjacent)
        if len(zero) + kept > max_rows:
            raise _Stopped(
                f"more than {max_rows} intermediate semiflows while eliminating a column; this "
                f"net has too many minimal P-semiflows to enumerate (raise the limit to try "
                f"harder)")
    mask = np.concatenate(adjacent)
    pi, ki = pi[mask], ki[mask]
    if len(pi) == 0:
        return keep_a, keep_y
    limits.need(3 * 8 * len(pi) * (a.shape[1] + y.shape[1]), f"while eliminating column {j}")
    fa = -col[ki]      # multiplier of the positive row (> 0)
    fb = col[pi]       # multiplier of the negative row (> 0)
    if a.dtype != np.object_ and _may_overflow(a, y, fa, fb):
        a, y = a.astype(np.object_), y.astype(np.object_)
        keep_a, keep_y = a[zero], y[zero]
        fa, fb = fa.astype(np.object_), fb.astype(np.object_)
    new_a = fa[:, None] * a[pi] + fb[:, None] * a[ki]
    new_y = fa[:, None] * y[pi] + fb[:, None] * y[ki]
    g = _row_gcd(new_y)
    new_a = new_a // g[:, None]
    new_y = new_y // g[:, None]
    return np.concatenate([keep_a, new_a]), np.concatenate([keep_y, new_y])


def _may_overflow(a: IntMatrix, y: IntMatrix, fa: IntMatrix, fb: IntMatrix) -> bool:
    big = max(int(np.abs(a).max(initial=0)), int(np.abs(y).max(initial=0)))
    mult = max(int(np.abs(fa).max(initial=0)), int(np.abs(fb).max(initial=0)))
    return 2 * big * mult >= _SAFE_MAGNITUDE


def _row_gcd(m: IntMatrix) -> IntMatrix:
    if m.dtype == np.object_:
        return np.array([math.gcd(*(int(v) for v in row)) or 1 for row in m], dtype=np.object_)
    g: npt.NDArray[np.int64] = np.gcd.reduce(np.abs(m), axis=1)
    g[g == 0] = 1
    return g


def _normalise(row: list[int]) -> list[int]:
    g = math.gcd(*row) or 1
    return [v // g for v in row]


def place_invariants(
    net: FlatNet,
    max_rows: int = DEFAULT_MAX_ROWS,
    time_limit: float | None = None,
    budget: Budget | None = None,
) -> InvariantResult:
    """The minimal P-semiflows of ``net`` and the places whose safeness they prove.
    ``time_limit`` is the computation's own; the run's ``budget`` may stop it earlier."""
    start = time.monotonic()
    deadline = None if time_limit is None else start + time_limit
    nplaces, ntrans = len(net.places), len(net.transitions)
    if nplaces * (nplaces + ntrans) > MAX_CELLS:
        return InvariantResult((), False, f"not computed: the net is too large for the dense "
                               f"computation ({nplaces:,} places, {ntrans:,} transitions)",
                               time.monotonic() - start)
    if budget is None:
        flows, complete, message = minimal_semiflows(incidence_matrix(net), max_rows, deadline)
    else:
        with budget.running("the place invariants"):
            try:
                flows, complete, message = minimal_semiflows(incidence_matrix(net), max_rows,
                                                             deadline, budget)
            except MemoryError:     # the run goes on without them
                flows, complete, message = [], False, "not computed: an allocation failed"
    m0 = net.initial
    invariants = sorted(
        (Invariant(
            weights=tuple((p, w) for p, w in enumerate(flow) if w),
            tokens=sum(w for p, w in enumerate(flow) if p in m0),
        ) for flow in flows),
        key=lambda inv: (inv.weights[0][0] if inv.weights else -1, inv.weights),
    )
    proof: dict[int, int] = {}
    for k, inv in enumerate(invariants):
        for p, w in inv.weights:
            if inv.tokens < 2 * w and p not in proof:
                proof[p] = k
    return InvariantResult(
        invariants=tuple(invariants), complete=complete, message=message,
        seconds=time.monotonic() - start, proof=proof,
    )
