"""The scheduler of the paper (V-C): find the enabled transitions whose conditions hold, fire
one, run the operation of each newly marked place; a place's token is usable once its
operation has finished. Two modes:

* **deterministic** — one thread; the transition is chosen among the active ones with a
  seeded random generator; operations run when their place is marked and take no simulated
  time; simulated time moves to the next tick of a paced subsystem or device when nothing
  else can fire. The same seed gives the same run.
* **concurrent** — the scheduler runs in the calling thread, operations in a pool of worker
  threads (the paper's generated interpreter runs each operation in a thread); ticks are paced
  by the wall clock.

A run stops at ``max_steps`` firings, at time ``until``, when the system terminates (the
final place of H is marked), at a deadlock, at an operation failure that no error condition
handles, at the end of a forced (replayed) firing sequence, or on Ctrl-C; in every case the
trace is flushed and a :class:`RunResult` describes what happened.
"""

from __future__ import annotations

import queue
import random
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import field
from heapq import heappop, heappush
from typing import Any

from rssm_core.records import dataclass
from rssm_core.trace import SOURCE_INTERPRETER, start_event
from rssm_dsl.diagnostics import Diagnostic, Related
from rssm_dsl.hpn.flat import Role
from rssm_dsl.interp.clock import SimClock
from rssm_dsl.interp.codegen import FiringCode
from rssm_dsl.interp.engine import TokenGame, UnsafeFiring
from rssm_dsl.interp.errors import EvalError, StopSimulation
from rssm_dsl.interp.program import Runtime
from rssm_dsl.interp.state import SubsystemState
from rssm_dsl.interp.summary import Snapshot, snapshot
from rssm_dsl.interp.watchdog import STALL_PERIODS, Stall, Watchdog

PROGRESS_EVERY = 1024          # firings between two looks at the wall clock
ZENO_FIRINGS = 2_000_000       # firings at one simulated instant before giving up (E808)
FINISHED = "the system finished (every agent terminated)"


@dataclass
class SimOptions:
    mode: str = "deterministic"                 # or "concurrent"
    seed: int = 0
    max_steps: int | None = None
    until: float | None = None                  # seconds (simulated, or wall in concurrent)
    workers: int = 4
    forced: list[int] | None = None             # replay: fire exactly these transitions
    record_markings: bool = False               # keep every marking reached (tests)
    eager: bool = True                          # fire local steps at once (see Simulator)
    macros: bool = True                         # ... compiled into macro steps (codegen)
    progress: Callable[[Snapshot], None] | None = None
    progress_interval: float = 0.5              # seconds of wall-clock time
    stall_periods: int = STALL_PERIODS          # see watchdog.py (0: not watched)
    observe: Callable[[int], None] | None = None  # deterministic: called after each firing
    trace_info: dict[str, Any] = field(default_factory=dict)  # more fields of `start`


@dataclass
class Blocked:
    """Why a deadlocked subsystem cannot go on: a token waits in ``place`` and the
    transitions that would take it miss the listed places."""

    owner: str
    place: str
    label: str
    needs: list[tuple[str, list[tuple[str, str]]]]   # (transition, [(place, label)])


@dataclass
class RunResult:
    reason: str            # steps | until | finished | deadlock | stalled | error | interrupted
                           # | replayed
                           # (or what a StopSimulation raised by a device says)
    message: str
    steps: int
    time: float            # seconds, simulated or wall-clock
    wall: float            # seconds of wall-clock time the run took
    diagnostics: list[Diagnostic] = field(default_factory=list)
    marking: list[str] = field(default_factory=list)        # place names at the end
    blocked: list[Blocked] = field(default_factory=list)    # at a deadlock
    markings: list[frozenset[int]] = field(default_factory=list)
    forced: int = 0        # replayed firings whose condition did not hold in the data
    summary: Snapshot | None = None
    stopped_cleanly: bool = False   # a StopSimulation without failed=True ended the run
    forced_at: list[tuple[int, int]] = field(default_factory=list)  # (step, transition)

    @property
    def ok(self) -> bool:
        return self.stopped_cleanly or self.reason in ("steps", "until", "finished",
                                                       "interrupted", "replayed")


class _Stop(Exception):
    def __init__(self, reason: str, message: str, diagnostic: Diagnostic | None = None) -> None:
        super().__init__(message)
        self.reason = reason
        self.message = message
        self.diagnostic = diagnostic


