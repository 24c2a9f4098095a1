"""Time in the interpreter: integer nanoseconds, simulated or wall-clock, and the tickers
that pace subsystems and devices that run at a frequency.

A subsystem (or device) with frequency f owns a :class:`Ticker` of period ``round(1e9 / f)``
ns. The transitions that start one of its iterations (``t_in`` and ``t_4`` of its behaviour
pages, ``t_in`` and the loop transition of a device net) are *gated*: they may fire only when
the clock has reached the ticker's next tick. Firing one starts an iteration at the current
tick and moves the next tick one period after it; an iteration that starts late (it was
blocked for a whole period or more) is an *overrun*, and the ticks it missed are skipped,
as a real-time loop does. See docs/simulate.md for the whole clock model.
"""

from __future__ import annotations

import time

NS_PER_S = 1_000_000_000


def period_ns(hertz: float) -> int:
    return max(1, round(NS_PER_S / hertz))


def seconds(ns: int) -> float:
    return ns / NS_PER_S


class Ticker:
    """The next tick of one paced subsystem or device."""

    __slots__ = ("next", "overruns", "owner", "period", "starts")

    def __init__(self, owner: str, hertz: float) -> None:
        self.owner = owner
        self.period = period_ns(hertz)
        self.next = 0          # the first iteration starts at time 0
        self.overruns = 0      # iterations that started a period or more after their tick
        self.starts = 0

    def start(self, now: int) -> None:
        """An iteration starts at ``now`` (never before ``self.next``)."""
        period = self.period
        # on its tick (the common case) the next one is a period on: what the formula below
        # gives, ticks being multiples of the period, without dividing counts of ns
        if now == self.next:
            self.next = now + period
        else:
            if now >= self.next + period:
                self.overruns += 1
            self.next = (now // period + 1) * period
        self.starts += 1


class SimClock:
    """Simulated time: advances only when the scheduler moves it to the next tick."""

    __slots__ = ("ns",)

    def __init__(self) -> None:
        self.ns = 0

    def now(self) -> int:
        return self.ns


class WallClock:
    """Wall-clock time since the run started."""

    __slots__ = ("start",)

    def __init__(self) -> None:
        self.start = time.monotonic_ns()

    def now(self) -> int:
        return time.monotonic_ns() - self.start
