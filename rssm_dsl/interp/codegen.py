"""The firing rule of every transition compiled to straight-line Python.

For the deterministic mode each transition ``t`` gets a function ``fire_t()`` that removes the
tokens of its input places, runs its effect, then for each output place puts the token, runs
the place's operation and updates the count of missing tokens of the transitions reading that
place, adding those that became enabled to the enabled set (local steps go to the stack of
local steps instead, a paced one whose tick has not come to the loop's timers: while the
deterministic loop runs, the enabled set holds only the other transitions). Place and
transition indices are constants in the code, loops over the net structure are unrolled: a
firing costs a handful of list stores instead of a walk over the incidence lists.

Each transition also gets a *macro step* ``macro_t()``: the transition and then every local
step it makes possible, in one function (see :meth:`FiringCode._macro`).

A function is compiled the first time it is called (a run uses a fraction of them, and
compiling Python is the slow part; compiled sources are kept for the next run of the
process); the number of firings of every macro step is known upfront. The generated source
contains only integers and fixed identifiers (no text of the specification); operations and
effects are reached through the namespace the code is executed in.

The code is generated from the structure of :class:`rssm_core.firing.Net` (``game.rule``: the
pre-sets, post-sets and consumers) and follows its rule: empty the input places, then for each
output place report an unsafe firing if it is still marked, and mark it. ``tests/core``
checks the compiled functions against the rule on random safe and unsafe nets.

What the generator knows is not computed at run time. A function is only called when its
transition is enabled (the scheduler makes sure of it), so the transition's own count of
missing tokens is 0 on entry: its value is a constant all through the function, written once
when the input places are emptied (no operation or effect runs in between) and again where
the output places change it, and its removal from the enabled set needs no test. An input place
the function has emptied holds no token until the function marks it again (nothing else
writes the token game while it runs), so the unsafe check of such a place is left out. Every
other count, the calls on the enabled set and the pushes on the stack of local steps are the
step-by-step rule's, in the same order, so the state any operation, effect or failure sees is
the same. The names the code uses are bound as default arguments (fast locals).

The net's place invariants say more (:func:`exclusive_places`): a place exclusive with an input
place of the transition holds no token when the function is entered (the function runs only
from markings the firing rule reaches from the initial marking, where the invariants hold).
Such a place needs no unsafe check until the function marks it; a transition reading one is not
enabled, so emptying a place it shares with the firing transition needs no test on its count
and no call on the enabled set, and marking another of its places cannot enable it. The checks
and tests left out are those whose outcome is known, so the code does what the rule says.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Collection, Mapping, Sequence, Set
from heapq import heappush
from types import CodeType
from typing import Any, TypeVar

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.interp.clock import SimClock
from rssm_dsl.interp.engine import TokenGame

Action = Callable[[], None]
Macro = Callable[[], int]        # returns its number of firings (the loop adds it up)
Step = Callable[[], object]      # an operation or an effect (what it returns is not used)
R = TypeVar("R")
MAX_MACRO = 64                   # firings in one macro step at most
# the compiled functions by name and body, shared by the runs of a process
_CODE: dict[tuple[str, str], CodeType] = {}
MAX_CACHED = 100_000
# the names of the namespace a function uses (bound as default arguments: fast locals)
_NAMES = re.compile(r"\b(?:tokens|missing|_add|_discard|_local|_timers?|_clock|_unsafe|_failure"
                    r"|[eoGNT][0-9]+)\b")
# a call out of the token game's bookkeeping: an effect, an operation, an unsafe report
_CALLS_OUT = re.compile(r"\b(?:[eo][0-9]+|co|_unsafe)\(")
INVARIANT_ROWS = 2_000           # bounds of the place invariants' computation
INVARIANT_SECONDS = 1.0
MAX_NETS = 256                   # nets whose exclusive places are kept
_EXCLUSIVE: dict[tuple[object, ...], tuple[frozenset[int], ...]] = {}   # by net structure


def _add_one(u: int, count: str) -> str:
    """The line that adds one to the count of missing tokens of ``u``, which is ``count``
    (``missing[u]`` or a local holding it): ``missing[u] = ... + 1`` takes fewer instructions
    of the interpreter than ``missing[u] += 1``."""
    return f"missing[{u}] = {count} + 1"


def exclusive_places(net: FlatNet) -> tuple[frozenset[int], ...]:
    """Per place ``q``, the places that hold no token whenever ``q`` holds one, in every
    marking reached from the initial marking by the firing rule, as the net's place
    invariants prove: ``p`` and ``q`` are in the support of a P-semiflow ``y`` whose weighted
    token count ``y . m0`` is less than ``y_p + y_q``. Invariants left out by the bounds of
    their computation only prove less. Computed once per net structure in a process."""
    key = (len(net.places), net.initial, tuple((t.pre, t.post) for t in net.transitions))
    known = _EXCLUSIVE.get(key)
    if known is not None:
        return known
    from rssm_dsl.verify.invariants import place_invariants  # numpy: imported when needed

    found = place_invariants(net, INVARIANT_ROWS, INVARIANT_SECONDS)
    exclusive: list[set[int]] = [set() for _ in net.places]
    for inv in found.invariants:
        for q, wq in inv.weights:
            exclusive[q].update(p for p, wp in inv.weights if p != q and wp + wq > inv.tokens)
    result = tuple(frozenset(ps) for ps in exclusive)
    if len(_EXCLUSIVE) >= MAX_NETS:
        _EXCLUSIVE.clear()
    _EXCLUSIVE[key] = result
    return result


class FiringCode:
    """Per transition: ``fire[t]`` fires it alone; ``macros[t]`` fires its macro step, which
    makes ``macro_len[t]`` firings and returns that number (``macros`` is None when macro
    steps are off).

    With ``timers`` and ``clock`` (the deterministic loop's heap of ``(tick, local step)`` and
    its simulated clock), a *paced* local step (see :meth:`_paced`) that becomes enabled before
    its tick goes straight into ``timers``, where the loop would put it when it takes it from
    the stack (nothing else happens to it there)."""

    def __init__(self, game: TokenGame, ops: Sequence[Step | None],
                 effects: Sequence[Step | None], guards: Sequence[object | None],
                 gates: Sequence[object | None], eager: bytearray, local: list[int],
                 case_groups: Mapping[int, Any], failure: Callable[[int, Exception], None],
                 unsafe: Callable[[int, int], None], macros: bool,
                 timers: list[tuple[int, int]] | None = None,
                 clock: SimClock | None = None) -> None:
        self.game = game
        self.ops, self.effects, self.guards, self.gates = ops, effects, guards, gates
        self.eager = eager
        self.case_groups = case_groups
        self.paced = self._paced() if timers is not None and clock is not None else set()
        # what the place invariants prove (for the net the rule describes)
        self.exclusive = exclusive_places(game.net) if game.rule is game.net.rule else \
            tuple(frozenset[int]() for _ in game.net.places)
        self.ns: dict[str, Any] = {
            "tokens": game.tokens, "missing": game.missing, "_add": game.enabled.add,
            "_discard": game.enabled.discard, "_local": local.append, "_failure": failure,
            "_unsafe": unsafe, "_timer": heappush, "_timers": timers, "_clock": clock,
        }
        for u in self.paced:
            self.ns[f"T{u}"] = gates[u]
        n = game.rule.ntransitions
        self.fire: list[Action] = [self._lazy(self.fire_table, t, self._firing)
                                   for t in range(n)]
        self.macros: list[Macro] | None = None
        self.macro_len: list[int] = [1] * n
        self._bodies: list[list[str]] = []
        if macros:
            built = [self._macro(t) for t in range(n)]
            self.macro_len = [count for _, count in built]
            self._bodies = [[*body, f"return {count}"] for body, count in built]
            self.macros = [self._lazy(self.macro_table, t, self._bodies.__getitem__)
                           for t in range(n)]

    def _paced(self) -> set[int]:
        """The local steps with a tick (a gate) whose input places no other transition reads.
        Such a step stays enabled until it fires, and simulated time stands still while the
        stack of local steps is not empty: when it becomes enabled before its tick, the loop
        takes it from the stack only to put it into the timers, at that same tick (a gate's
        next tick changes only when its tick has come)."""
        rule, gates = self.game.rule, self.gates
        return {u for u in range(rule.ntransitions)
                if self.eager[u] and gates[u] is not None
                and all(rule.consumers[p] == (u,) for p in rule.pre[u])}

    def _enable(self, u: int, indent: str = "") -> list[str]:
        """The lines that put ``u``, just enabled, where the loop finds it: the enabled set, or
        for a local step the stack of local steps (a paced one the timers, before its tick)."""
        if not self.eager[u]:
            return [f"{indent}_add({u})"]
        if u not in self.paced:
            return [f"{indent}_local({u})"]
        return [f"{indent}if T{u}.next > _clock.ns:",
                f"{indent}    _timer(_timers, (T{u}.next, {u}))",
                f"{indent}else:",
                f"{indent}    _local({u})"]

    def fire_table(self) -> list[Action]:
        return self.fire

    def macro_table(self) -> list[Macro]:
        assert self.macros is not None
        return self.macros

    # ------------------------------------------------------------------ compiling
    def _lazy(self, table: Callable[[], list[Callable[[], R]]], t: int,
              body: Callable[[int], list[str]]) -> Callable[[], R]:
        """A stand-in that compiles the function of ``t`` when first called, puts it in its
        place in ``table()`` and runs it."""
        def first_call() -> R:
            fn: Callable[[], R] = self._compile(f"f{t}", body(t))
            table()[t] = fn
            return fn()
        return first_call

    def _compile(self, name: str, body: list[str]) -> Callable[[], Any]:
        text = "\n".join("    " + line for line in body or ["pass"])
        code = _CODE.get((name, text))
        if code is None:
            names = sorted(set(_NAMES.findall(text)))
            source = f"def {name}({', '.join(f'{n}={n}' for n in names)}):\n" + text
            if len(_CODE) >= MAX_CACHED:
                _CODE.clear()
            code = _CODE[name, text] = compile(source, f"<rssm {name}>", "exec")
        # generated from indices only: no text of the specification
        exec(code, self.ns)
        fn: Callable[[], Any] = self.ns.pop(name)
        return fn

    # ------------------------------------------------------------------ pieces of code
    def _empty_before(self, t: int) -> set[int]:
        """The places that hold no token when ``t`` is enabled: those exclusive with one of its
        input places (which all hold one)."""
        out: set[int] = set()
        for q in self.game.rule.pre[t]:
            out |= self.exclusive[q]
        return out

    def _consume(self, t: int, body: list[str], known: dict[int, int],
                 empty: Set[int], held: Collection[int] = ()) -> None:
        """Empty the input places of ``t`` (but those in ``held``, left marked). ``known``:
        the counts of missing tokens the generator knows (``t``'s own, 0 on entry), updated
        here and written at the end; ``empty``: places known to hold no token (a transition
        reading one is not enabled)."""
        rule, eager = self.game.rule, self.eager
        consumers = rule.consumers
        pre = [p for p in rule.pre[t] if p not in held]
        known[t] = 0
        for p in pre:
            body.append(f"tokens[{p}] = 0")
            for u in consumers[p]:
                if u in known:
                    if known[u] == 0 and not eager[u]:
                        body.append(f"_discard({u})")
                    known[u] += 1
                elif eager[u]:                   # local steps are not kept in the enabled set
                    body.append(_add_one(u, f"missing[{u}]"))
                elif len(rule.pre[u]) == 1:
                    body.append(f"_discard({u})")
                    body.append(f"missing[{u}] = 1")
                elif not empty.isdisjoint(rule.pre[u]):    # u is not enabled
                    body.append(_add_one(u, f"missing[{u}]"))
                else:
                    body.append(f"m = missing[{u}]")
                    body.append("if m == 0:")
                    body.append(f"    _discard({u})")
                    body.append(_add_one(u, "m"))
        if pre:
            body.append(f"missing[{t}] = {known[t]}")

    def _effect(self, t: int, body: list[str]) -> None:
        if self.effects[t] is not None:
            self.ns[f"e{t}"] = self.effects[t]
            body.append(f"e{t}()")

    def _arrive(self, src: str, p: int, body: list[str], empty: Collection[int]) -> None:
        """A token arrives in ``p``: the safeness check (not for a place in ``empty``, known
        to hold no token) and the place's operation."""
        if p not in empty:
            body.append(f"if tokens[{p}]:")
            body.append(f"    _unsafe({src}, {p})")
        if self.ops[p] is not None:
            self.ns[f"o{p}"] = self.ops[p]
            body += ["try:", f"    o{p}()", "except Exception as e:", f"    _failure({p}, e)"]

    def _mark(self, p: int, body: list[str], known: dict[int, int],
              empty: Collection[int]) -> None:
        """The token of ``p`` is put and the transitions reading ``p`` are updated (one that
        also reads a place of ``empty``, known to hold no token, is not enabled by it)."""
        pre, consumers = self.game.rule.pre, self.game.rule.consumers
        body.append(f"tokens[{p}] = 1")
        for u in consumers[p]:
            if u in known:
                known[u] -= 1
                body.append(f"missing[{u}] = {known[u]}")
                if known[u] == 0:
                    body += self._enable(u)
            elif len(pre[u]) == 1:
                body.append(f"missing[{u}] = 0")
                body += self._enable(u)
            elif any(q != p and q in empty for q in pre[u]):
                body.append(f"missing[{u}] = missing[{u}] - 1")   # not -=: see _add_one
            else:
                body.append(f"m = missing[{u}] - 1")
                body.append(f"missing[{u}] = m")
                body.append("if m == 0:")
                body += self._enable(u, "    ")

    def _case(self, p: int, group: Any, body: list[str], empty: Collection[int]) -> None:
        """The case of the partial function whose input place is ``p`` (``group``, a
        ``CaseGroup``) fires, then its operation runs."""
        self.ns[f"G{p}"] = group.table
        self.ns[f"N{p}"] = group.state.new      # its mask is state.new_mask
        self.ns[f"S{p}"] = group.select         # mask -> row (rssm_dsl/semantics/cases.py)
        # the case's transition, place, operation and `done` transition
        body.append(f"ct, cp, co, cd = G{p}[S{p}(N{p}.mask)]" if group.split
                    else f"ct, cp, co, cd = G{p}[0]")
        if not all(row[1] in empty for row in group.table):
            body += ["if tokens[cp]:", "    _unsafe(ct, cp)"]
        run = ["try:", "    co()", "except Exception as e:", "    _failure(cp, e)"]
        ops = [row[2] is not None for row in group.table]
        if all(ops):
            body += run
        elif any(ops):
            body += ["if co is not None:", *("    " + x for x in run)]

    def _firing(self, t: int) -> list[str]:
        body: list[str] = []
        known: dict[int, int] = {}
        before = self._empty_before(t)
        self._consume(t, body, known, before)
        self._effect(t, body)
        empty = before | set(self.game.rule.pre[t])
        for p in self.game.rule.post[t]:
            self._arrive(str(t), p, body, empty)
            self._mark(p, body, known, empty)
            empty.discard(p)
        return body

    def _macro(self, t: int) -> tuple[list[str], int]:
        """The macro step of ``t`` (see :meth:`_steps`).

        A place that ``t`` empties and marks again (a test arc: the fused place of a channel
        that a transition of a communication mode reads) is left marked, without the
        bookkeeping of both, when nothing between them can see the token game (the macro
        calls no effect, no operation and no unsafe report: the places are marked at its
        end) and no local step reads it: emptying it and marking it again changes no count
        and leaves every transition that reads it in or out of the enabled set as it was."""
        rule, eager = self.game.rule, self.eager
        body, count = self._steps(t, ())
        if not any(_CALLS_OUT.search(line) for line in body):
            held = [p for p in rule.pre[t] if p in rule.post[t]
                    and not any(eager[u] for u in rule.consumers[p])]
            if held:
                body, count = self._steps(t, held)
        return body, count

    def _steps(self, t: int, held: Collection[int]) -> tuple[list[str], int]:
        """The macro step of ``t``, ``held``: places of ``t`` left marked (see :meth:`_macro`).

        From the output places of ``t`` the builder follows local steps symbolically: an
        unconditional, unpaced local transition whose input places were all marked within the
        macro fires; the data-availability cases of a partial function (a ``CaseGroup`` at an
        input place) fire as one step that picks the case from the subsystem's new(x) mask
        (exactly one case matches: the cases are disjoint and exhaustive). Each transition
        fires at most once in a macro. The places left marked at the end get their tokens
        and the usual bookkeeping; the places in between are never written. Every firing,
        effect and operation happens in the order a step-by-step run with local steps first
        would make them (the chain commutes with everything outside it), so a macro step is
        only a faster way to make the same firings. The count is the same on every path."""
        rule = self.game.rule
        pre, post, consumers = rule.pre, rule.post, rule.consumers
        eager, guards, gates = self.eager, self.guards, self.gates
        body: list[str] = []
        virtual: dict[int, None] = {}      # marked within the macro, not yet consumed
        known: dict[int, int] = {}
        before = self._empty_before(t)
        # emptied by t or empty before it; the macro marks places only at its end
        empty = before | set(pre[t]).difference(held)

        def produce(src: str, p: int) -> None:
            if p in virtual:
                body.append(f"_unsafe({src}, {p})")
            self._arrive(src, p, body, empty)
            virtual[p] = None

        self._consume(t, body, known, before, held)
        self._effect(t, body)
        for p in post[t]:
            if p not in held:
                produce(str(t), p)
        count = 1
        fired = {t}
        changed = True
        while changed and count < MAX_MACRO:
            changed = False
            for p in list(virtual):
                if p not in virtual:
                    continue
                group = self.case_groups.get(p)
                if group is not None and all(eager[u] and gates[u] is None and u not in fired
                                             for u in consumers[p]):
                    fired.update(consumers[p])
                    fired.update(row[3] for row in group.table)
                    del virtual[p]
                    self._case(p, group, body, empty)
                    produce("cd", group.out_place)
                    count += 2
                    changed = True
                    continue
                for u in consumers[p]:
                    if (eager[u] and guards[u] is None and gates[u] is None and u not in fired
                            and all(q in virtual for q in pre[u])):
                        fired.add(u)
                        for q in pre[u]:
                            del virtual[q]
                        self._effect(u, body)
                        for q in post[u]:
                            produce(str(u), q)
                        count += 1
                        changed = True
                        break
        settled = empty.difference(virtual)     # still empty at the end
        for p in virtual:
            self._mark(p, body, known, settled)
        return body, count