class Simulator:
    def __init__(self, rt: Runtime, options: SimOptions) -> None:
        if options.mode not in ("deterministic", "concurrent"):
            raise ValueError(f"unknown mode {options.mode!r}")
        if options.mode == "deterministic" and not isinstance(rt.clock, SimClock):
            raise ValueError("the deterministic mode needs a runtime built with simulated time")
        self.rt = rt
        self.opt = options
        self.game = TokenGame(rt.net)
        self.watchdog = Watchdog(rt, options.stall_periods if options.forced is None else 0,
                                 on_work=not isinstance(rt.clock, SimClock))
        self.stalled: set[str] = set()           # the subsystems of an E809
        (self.final,) = tuple(rt.net.final)
        self.markings: list[frozenset[int]] = []
        self.diagnostics: list[Diagnostic] = []
        self.forced_count = 0
        self.forced_at: list[tuple[int, int]] = []   # (step, transition) of those forced
        self._next_progress = 0.0
        self.eager = self._local_steps()
        self.local: list[int] = []       # local steps that became enabled (deterministic)
        self.timers: list[tuple[int, int]] = []   # (tick, local step waiting for it): a heap
        self.fire: list[Callable[[], None]] = []
        self.macros: list[Callable[[], int]] | None = None   # each returns its firings
        self.macro_len: list[int] = []
        if options.mode == "deterministic":
            assert isinstance(rt.clock, SimClock)       # see above
            eager = self.eager if options.eager and options.forced is None else bytearray(
                len(self.eager))
            code = FiringCode(self.game, rt.ops, rt.effects, rt.guards, rt.gates, eager,
                              self.local, rt.case_groups, self._failure, self._raise_unsafe,
                              options.macros and options.eager and options.forced is None,
                              self.timers, rt.clock)
            self.fire, self.macros, self.macro_len = code.fire, code.macros, code.macro_len

    def _local_steps(self) -> bytearray:
        """Transitions the deterministic mode fires as soon as they are enabled.

        A transition is *local* when it is not a behaviour switch, and neither it nor any
        transition sharing an input place with it reads a channel's fused place: then only
        transitions of its own subsystem compete for its input places, its condition reads
        only its own subsystem's state, and no other firing can disable it. Firing it at once
        (a paced one: at once when its tick has come) commutes with every other enabled
        transition (a persistent set of one), so every run is still a firing sequence of the
        net and no deadlock is hidden; the seeded choice is made among the remaining
        transitions. With ``SimOptions(eager=False)`` every enabled transition takes part in
        the choice.
        """
        rt, game = self.rt, self.game
        fused = {p.index for p in rt.net.places if p.name in rt.hpn.fusions}

        def own(t: int) -> bool:
            ft = rt.net.transitions[t]
            return ft.role is not Role.SWITCH and not any(p in fused for p in ft.pre)

        flags = bytearray(len(rt.net.transitions))
        for t in range(len(flags)):
            if own(t) and all(own(u) for p in game.pre[t] for u in game.consumers[p]):
                flags[t] = 1
        return flags

    # ------------------------------------------------------------------ common pieces
    def _failure(self, p: int, e: BaseException) -> None:
        """An operation of place ``p`` failed: take the error path, or stop the run."""
        rt = self.rt
        fp = rt.net.places[p]
        if isinstance(e, EvalError):
            err = e
        else:
            err = EvalError("E802", f"{fp.label}: {type(e).__name__}: {e}", fp.span,
                            related=(Related(fp.span, f"operation of {fp.name}"),))
        owner = rt.op_owner[p]
        handled = isinstance(owner, SubsystemState) and owner.can_handle()
        rt.emit({"event": "error", "code": err.code, "message": err.message,
                 "span": str(err.span), "subsystem": owner.id if owner else None,
                 "place": fp.name, "handled": handled})
        if handled:
            assert isinstance(owner, SubsystemState)
            owner.fail(err)
            return
        who = f" in {owner.id}" if owner is not None else ""
        if isinstance(owner, SubsystemState) and owner.behaviour is not None:
            hint = (f"behaviour {owner.behaviour} of {owner.id} has no error condition to "
                    "take; declare `error NAME when ...` and a switch on it to recover")
        else:
            hint = None
        related = err.related
        if fp.span != err.span:
            related = (*related, Related(fp.span, f"while running {fp.name}{who}"))
        hints = "; ".join(h for h in (err.hint, hint) if h)
        diag = Diagnostic(err.code, err.message, err.span, hints or None, related)
        raise _Stop("error", f"operation failed{who}: {err.message}", diag)

    def _raise_unsafe(self, t: int, p: int) -> None:
        raise self._unsafe(UnsafeFiring(t, p))

    def _unsafe(self, e: UnsafeFiring) -> _Stop:
        net = self.rt.net
        t, p = net.transitions[e.transition], net.places[e.place]
        diag = Diagnostic("E807", f"firing {t.name} would put a second token into {p.name} "
                          f"({p.label})", t.span, "the net is not safe; run `rssmc verify`")
        return _Stop("error", diag.message, diag)

    def deadlock_diagnostic(self) -> Diagnostic:
        stop = self._deadlock()
        assert stop.diagnostic is not None
        return stop.diagnostic

    def _zeno(self, firings: int, now_ns: int) -> _Stop:
        rt = self.rt
        free = [s.id for s in rt.system.subsystems() if s.frequency is None]
        msg = (f"simulated time stands still: {firings:,} firings at t = {now_ns / 1e9:g} s"
               + (f"; subsystems without a frequency: {', '.join(free)}" if free else ""))
        diag = Diagnostic("E808", msg, rt.system.span,
                          "give a free-running subsystem a frequency (`@ 100 Hz`) or a "
                          "blocking receive, so that it waits for its peers")
        return _Stop("error", msg, diag)

    def _stalled(self, stalls: list[Stall], now: int) -> _Stop:
        """The run stops: these subsystems complete no iteration while the rest goes on."""
        rt, net = self.rt, self.rt.net
        blocked = self.blocked()
        parts: list[str] = []
        related: list[Related] = []
        span = None
        waiting: dict[str, str] = {}
        for st in stalls:
            s = st.subsystem
            mine = [b for b in blocked if b.owner == s.id and any(m for _, m in b.needs)]
            what = mine[0].label if mine else f"{s.id} ({s.behaviour})"
            needs = [q for b in mine for _, m in b.needs for q in m]
            since = f"since t = {st.since / 1e9:g} s" if st.since else "since the start"
            parts.append(f"{what}, no iteration {since}"
                         + (f" ({awaited(needs[0][1])})" if needs else ""))
            waiting[s.id] = mine[0].place if mine else ""
            where = net.place(mine[0].place).span if mine else s.model.span
            if span is None:
                span = where
            else:
                related.append(Related(where, what))
            for name, label in needs[:3]:
                related.append(Related(net.place(name).span, f"{s.id} {awaited(label)}"))
        assert span is not None
        periods = self.watchdog.periods
        msg = (f"{len(stalls)} subsystem(s) stalled at t = {now / 1e9:g} s while the rest of "
               f"the system runs on: " + "; ".join(parts))
        rt.emit({"event": "stalled", "waiting": waiting})
        diag = Diagnostic("E809", msg, span,
                          f"a subsystem is stalled after {periods} periods of the slowest "
                          "paced subsystem or device without an iteration; `rssmc verify` "
                          "shows the firing sequence that loses progress; change a "
                          "communication mode or the order of sends and receives, or pass "
                          "--stall-periods (0: never stop)", tuple(related))
        self.stalled = {st.subsystem.id for st in stalls}
        names = ", ".join(st.subsystem.id for st in stalls)
        return _Stop("stalled", f"stalled at t = {now / 1e9:g} s: {names} complete(s) no "
                     "iteration while the rest runs on (E809)", diag)

    def _deadlock(self) -> _Stop:
        rt, game = self.rt, self.game
        game.recompute_enabled()
        enabled = sorted(game.enabled)
        names = game.marked_names()
        if enabled:
            listed = ", ".join(rt.net.transitions[t].name for t in enabled[:6])
            msg = (f"no condition holds among the enabled transitions ({listed}) and nothing "
                   "else can change the data")
        else:
            msg = "deadlock: no transition is enabled and the system has not finished"
        blocked = self.blocked()
        where = "; ".join(f"{b.owner} waits in {b.place}" for b in blocked[:4])
        net = rt.net
        span = net.places[next(iter(net.initial))].span
        related: tuple[Related, ...] = ()
        if blocked:
            first = net.place(blocked[0].place)
            span = first.span
            related = tuple(Related(net.place(b.place).span, f"{b.owner}: {b.label}")
                            for b in blocked[1:6])
        rt.emit({"event": "deadlock", "marking": names,
                 "waiting": {b.owner: b.place for b in blocked}})
        diag = Diagnostic("E805", f"{msg}" + (f" ({where})" if where else ""), span,
                          "run `rssmc verify` for the shortest firing sequence to it", related)
        return _Stop("deadlock", msg, diag)

    def blocked(self) -> list[Blocked]:
        """For each marked place owned by a subsystem or device, what its consumers miss."""
        net, game = self.rt.net, self.game
        rule, marking = game.rule, game.marking()
        out: list[Blocked] = []
        for p in sorted(marking):
            fp = net.places[p]
            if fp.subsystem is None or not rule.consumers[p]:
                continue
            needs: list[tuple[str, list[tuple[str, str]]]] = []
            for t in rule.consumers[p]:
                missing = [net.places[q] for q in rule.missing(marking, t)]
                needs.append((net.transitions[t].name, [(q.name, q.label) for q in missing]))
            out.append(Blocked(fp.subsystem, fp.name, fp.label, needs))
        return out

    def _progress(self, steps: int) -> None:
        cb = self.opt.progress
        if cb is None:
            return
        now = time.monotonic()
        if now >= self._next_progress:
            self._next_progress = now + self.opt.progress_interval
            cb(snapshot(self.rt, self.game, steps))

    def _trace_fire(self, t: int, forced: bool = False) -> None:
        rt = self.rt
        ft = rt.net.transitions[t]
        event: dict[str, Any] = {"event": "fire", "transition": ft.name, "role": ft.role.value,
                                 "label": ft.label, "span": str(ft.span)}
        if ft.subsystem is not None:
            event["subsystem"] = ft.subsystem
        if forced:
            event["forced"] = True
        rt.emit(event)

    # ------------------------------------------------------------------ entry
    def run(self) -> RunResult:
        start = time.monotonic()
        self._next_progress = start + self.opt.progress_interval
        rt = self.rt
        rt.emit(start_event(SOURCE_INTERPRETER, system=rt.system.name, mode=self.opt.mode,
                            seed=self.opt.seed, places=len(rt.net.places),
                            transitions=len(rt.net.transitions), **self.opt.trace_info))
        if self.opt.record_markings:
            self.markings.append(self.game.marking())
        steps = 0
        diag: Diagnostic | None = None
        clean = False
        try:
            if self.opt.mode == "deterministic":
                steps, reason, message = self._run_deterministic()
            else:
                steps, reason, message = self._run_concurrent()
        except _Stop as stop:
            steps, reason, message, diag = rt.step, stop.reason, stop.message, stop.diagnostic
        except StopSimulation as stop:
            steps, reason, message, clean = rt.step, stop.reason, stop.message, not stop.failed
        except KeyboardInterrupt:
            steps, reason, message = rt.step, "interrupted", "interrupted (Ctrl-C)"
        if diag is not None:
            self.diagnostics.append(diag)
        blocked = self.blocked() if reason == "deadlock" else \
            [b for b in self.blocked() if b.owner in self.stalled] if reason == "stalled" else []
        problems = rt.close_devices()
        summary = snapshot(rt, self.game, steps)
        result = RunResult(reason, message, steps, rt.time(), time.monotonic() - start,
                           self.diagnostics, self.game.marked_names(), blocked, self.markings,
                           self.forced_count, summary, clean, list(self.forced_at))
        rt.emit({"event": "end", "reason": reason, "message": message,
                 "problems": problems, "summary": summary.to_json()})
        if rt.tracer is not None:
            rt.tracer.flush()
        return result

    # ------------------------------------------------------------------ deterministic
    def _active(self, now: int) -> list[int]:
        rt = self.rt
        gates, guards = rt.gates, rt.guards
        active: list[int] = []
        for t in self.game.enabled:
            gate = gates[t]
            if gate is not None and gate.next > now:
                continue
            guard = guards[t]
            if guard is not None and not guard():
                continue
            active.append(t)
        return active

    def _next_tick(self, now: int) -> int | None:
        gates = self.rt.gates
        nxt: int | None = None
        for t in self.game.enabled:
            gate = gates[t]
            if gate is not None and gate.next > now and (nxt is None or gate.next < nxt):
                nxt = gate.next
        return nxt

    def _run_deterministic(self) -> tuple[int, str, str]:
        loop = _Deterministic(self)
        try:
            return loop.run()
        except _Finish as f:
            return f.steps, f.reason, f.message
        except EvalError as e:
            raise _Stop("error", e.message, e.diagnostic()) from None
        finally:
            self.rt.step = loop.steps
            self.game.recompute_enabled()

    def _diverged(self, k: int, t: int) -> _Stop:
        net, game = self.rt.net, self.game
        ft = net.transitions[t]
        missing = [net.places[q] for q in game.rule.missing(game.marking(), t)]
        what = ", ".join(f"{q.name} ({q.label})" for q in missing) or "its input places"
        diag = Diagnostic("E806", f"step {k + 1} of the replay fires {ft.name}, which is not "
                          f"enabled: {what} hold no token", ft.span,
                          "the counterexample does not belong to this specification (was it "
                          "changed since it was verified?)")
        return _Stop("error", diag.message, diag)

    # ------------------------------------------------------------------ concurrent
    def _run_concurrent(self) -> tuple[int, str, str]:
        loop = _Concurrent(self)
        try:
            return loop.run()
        finally:
            loop.shutdown()


