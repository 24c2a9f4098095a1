"""Stalled subsystems: a subsystem that completes no iteration for a while although the run
goes on (simulated time advances because other subsystems or devices keep ticking). A global
deadlock stops the run by itself (nothing can fire, E805); a partial one does not: two
controllers that wait for each other on blocking channels freeze while their effectors and
devices run on, and without this watch the run would go on to its bound and report success.

A subsystem is *stalled* when it has completed no iteration (fired neither `t_4` nor
`t_out` of a behaviour page) for ``periods`` periods of the slowest paced subsystem or
device of the system. Completed iterations, not the discrete time stamp i: i := i + 1 runs at
p_2, before the receive, so a subsystem that waits for ever in its blocking receive has
counted an iteration it never completes. The slowest period, not the subsystem's own: a
100 Hz consumer that receives, blocking, from a 1 Hz producer waits a whole second for each
value, which is the system's rhythm and not a stall. A subsystem that has ended (switched to
`end`) is not watched. Simulated time only advances at ticks, so a system with no frequency
at all cannot stall this way (it deadlocks or stands still: E805, E808).

On the wall clock (``--mode concurrent``) time passes whether or not the process runs: on a
busy machine it may get no CPU for longer than the limit, and every subsystem would look
stalled. There a stall is judged on work done as well: the rest of the system must have
worked ``periods`` slowest periods meanwhile, i.e. some *other* paced subsystem or device
started iterations worth that time (its starts times its period; a late tick is skipped, not
counted). In simulated time the clock only advances at ticks that are taken, so the clock is
the work and this second test is not made.

The run stops with E809, which names each stalled subsystem, its behaviour, and what it
waits for (the places its next transition misses; a channel is worded by what is awaited
and the state it stands in: "waits for the consumer to take the value: channel ...: full",
"waits for fresh data: channel ...: empty", as `rssmc verify` words its "stands at" lines).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rssm_core.records import dataclass

if TYPE_CHECKING:   # the command line reads STALL_PERIODS without loading the interpreter
    from rssm_dsl.interp.clock import Ticker
    from rssm_dsl.interp.program import Runtime
    from rssm_dsl.interp.state import SubsystemState

STALL_PERIODS = 5      # default of `rssmc simulate --stall-periods`


@dataclass
class Stall:
    subsystem: SubsystemState
    since: int          # ns: when its last iteration ended (or the run started)


class Watchdog:
    """Checks every half slowest period (of simulated or wall-clock time) which subsystems
    have stopped completing iterations."""

    def __init__(self, rt: Runtime, periods: int, *, on_work: bool = False) -> None:
        self.rt = rt
        tickers = [s.ticker for s in rt.subsystems.values() if s.ticker is not None]
        tickers += [d.ticker for d in rt.devices.values() if d.ticker is not None]
        self.tickers: list[Ticker] = tickers
        self.on_work = on_work       # wall clock: the rest of the system must have worked too
        self.starts: dict[str, list[int]] = {}   # per subsystem: tickers' starts at `since`
        self.reference = max((t.period for t in tickers), default=0)   # ns
        self.periods = periods
        self.active = periods > 0 and self.reference > 0
        self.limit = periods * self.reference
        self.step = max(1, self.reference // 2)
        self.next_check = self.step
        self.seen: dict[str, tuple[int, int]] = {
            sid: (s.completed, 0) for sid, s in rt.subsystems.items()}   # (count, since when)

    def due(self, now: int) -> bool:
        return self.active and now >= self.next_check

    def stalls(self, now: int) -> list[Stall]:
        """The subsystems stalled at ``now`` (and the next check is set)."""
        self.next_check = now + self.step
        out: list[Stall] = []
        for sid, s in self.rt.subsystems.items():
            done, since = self.seen[sid]
            if s.completed != done:
                self.seen[sid] = (s.completed, now)
                if self.on_work:
                    self.starts[sid] = [t.starts for t in self.tickers]
                continue
            if not s.ended and now - since >= self.limit and self._others_worked(sid, s.ticker):
                out.append(Stall(s, since))
        return out

    def _others_worked(self, sid: str, own: Ticker | None) -> bool:
        """On the wall clock: another paced subsystem or device started iterations worth the
        limit since ``sid``'s last iteration (always true in simulated time)."""
        if not self.on_work:
            return True
        before = self.starts.get(sid)
        done = max((((t.starts - (before[k] if before else 0)) * t.period)
                    for k, t in enumerate(self.tickers) if t is not own), default=0)
        return done >= self.limit
