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
from dataclasses import dataclass, field
from heapq import heappop, heappush
from typing import Any

from rssm_dsl.diagnostics import Diagnostic, Related
from rssm_dsl.hpn.flat import Role
from rssm_dsl.interp.clock import SimClock
from rssm_dsl.interp.codegen import FiringCode
from rssm_dsl.interp.engine import TokenGame, UnsafeFiring
from rssm_dsl.interp.errors import EvalError, StopSimulation
from rssm_dsl.interp.program import Runtime
from rssm_dsl.interp.state import SubsystemState
from rssm_dsl.interp.summary import Snapshot, snapshot

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
    reason: str            # steps | until | finished | deadlock | error | interrupted | replayed
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

    @property
    def ok(self) -> bool:
        return self.reason in ("steps", "until", "finished", "interrupted", "replayed",
                               "stopped", "switches")


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
        (self.final,) = tuple(rt.net.final)
        self.markings: list[frozenset[int]] = []
        self.diagnostics: list[Diagnostic] = []
        self.forced_count = 0
        self._next_progress = 0.0
        self.eager = self._local_steps()
        self.local: list[int] = []       # local steps that became enabled (deterministic)
        self.fire: list[Callable[[], None]] = []
        self.macros: list[Callable[[], None]] | None = None
        self.macro_len: list[int] = []
        if options.mode == "deterministic":
            eager = self.eager if options.eager and options.forced is None else bytearray(
                len(self.eager))
            code = FiringCode(self.game, rt.ops, rt.effects, rt.guards, rt.gates, eager,
                              self.local, rt.case_groups, self._failure, self._raise_unsafe,
                              options.macros and options.eager and options.forced is None)
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
        out: list[Blocked] = []
        for p, v in enumerate(game.tokens):
            fp = net.places[p]
            if not v or fp.subsystem is None or not game.consumers[p]:
                continue
            needs: list[tuple[str, list[tuple[str, str]]]] = []
            for t in game.consumers[p]:
                missing = [net.places[q] for q in net.transitions[t].pre if not game.tokens[q]]
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
        rt.emit({"event": "start", "system": rt.system.name, "mode": self.opt.mode,
                 "seed": self.opt.seed, "places": len(rt.net.places),
                 "transitions": len(rt.net.transitions), **self.opt.trace_info})
        if self.opt.record_markings:
            self.markings.append(self.game.marking())
        steps = 0
        diag: Diagnostic | None = None
        try:
            if self.opt.mode == "deterministic":
                steps, reason, message = self._run_deterministic()
            else:
                steps, reason, message = self._run_concurrent()
        except _Stop as stop:
            steps, reason, message, diag = rt.step, stop.reason, stop.message, stop.diagnostic
        except StopSimulation as stop:
            steps, reason, message = rt.step, stop.reason, stop.message
        except KeyboardInterrupt:
            steps, reason, message = rt.step, "interrupted", "interrupted (Ctrl-C)"
        if diag is not None:
            self.diagnostics.append(diag)
        blocked = self.blocked() if reason == "deadlock" else []
        problems = rt.close_devices()
        summary = snapshot(rt, self.game, steps)
        result = RunResult(reason, message, steps, rt.time(), time.monotonic() - start,
                           self.diagnostics, self.game.marked_names(), blocked, self.markings,
                           self.forced_count, summary)
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
        rt, game, opt = self.rt, self.game, self.opt
        clock = rt.clock
        assert isinstance(clock, SimClock)
        gates, guards, fire = rt.gates, rt.guards, self.fire
        missing, enabled, tokens = game.missing, game.enabled, game.tokens
        rnd = random.Random(opt.seed).random
        final = self.final
        limit = opt.max_steps if opt.max_steps is not None else 1 << 62
        until = None if opt.until is None else round(opt.until * 1e9)
        forced = opt.forced
        local = self.local
        record = self.markings if opt.record_markings else None
        tracer = rt.tracer
        macros = self.macros if tracer is None and record is None else None
        mlen = self.macro_len
        eager = self.eager if opt.eager and forced is None else bytearray(len(self.eager))
        steps = 0
        next_look = PROGRESS_EVERY
        instant, instant_steps = clock.ns, 0     # when simulated time last moved (E808)
        timers: list[tuple[int, int]] = []      # (tick, local step waiting for it)
        local.extend(sorted((u for u in enabled if eager[u]), reverse=True))
        enabled.difference_update(local)         # local steps live on the stack and timers
        try:
            while True:
                while local:                     # local steps first (see _local_steps)
                    u = local.pop()
                    if missing[u] != 0:
                        continue
                    gate = gates[u]
                    if gate is not None and gate.next > clock.ns:
                        heappush(timers, (gate.next, u))    # taken up again at its tick
                        continue
                    guard = guards[u]
                    if guard is not None and not guard():
                        continue
                    if steps >= limit:
                        local.append(u)
                        return steps, "steps", f"stopped after {steps} firings"
                    if gate is not None:
                        gate.start(clock.ns)
                    if steps >= next_look:       # the same look as below: local steps
                        next_look = steps + PROGRESS_EVERY   # alone may spin at one instant
                        rt.step = steps
                        self._progress(steps)
                        if clock.ns != instant:
                            instant, instant_steps = clock.ns, steps
                        elif steps - instant_steps > ZENO_FIRINGS:
                            raise self._zeno(steps - instant_steps, clock.ns)
                    if macros is not None and steps + mlen[u] <= limit:
                        macros[u]()
                        steps += mlen[u]
                        if tokens[final]:
                            return steps, "finished", FINISHED
                        continue
                    steps += 1
                    if tracer is not None:
                        rt.step = steps
                        self._trace_fire(u)
                    fire[u]()
                    if record is not None:
                        record.append(game.marking())
                    if tokens[final]:
                        return steps, "finished", FINISHED
                if tokens[final]:
                    return steps, "finished", FINISHED
                if steps >= limit:
                    return steps, "steps", f"stopped after {steps} firings"
                now = clock.ns
                was_forced = False
                if forced is not None:
                    if steps >= len(forced):
                        return steps, "replayed", f"replayed {steps} firings"
                    t = forced[steps]
                    if t not in enabled:
                        raise self._diverged(steps, t)
                    gate = gates[t]
                    if gate is not None and gate.next > now:
                        clock.ns = now = gate.next
                    guard = guards[t]
                    was_forced = guard is not None and not guard()
                    if was_forced:
                        self.forced_count += 1
                else:
                    if steps >= next_look:
                        next_look = steps + PROGRESS_EVERY
                        rt.step = steps
                        self._progress(steps)
                        if now != instant:
                            instant, instant_steps = now, steps
                        elif steps - instant_steps > ZENO_FIRINGS:
                            raise self._zeno(steps - instant_steps, now)
                    active = []                  # enabled, due and condition true
                    nxt = -1                     # the next tick of a gated enabled transition
                    for u in enabled:
                        gate = gates[u]
                        if gate is not None:
                            due = gate.next
                            if due > now:
                                if nxt < 0 or due < nxt:
                                    nxt = due
                                continue
                        guard = guards[u]
                        if guard is None or guard():
                            active.append(u)
                    if not active:
                        if timers and (nxt < 0 or timers[0][0] < nxt):
                            nxt = timers[0][0]
                        if nxt < 0:
                            rt.step = steps
                            raise self._deadlock()
                        if until is not None and nxt > until:
                            clock.ns = until
                            return steps, "until", f"reached t = {opt.until:g} s"
                        clock.ns = nxt
                        while timers and timers[0][0] <= nxt:
                            local.append(heappop(timers)[1])
                        continue
                    if len(active) > 1:
                        active.sort()
                        t = active[int(rnd() * len(active))]
                    else:
                        t = active[0]
                gate = gates[t]
                if gate is not None:
                    gate.start(now)
                if macros is not None and steps + mlen[t] <= limit:
                    macros[t]()
                    steps += mlen[t]
                    continue
                steps += 1
                if tracer is not None:
                    rt.step = steps
                    self._trace_fire(t, was_forced)
                fire[t]()
                if record is not None:
                    record.append(game.marking())
        except EvalError as e:
            raise _Stop("error", e.message, e.diagnostic()) from None
        finally:
            rt.step = steps
            game.recompute_enabled()

    def _diverged(self, k: int, t: int) -> _Stop:
        net, game = self.rt.net, self.game
        ft = net.transitions[t]
        missing = [net.places[q] for q in ft.pre if not game.tokens[q]]
        what = ", ".join(f"{q.name} ({q.label})" for q in missing) or "its input places"
        diag = Diagnostic("E806", f"step {k + 1} of the replay fires {ft.name}, which is not "
                          f"enabled: {what} hold no token", ft.span,
                          "the counterexample does not belong to this specification (was it "
                          "changed since it was verified?)")
        return _Stop("error", diag.message, diag)

    # ------------------------------------------------------------------ concurrent
    def _run_concurrent(self) -> tuple[int, str, str]:
        rt, game, opt = self.rt, self.game, self.opt
        clock = rt.clock
        gates, effects, ops = rt.gates, rt.effects, rt.ops
        rnd = random.Random(opt.seed).random
        final = self.final
        until = None if opt.until is None else round(opt.until * 1e9)
        done: queue.SimpleQueue[tuple[int, BaseException | None]] = queue.SimpleQueue()
        pending = 0
        steps = 0
        record = self.markings if opt.record_markings else None

        def work(p: int, op: Callable[[], None]) -> None:
            try:
                op()
            except BaseException as e:
                done.put((p, e))
                return
            done.put((p, None))

        def finish(p: int, err: BaseException | None) -> None:
            nonlocal pending
            pending -= 1
            if err is not None:
                if not isinstance(err, Exception):
                    raise err
                self._failure(p, err)
            game.release(p)

        pool = ThreadPoolExecutor(max_workers=max(1, opt.workers),
                                  thread_name_prefix="rssm-op")
        try:
            while True:
                while True:
                    try:
                        p, err = done.get_nowait()
                    except queue.Empty:
                        break
                    finish(p, err)
                if game.tokens[final] and pending == 0:
                    return steps, "finished", FINISHED
                if opt.max_steps is not None and steps >= opt.max_steps:
                    return steps, "steps", f"stopped after {steps} firings"
                now = clock.now()
                if until is not None and now >= until:
                    return steps, "until", f"reached t = {opt.until:g} s (wall clock)"
                if steps % PROGRESS_EVERY == 0 and steps:
                    self._progress(steps)
                try:
                    active = self._active(now)
                except EvalError as e:
                    raise _Stop("error", e.message, e.diagnostic()) from None
                if active:
                    active.sort()
                    t = active[int(rnd() * len(active))] if len(active) > 1 else active[0]
                    steps += 1
                    rt.step = steps
                    gate = gates[t]
                    if gate is not None:
                        gate.start(now)
                    game.consume(t)
                    if rt.tracer is not None:
                        self._trace_fire(t)
                    effect = effects[t]
                    if effect is not None:
                        try:
                            effect()
                        except EvalError as e:
                            raise _Stop("error", e.message, e.diagnostic()) from None
                    for p in game.post[t]:
                        try:
                            game.occupy(t, p)
                        except UnsafeFiring as e:
                            raise self._unsafe(e) from None
                        op = ops[p]
                        if op is None:
                            game.release(p)
                        else:
                            pending += 1
                            pool.submit(work, p, op)
                    if record is not None:
                        record.append(game.marking())
                    continue
                nxt = self._next_tick(now)
                if nxt is None and pending == 0:
                    if game.tokens[final]:
                        continue
                    raise self._deadlock()
                timeout = None if nxt is None else max(0.0, (nxt - now) / 1e9)
                if until is not None:
                    left = max(0.0, (until - now) / 1e9)
                    timeout = left if timeout is None else min(timeout, left)
                try:
                    p, err = done.get(timeout=timeout)
                except queue.Empty:
                    continue
                finish(p, err)
        finally:
            deadline = time.monotonic() + 5.0
            while pending > 0 and time.monotonic() < deadline:
                try:
                    p, _ = done.get(timeout=max(0.0, deadline - time.monotonic()))
                except queue.Empty:
                    break
                pending -= 1
                game.release(p)
            pool.shutdown(wait=pending == 0, cancel_futures=True)