def awaited(label: str) -> str:
    """What a stalled subsystem waits for, given the label of the place its next transition
    misses. A channel's two fused places are complements: missing `empty` means the channel
    is full and the producer waits for the consumer to take the value; missing `full` means
    it is empty and the consumer waits for fresh data. The channel is named with the state it
    stands in, as `rssmc verify` words its "stands at" lines."""
    if label.startswith("channel ") and label.endswith(": empty"):
        return ("waits for the consumer to take the value: "
                f"{label.removesuffix(': empty')}: full")
    if label.startswith("channel ") and label.endswith(": full"):
        return f"waits for fresh data: {label.removesuffix(': full')}: empty"
    return f"waits for: {label}"


class _Finish(Exception):
    """The deterministic loop ends normally (limit, termination, time, end of a replay)."""

    def __init__(self, steps: int, reason: str, message: str) -> None:
        super().__init__(message)
        self.steps, self.reason, self.message = steps, reason, message


class _Replaying:
    """The deterministic loop's set of conditional transitions when replaying: every turn takes
    the way that fires the next transition of the forced sequence."""

    __slots__ = ()

    @staticmethod
    def isdisjoint(enabled: object) -> bool:
        return False


class _Deterministic:
    """The deterministic mode's loop (see the module docstring): local steps first, then the
    seeded choice among the active transitions, simulated time moved to the next tick when
    nothing can fire. The state of the run lives in the attributes; the hot loop,
    :meth:`loop`, works on local variables only."""

    __slots__ = ("clock", "conditional", "enabled", "final", "fire", "forced", "game", "gates",
                 "guards", "instant", "instant_steps", "limit", "local", "macros", "missing",
                 "mlen", "next_look", "observe", "record", "rnd", "rt", "sim", "steps", "timers",
                 "tokens", "tracer", "until", "was_forced")

    def __init__(self, sim: Simulator) -> None:
        rt, game, opt = sim.rt, sim.game, sim.opt
        clock = rt.clock
        assert isinstance(clock, SimClock)
        self.sim, self.rt, self.game, self.clock = sim, rt, game, clock
        self.gates, self.guards, self.fire = rt.gates, rt.guards, sim.fire
        # the transitions with a tick to wait for or a condition: while none is enabled, every
        # enabled transition is active (the common case the hot loop takes without a scan).
        # When replaying, no turn takes that way (each fires the next forced transition).
        self.conditional: frozenset[int] | _Replaying = _Replaying() if opt.forced is not None \
            else frozenset(t for t, (gate, guard) in enumerate(zip(rt.gates, rt.guards,
                                                                    strict=True))
                           if gate is not None or guard is not None)
        self.missing, self.enabled, self.tokens = game.missing, game.enabled, game.tokens
        self.rnd = random.Random(opt.seed).random
        self.final = sim.final
        self.limit = opt.max_steps if opt.max_steps is not None else 1 << 62
        self.until = None if opt.until is None else round(opt.until * 1e9)
        self.forced = opt.forced
        self.local = sim.local
        self.record = sim.markings if opt.record_markings else None
        self.tracer = rt.tracer
        self.observe = opt.observe
        self.macros = sim.macros if self.tracer is None and self.record is None \
            and self.observe is None else None
        self.mlen = sim.macro_len
        self.steps = 0                   # firings so far, stored when the loop ends or raises
        self.next_look = PROGRESS_EVERY                  # the next look at progress and time
        self.instant, self.instant_steps = clock.ns, 0   # when simulated time last moved (E808)
        self.timers = sim.timers         # (tick, local step waiting for it): a heap
        self.was_forced = False
        eager = sim.eager if opt.eager and self.forced is None else bytearray(len(sim.eager))
        self.local.extend(sorted((u for u in self.enabled if eager[u]), reverse=True))
        self.enabled.difference_update(self.local)   # local steps live on the stack and timers

    def run(self) -> tuple[int, str, str]:
        """Fire until something ends the run (or raise :class:`_Finish` or :class:`_Stop`);
        see :meth:`loop`."""
        if self.tokens[self.final] or self.limit <= 0:
            return self.ended(0)
        return self.loop()

    def loop(self) -> tuple[int, str, str]:
        """The turns of :meth:`run` (the system has not finished, the limit is not reached).
        Each turn fires one transition: the local step on top of the stack (see
        ``Simulator._local_steps``; one whose tick has not come waits in ``timers``, one that
        is no longer enabled or whose condition does not hold is dropped), else one chosen
        with the seeded generator among the enabled transitions that are due and whose
        condition holds (when replaying: the next one of the sequence)."""
        local, tokens, final, limit = self.local, self.tokens, self.final, self.limit
        macros, mlen, enabled, gates, guards = (self.macros, self.mlen, self.enabled,
                                                self.gates, self.guards)
        clock, rnd, missing, timers = self.clock, self.rnd, self.missing, self.timers
        conditional = self.conditional
        steps = 0
        # Below `fast` no look at progress is due and every macro step fits under the limit
        # with room to spare: a turn fires its macro step (the limit cannot be reached). At or
        # above it, the turn checks as it always does (see `checked`). Without macro steps
        # every turn takes the checked way.
        table = macros if macros is not None else []
        spare = limit - max(mlen, default=1)
        fast = self.fast_bound(spare)
        try:
            while True:                          # the loop is hot: locals only
                if local:
                    t = local.pop()
                    if missing[t]:
                        continue
                    gate = gates[t]
                    if gate is not None and gate.next > clock.ns:
                        heappush(timers, (gate.next, t))    # taken up again at its tick
                        continue
                    guard = guards[t]
                    if guard is not None and not guard():
                        continue
                    if gate is not None:
                        gate.start(clock.ns)
                elif conditional.isdisjoint(enabled):   # every enabled one is active
                    n = len(enabled)
                    if n == 1:
                        (t,) = enabled
                    elif n == 2:                 # sorted(enabled)[int(rnd() * 2)]:
                        a, b = enabled           # r * 2 < 1 exactly when r < 0.5
                        t = (a if a < b else b) if rnd() < 0.5 else (b if a < b else a)
                    elif n:
                        t = sorted(enabled)[int(rnd() * n)]
                    else:
                        self.advance(clock.ns, steps)   # to the next tick
                        continue
                else:
                    t = self.scan(steps)         # its tick has started
                    if t < 0:                    # time moved to the next tick
                        continue
                if steps < fast:
                    steps += table[t]()          # its macro step's firings, mlen[t]
                else:
                    k = self.checked(t, steps)
                    fast = self.fast_bound(spare)
                    if k:
                        table[t]()
                        steps += k
                    else:
                        steps += 1
                        self.fire_one(t, self.was_forced, steps)
                if tokens[final] or steps >= limit:
                    return self.ended(steps)
        finally:
            self.steps = steps

    def scan(self, steps: int) -> int:
        """The seeded choice among the enabled transitions that are due and whose condition
        holds (its tick starts); -1 when there is none: time moved to the next tick. When
        replaying: the next transition of the forced sequence."""
        if self.forced is not None:
            return self.choose_forced(steps)
        gates, guards = self.gates, self.guards
        now = self.clock.ns
        active = []                              # enabled, due and condition true
        for u in self.enabled:
            gate = gates[u]
            if gate is not None and gate.next > now:
                continue
            guard = guards[u]
            if guard is None or guard():
                active.append(u)
        if not active:
            self.advance(now, steps)             # to the next tick
            return -1
        active.sort()
        t = active[int(self.rnd() * len(active))] if len(active) > 1 else active[0]
        gate = gates[t]
        if gate is not None:
            gate.start(self.clock.ns)
        return t

    def fast_bound(self, spare: int) -> int:
        """The number of firings below which a turn takes the fast way (see :meth:`loop`):
        the next look at progress, or ``spare`` (the limit less the longest macro step)."""
        return min(self.next_look, spare) if self.macros is not None else -1

    def checked(self, t: int, steps: int) -> int:
        """A turn at or above the fast bound, before ``t`` fires: look at progress when it is
        due (local steps alone may spin at one instant), and say how ``t`` fires: the number
        of firings of its macro step when there are macro steps and it fits under the limit,
        else 0 (``t`` alone)."""
        if steps >= self.next_look:
            self.look(steps)
        k = self.mlen[t]
        return k if self.macros is not None and steps + k <= self.limit else 0

    def ended(self, steps: int) -> tuple[int, str, str]:
        """The run ends: the system finished, or the limit of firings is reached."""
        if self.tokens[self.final]:
            return steps, "finished", FINISHED
        return steps, "steps", f"stopped after {steps} firings"

    def look(self, steps: int) -> None:
        """Every PROGRESS_EVERY firings: report progress; stop if time stands still (E808)."""
        self.next_look = steps + PROGRESS_EVERY
        self.rt.step = steps
        self.sim._progress(steps)
        now = self.clock.ns
        if now != self.instant:
            self.instant, self.instant_steps = now, steps
        elif steps - self.instant_steps > ZENO_FIRINGS:
            raise self.sim._zeno(steps - self.instant_steps, now)

    def advance(self, now: int, steps: int) -> None:
        """Nothing can fire at ``now``: move simulated time to the next tick of an enabled
        transition or of a waiting local step, or end the run (deadlock, ``until``)."""
        timers = self.timers
        nxt = self.sim._next_tick(now) if self.enabled else None
        if timers and (nxt is None or timers[0][0] < nxt):
            nxt = timers[0][0]
        if nxt is None:
            self.rt.step = steps
            raise self.sim._deadlock()
        if self.until is not None and nxt > self.until:
            self.clock.ns = self.until
            raise _Finish(steps, "until", f"reached t = {self.sim.opt.until:g} s")
        self.clock.ns = nxt
        watchdog = self.sim.watchdog
        if watchdog.active and nxt >= watchdog.next_check:
            stalls = watchdog.stalls(nxt)
            if stalls:
                self.rt.step = steps
                raise self.sim._stalled(stalls, nxt)
        push = self.local.append
        while timers and timers[0][0] <= nxt:
            push(heappop(timers)[1])

    def choose_forced(self, steps: int) -> int:
        """Replay: the next transition of the forced sequence, whatever its condition says
        (``was_forced`` when it does not hold); simulated time moves to its tick."""
        forced = self.forced
        assert forced is not None
        if steps >= len(forced):
            raise _Finish(steps, "replayed", f"replayed {steps} firings")
        t = forced[steps]
        if t not in self.enabled:
            raise self.sim._diverged(steps, t)
        now = self.clock.ns
        gate = self.gates[t]
        if gate is not None and gate.next > now:
            self.clock.ns = gate.next
        guard = self.guards[t]
        self.was_forced = guard is not None and not guard()
        if self.was_forced:
            self.sim.forced_count += 1
            self.sim.forced_at.append((steps, t))
        if gate is not None:
            gate.start(self.clock.ns)
        return t

    def fire_one(self, t: int, forced: bool, steps: int) -> None:
        """Fire ``t`` alone, as firing ``steps``: traced and recorded if asked."""
        if self.tracer is not None:
            self.rt.step = steps
            self.sim._trace_fire(t, forced)
        self.fire[t]()
        if self.record is not None:
            self.record.append(self.game.marking())
        if self.observe is not None:
            self.observe(t)


