"""The verify command's watchdog: the limits bind in every phase, also those that never
check the budget (the compilation, the flattening, a long step in C), and the progress line
keeps coming in them.

A thread wakes every ``tick`` seconds while the command runs. It

1. looks for a limit of the run: the run's own deadline passed (not a capped first try's,
   ``Budget.capped``), the resident size above the memory limit, or a stop request (Ctrl-C);
   a limit it sees first is recorded as the run's stop (``Budget.expire``), so the next
   check of a cooperative phase raises and the phase returns with what it found;
2. reports the status (phase, states, resident size) when the phase itself has not reported
   one for a second (``Budget.report_status``): the progress line of ``--progress``;
3. ``grace`` seconds after the limit, if the command has not started to write its report
   (``finish``), sends SIGALRM to the main thread, whose handler raises ``LimitReached``
   between two bytecodes: a pure-Python loop or a sleep is interrupted, the verifier's
   handlers keep what was found, and the command prints its report the normal way (the
   exception is raised once);
4. ``hard`` seconds after that, if the command still has not finished (the exception was
   swallowed, or the main thread is inside C code that released the GIL and does not
   return), calls ``give_up`` with the stop: it prints the partial report and ends the
   process with ``os._exit``.

A call into C that holds the GIL and does not return lets neither the thread nor the
handler run: the run then ends when that call returns.
"""

from __future__ import annotations

import signal
import threading
import time
from collections.abc import Callable
from types import FrameType, TracebackType
from typing import Any

from rssm_dsl.verify.budget import INTERRUPT, MEMORY, TIME, Budget, LimitReached, Stop, format_size

TICK = 0.25         # seconds between two looks
GRACE = 2.0         # seconds after a limit for the phase to return on its own
HARD = 2.0          # seconds more before the process ends from the watchdog
STATUS_QUIET = 1.0  # report the status when the phase has not for this long
SIGNAL = signal.SIGALRM


class Watchdog:
    """A context manager around one verification (see the module docstring)."""

    def __init__(self, budget: Budget, give_up: Callable[[Stop, str], None], *,
                 tick: float = TICK, grace: float = GRACE, hard: float = HARD) -> None:
        self.budget = budget
        self.give_up = give_up          # (stop, phase interrupted): print, os._exit
        self.tick, self.grace, self.hard = tick, grace, hard
        self.deadline = None if budget.time_limit is None else budget.start + budget.time_limit
        self.seen: float | None = None  # when the watchdog first saw the run's limit
        self.interrupted: str | None = None   # the phase its exception was raised in
        self._final = False
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._main: int | None = None
        self._old_handler: Any = None
        self._thread = threading.Thread(target=self._watch, name="rssmc-verify-watchdog",
                                        daemon=True)

    def __enter__(self) -> Watchdog:
        try:
            self._old_handler = signal.signal(SIGNAL, self._raise)
            self._main = threading.get_ident()
        except ValueError:      # not the main thread: no exception raised in it, only step 4
            self._main = None
        self._thread.start()
        return self

    def __exit__(self, kind: type[BaseException] | None, value: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.finish()
        self._done.set()
        self._thread.join(timeout=5)
        if self._main is not None:
            signal.signal(SIGNAL, self._old_handler)

    def finish(self) -> None:
        """The command writes its report: from now on the watchdog neither raises, nor ends
        the process, nor reports the status (waits for a status line being written)."""
        with self._lock:
            self._final = True

    @property
    def final(self) -> bool:
        return self._final

    # ------------------------------------------------------------------ the thread
    def limit(self) -> Stop | None:
        """The run's stop if one of its limits is reached (recorded if it was not)."""
        b = self.budget
        now = time.monotonic()
        past = self.deadline is not None and now >= self.deadline
        stop = b.stop
        if stop is not None and (stop.kind != TIME or past):
            return stop                 # not the stop of a capped first try
        if b.cancelled:
            return b.expire(INTERRUPT)
        if past:
            return b.expire(TIME)
        if b.max_memory is not None:
            resident = b.resident()
            if resident > b.max_memory:
                return b.expire(MEMORY, f"{format_size(resident)} resident")
        return None

    def _watch(self) -> None:
        while not self._done.wait(self.tick):
            with self._lock:
                if self._final:
                    return
                stop = self.limit()
                self.budget.report_status(STATUS_QUIET)
                if stop is None:
                    continue
                now = time.monotonic()
                if self.seen is None:
                    self.seen = now
                late = now - self.seen
                if late >= self.grace + self.hard:
                    self.give_up(stop, self.interrupted or self.budget.phase)
                    return              # give_up ends the process; a test's may not
                if late >= self.grace and self._main is not None and self.interrupted is None:
                    signal.pthread_kill(self._main, SIGNAL)

    # ------------------------------------------------------------------ the main thread
    def _raise(self, signum: int, frame: FrameType | None) -> None:
        """Raise the run's stop in the main thread, once: a second exception could hit the
        handler of the first (step 4 ends a run that swallowed it)."""
        stop = self.budget.stop
        if self._final or stop is None or self.interrupted is not None:
            return
        self.interrupted = self.budget.phase
        raise LimitReached(stop)