class _Concurrent:
    """The concurrent mode's loop: the scheduler here, operations in a pool of worker threads;
    a place's token becomes usable when its operation reports back on ``done``."""

    def __init__(self, sim: Simulator) -> None:
        self.sim, self.rt, self.game, self.opt = sim, sim.rt, sim.game, sim.opt
        self.rnd = random.Random(self.opt.seed).random
        self.until = None if self.opt.until is None else round(self.opt.until * 1e9)
        self.done: queue.SimpleQueue[tuple[int, BaseException | None]] = queue.SimpleQueue()
        self.pending = 0
        self.steps = 0
        self.record = sim.markings if self.opt.record_markings else None
        self.pool = ThreadPoolExecutor(max_workers=max(1, self.opt.workers),
                                       thread_name_prefix="rssm-op")

    def work(self, p: int, op: Callable[[], None]) -> None:
        """In a worker thread: run the operation of place ``p``, report to the scheduler."""
        try:
            op()
        except BaseException as e:
            self.done.put((p, e))
            return
        self.done.put((p, None))

    def finish(self, p: int, err: BaseException | None) -> None:
        self.pending -= 1
        if err is not None:
            if not isinstance(err, Exception):
                raise err
            self.sim._failure(p, err)
        self.game.release(p)

    def collect(self) -> None:
        """Take in every operation that has finished."""
        while True:
            try:
                p, err = self.done.get_nowait()
            except queue.Empty:
                return
            self.finish(p, err)

    def run(self) -> tuple[int, str, str]:
        sim, game, opt = self.sim, self.game, self.opt
        clock, final, until = self.rt.clock, sim.final, self.until
        while True:
            self.collect()
            if game.tokens[final] and self.pending == 0:
                return self.steps, "finished", FINISHED
            if opt.max_steps is not None and self.steps >= opt.max_steps:
                return self.steps, "steps", f"stopped after {self.steps} firings"
            now = clock.now()
            if until is not None and now >= until:
                return self.steps, "until", f"reached t = {opt.until:g} s (wall clock)"
            if sim.watchdog.due(now):
                stalls = sim.watchdog.stalls(now)
                if stalls:
                    raise sim._stalled(stalls, now)
            if self.steps % PROGRESS_EVERY == 0 and self.steps:
                sim._progress(self.steps)
            try:
                active = sim._active(now)
            except EvalError as e:
                raise _Stop("error", e.message, e.diagnostic()) from None
            if active:
                self.fire(active, now)
            else:
                self.wait(now)

    def fire(self, active: list[int], now: int) -> None:
        """Fire one of ``active``; the operations of its output places go to the pool."""
        rt, game, sim = self.rt, self.game, self.sim
        active.sort()
        t = active[int(self.rnd() * len(active))] if len(active) > 1 else active[0]
        self.steps += 1
        rt.step = self.steps
        gate = rt.gates[t]
        if gate is not None:
            gate.start(now)
        game.consume(t)
        if rt.tracer is not None:
            sim._trace_fire(t)
        effect = rt.effects[t]
        if effect is not None:
            try:
                effect()
            except EvalError as e:
                raise _Stop("error", e.message, e.diagnostic()) from None
        for p in game.post[t]:
            try:
                game.occupy(t, p)
            except UnsafeFiring as e:
                raise sim._unsafe(e) from None
            op = rt.ops[p]
            if op is None:
                game.release(p)
            else:
                self.pending += 1
                self.pool.submit(self.work, p, op)
        if self.record is not None:
            self.record.append(game.marking())

    def wait(self, now: int) -> None:
        """Nothing is active: wait for an operation to finish or the next tick (a deadlock if
        neither can come)."""
        nxt = self.sim._next_tick(now)
        if nxt is None and self.pending == 0:
            if self.game.tokens[self.sim.final]:
                return
            raise self.sim._deadlock()
        timeout = None if nxt is None else max(0.0, (nxt - now) / 1e9)
        if self.until is not None:
            left = max(0.0, (self.until - now) / 1e9)
            timeout = left if timeout is None else min(timeout, left)
        try:
            p, err = self.done.get(timeout=timeout)
        except queue.Empty:
            return
        self.finish(p, err)

    def shutdown(self) -> None:
        """Let the running operations finish (5 s at most), then stop the pool."""
        deadline = time.monotonic() + 5.0
        while self.pending > 0 and time.monotonic() < deadline:
            try:
                p, _ = self.done.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            self.pending -= 1
            self.game.release(p)
        self.pool.shutdown(wait=self.pending == 0, cancel_futures=True)
