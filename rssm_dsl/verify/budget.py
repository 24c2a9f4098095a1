"""The limits of one verification run in one object: a deadline, a memory limit and a stop
request (Ctrl-C), checked by every long loop of the verifier.

``Budget.check`` is cheap (a clock read; the resident size from ``/proc/self/statm`` at most
every few milliseconds). The loops call it every few thousand states, or after every block of
a vectorised step, so a run ends within a second or two of its deadline. ``extra`` names
memory about to be allocated, so one large allocation is refused before it is made.

The first limit reached is *sticky*. It is recorded as ``budget.stop`` (which limit, in which
phase, when), and every later check raises again. So every phase after it ends at once, and
the report says what was decided before it. ``check`` raises ``LimitReached``; a phase
catches it, keeps what it found (a deadlock found before the deadline is real), drops the
rest and returns. ``fits(extra)`` only asks whether an allocation would fit under the memory
limit, without stopping anything: a phase that the run can do without (the place
invariants) gives up on its own.

``run_limited`` runs an external tool (SPIN, 4ti2) under the same budget: the child is
killed at the deadline or on a stop request, and its resident size counts towards the
memory limit.

The phases that do not check (the compilation, the flattening, ...) are the verify command's
watchdog's (``watchdog.py``): it records the limit it sees (``expire``), reports the status
for them (``report_status``) and interrupts them; ``completed`` lists the phases that
returned, for the partial report (``partial.py``).
"""

from __future__ import annotations

import contextlib
import math
import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from rssm_core.records import dataclass

GB = 1 << 30
MB = 1 << 20
MAX_SIZE = 1 << 60              # bytes: the largest --max-memory (1048576T)
DEFAULT_MEMORY_FRACTION = 0.6       # of the machine's physical memory (or the cgroup's limit)
_MEASURE_EVERY = 0.005              # seconds between two reads of the resident size
_PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096

TIME, MEMORY, INTERRUPT = "time", "memory", "interrupt"


@dataclass(frozen=True)
class Stop:
    """Why a run stopped early: ``kind`` is ``time``, ``memory`` or ``interrupt``."""

    kind: str
    phase: str                     # "the full exploration", ...
    limit: float | None            # seconds (time), bytes (memory), None (interrupt)
    at: float                      # seconds since the start of the run
    resident: int                  # bytes resident (with what was about to be allocated)
    detail: str = ""               # e.g. "an allocation failed"

    @property
    def message(self) -> str:
        if self.kind == INTERRUPT:
            what = "interrupted (Ctrl-C)"
        elif self.kind == TIME:
            what = f"time limit of {format_seconds(self.limit or 0.0)} reached"
        elif self.limit is None:
            what = "out of memory"
        else:
            what = f"memory limit of {format_size(int(self.limit))} reached"
        return f"{what} in {self.phase}" + (f": {self.detail}" if self.detail else "")

    @property
    def short(self) -> str:
        """``message`` without the figures: "time limit reached in the full exploration"."""
        what = ("interrupted (Ctrl-C)" if self.kind == INTERRUPT else "out of memory"
                if self.limit is None else f"{self.kind} limit reached")
        return f"{what} in {self.phase}"

    def to_json(self) -> dict[str, Any]:
        return {"kind": self.kind, "phase": self.phase, "limit": self.limit,
                "after_seconds": round(self.at, 3), "resident_bytes": self.resident,
                "message": self.message}


class LimitReached(Exception):
    """A limit of the budget was reached (or had been reached before)."""

    def __init__(self, stop: Stop) -> None:
        super().__init__(stop.message)
        self.stop = stop


@dataclass(frozen=True)
class Status:
    """What a long run reports while it runs (the CLI prints it on stderr)."""

    phase: str
    states: int                    # states of the phase so far (as its loop last said)
    rate: float                    # states per second since the last status
    resident: int                  # bytes
    elapsed: float                 # seconds since the start of the run


StatusCallback = Callable[[Status], None]


@dataclass
class Cap:
    """What a capped first try did to the run (``Budget.capped``)."""

    hit: bool = False      # the cap's deadline stopped something inside the try


class Budget:
    """A deadline, a memory limit and a stop flag shared by every phase of one run."""

    def __init__(self, time_limit: float | None = None, max_memory: int | None = None, *,
                 start: float | None = None, on_status: StatusCallback | None = None,
                 status_every: float = 0.5) -> None:
        self.start = time.monotonic() if start is None else start
        self.time_limit = time_limit
        self.deadline = None if time_limit is None else self.start + time_limit
        self._caps: list[float] = []        # the seconds of the caps shortening ``deadline``
        self.max_memory = max_memory
        self.on_status = on_status
        self.status_every = status_every
        self.stop: Stop | None = None
        self.phase = "the verification"
        self.states = 0
        self.peak = 0                  # the largest resident size measured, bytes
        self._cancelled = False
        self._rss = 0
        self._measured = -1.0
        self._reported = self.start
        self._reported_states = 0
        self.depth = 0                 # phases open (``running``)
        self.completed: list[tuple[str, float, int]] = []  # phases that returned without a
        #                                                    stop: name, seconds, depth

    # ------------------------------------------------------------------ the stop request
    def cancel(self) -> None:
        """Ask the run to stop at its next check (safe to call from a signal handler)."""
        self._cancelled = True

    @property
    def cancelled(self) -> bool:
        return self._cancelled

    # ------------------------------------------------------------------ phases
    @contextmanager
    def running(self, phase: str) -> Iterator[Budget]:
        """Name the phase that the checks inside belong to (restored afterwards)."""
        outer, outer_states = self.phase, self.states
        self.phase, self.states, self._reported_states = phase, 0, 0
        began, depth = time.monotonic(), self.depth
        self.depth += 1
        try:
            yield self
            if self.stop is None:
                self.completed.append((phase, time.monotonic() - began, depth))
        finally:
            self.phase, self.states = outer, outer_states
            self._reported_states = outer_states
            self.depth = depth

    @contextmanager
    def capped(self, seconds: float) -> Iterator[Cap]:
        """A shorter deadline for what runs inside (a first try); reaching it is not the
        run's stop: afterwards the run's own deadline holds again and its stop is cleared.
        The yielded ``Cap`` tells, once the block is left, whether the cap cut the try short
        (whatever the try reports then is partial, though its search may be complete)."""
        saved = self.deadline
        cap = time.monotonic() + seconds
        shorter = saved is None or cap < saved
        if shorter:
            self.deadline = cap
            self._caps.append(seconds)
        outcome = Cap()
        try:
            yield outcome
        finally:
            self.deadline = saved
            if shorter:
                self._caps.pop()
            if (self.stop is not None and self.stop.kind == TIME
                    and (saved is None or time.monotonic() < saved)):
                self.stop = None
                outcome.hit = True

    @property
    def inside_cap(self) -> bool:
        """Is a shorter deadline of :meth:`capped` (a try with its own schedule) in force?"""
        return bool(self._caps)

    def elapsed(self) -> float:
        return time.monotonic() - self.start

    def remaining(self) -> float | None:
        return None if self.deadline is None else max(0.0, self.deadline - time.monotonic())

    def run_remaining(self) -> float | None:
        """The run's own time left, whatever cap holds now (a share of it taken inside a
        capped first try is cut by the try's cap, which the try's caller then sees hit)."""
        return (None if self.time_limit is None
                else max(0.0, self.time_limit - (time.monotonic() - self.start)))

    # ------------------------------------------------------------------ checks
    def check(self, states: int | None = None, extra: int = 0) -> None:
        """Raise ``LimitReached`` when a limit is reached, now or before. ``states``: the
        phase's count so far (for the status line); ``extra``: bytes about to be
        allocated."""
        if states is not None:
            self.states = states
        if self.stop is not None:
            raise LimitReached(self.stop)
        now = time.monotonic()
        if self._cancelled:
            self._halt(INTERRUPT, now, None)
        if self.deadline is not None and now > self.deadline:
            if self._caps:      # a try's share, not the run's own limit
                self._halt(TIME, now, self._caps[-1], detail=(
                    "the share of the run's time this step was given" if self.time_limit is None
                    else f"the share of the run's {format_seconds(self.time_limit)} this "
                    "step was given"))
            self._halt(TIME, now, self.time_limit)
        if self.max_memory is not None or self.on_status is not None:
            if extra or now - self._measured >= _MEASURE_EVERY:
                self._measure(now)
            if self.max_memory is not None and self._rss + extra > self.max_memory:
                self._halt(MEMORY, now, float(self.max_memory), self._rss + extra,
                           f"{format_size(self._rss)} resident, the next step needs "
                           f"{format_size(extra)} more" if extra else "")
        if self.on_status is not None and now - self._reported >= self.status_every:
            self._status(now)

    def poll(self, states: int | None = None, extra: int = 0) -> Stop | None:
        """``check`` without the exception: the stop, or None."""
        try:
            self.check(states, extra)
        except LimitReached as e:
            return e.stop
        return None

    def fits(self, extra: int) -> bool:
        """Would ``extra`` more bytes stay under the memory limit? Stops nothing."""
        if self.max_memory is None:
            return True
        self._measure(time.monotonic())
        return self._rss + extra <= self.max_memory

    def out_of_memory(self, detail: str = "an allocation failed") -> Stop:
        """Record that an allocation failed (``MemoryError``): a memory stop, unless the run
        had stopped already. Returns the run's stop."""
        if self.stop is None:
            now = time.monotonic()
            self._measure(now)
            self.stop = Stop(MEMORY, self.phase, None if self.max_memory is None
                             else float(self.max_memory), now - self.start, self._rss, detail)
        return self.stop

    def expire(self, kind: str, detail: str = "") -> Stop:
        """Record that a limit of the run (``kind``: time, memory, interrupt) was reached,
        as the verify command's watchdog sees it from outside the phase: the run's stop,
        without raising (the next check raises). Returns the run's stop, which stays the
        first one recorded."""
        if self.stop is None:
            now = time.monotonic()
            limit = (self.time_limit if kind == TIME else None if kind == INTERRUPT
                     else None if self.max_memory is None else float(self.max_memory))
            self.stop = Stop(kind, self.phase, limit, now - self.start, self._rss, detail)
        return self.stop

    def report_status(self, quiet_for: float = 0.0) -> None:
        """Report the status now (resident size measured), unless the phase itself
        reported one in the last ``quiet_for`` seconds: the watchdog's progress line in the
        phases that do not check the budget."""
        now = time.monotonic()
        if self.on_status is not None and now - self._reported >= quiet_for:
            self._measure(now)
            self._status(now)

    def resident(self) -> int:
        """The resident size, bytes (measured now)."""
        self._measure(time.monotonic())
        return self._rss

    def peak_resident(self) -> int:
        """The peak resident size of the run, bytes, for its report: the kernel's high-water
        mark of this process and of the largest child it waited for (SPIN, a worker), or
        what was sampled where the kernel does not say (the samples miss short peaks)."""
        return max(self.peak, self.resident(), high_water_mark())

    def _measure(self, now: float) -> None:
        self._measured = now
        self._rss = resident_memory()
        self.peak = max(self.peak, self._rss)

    def _halt(self, kind: str, now: float, limit: float | None, resident: int = 0,
              detail: str = "") -> None:
        self.stop = Stop(kind, self.phase, limit, now - self.start, resident or self._rss,
                         detail)
        raise LimitReached(self.stop)

    def _status(self, now: float) -> None:
        assert self.on_status is not None
        dt = max(1e-9, now - self._reported)
        done = self.states - self._reported_states if self.states >= self._reported_states \
            else self.states
        self._reported, self._reported_states = now, self.states
        self.on_status(Status(self.phase, self.states, done / dt, self._rss, now - self.start))


# ---------------------------------------------------------------------- the machine's memory
def resident_memory(pid: int | str = "self") -> int:
    """The resident size of a process in bytes (``/proc/<pid>/statm``); the peak resident
    size where there is no /proc (it bounds the current one); 0 when unknown."""
    try:
        with open(f"/proc/{pid}/statm", "rb") as f:
            return int(f.read().split()[1]) * _PAGE
    except (OSError, ValueError, IndexError):
        if pid != "self":
            return 0
    try:
        import resource
    except ImportError:             # no /proc, no resource: unknown
        return 0
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return int(peak) * (1 if os.uname().sysname == "Darwin" else 1024)


def high_water_mark() -> int:
    """The peak resident size of this process (``VmHWM`` of /proc/self/status: of its own
    image; ``getrusage``'s ``ru_maxrss`` keeps, across exec, the size of the process it was
    forked from: a test suite's 2 GB) or, if larger, of the largest child it waited for (SPIN:
    forked from this process, so never more than this process's size at the fork plus its
    own), bytes; 0 when unknown."""
    own = _status_kb("VmHWM")
    try:
        import resource
    except ImportError:
        return (own or 0) * 1024
    unit = 1 if os.uname().sysname == "Darwin" else 1024
    if own is None:
        own = int(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss) * unit // 1024
    children = int(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss) * unit
    return max(own * 1024, children)


def _status_kb(field: str) -> int | None:
    """A ``kB`` field of /proc/self/status, or None where there is none."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        return None
    return None


def _meminfo(field: str) -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith(field + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_limit() -> int | None:
    for path in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            with open(path) as f:
                text = f.read().strip()
        except OSError:
            continue
        if text.isdigit() and int(text) < 1 << 60:
            return int(text)
    return None


def physical_memory() -> int | None:
    """The machine's physical memory in bytes, or the cgroup's limit when smaller."""
    total: int | None = None
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        total = _meminfo("MemTotal")
    limit = _cgroup_limit()
    if limit is not None and (total is None or limit < total):
        total = limit
    return total


def default_max_memory(fraction: float = DEFAULT_MEMORY_FRACTION) -> int | None:
    """``fraction`` of the physical memory, and no more than 90 % of what is available now
    (with what this process holds already); None when the machine does not say."""
    total = physical_memory()
    if total is None:
        return None
    limit = int(total * fraction)
    available = _meminfo("MemAvailable")
    if available is not None:
        limit = min(limit, int(0.9 * (available + resident_memory())))
    return limit


def parse_size(text: str) -> int:
    """``8G``, ``500M``, ``1.5GB``, ``60%`` (of the physical memory); a bare number is in GB."""
    s = text.strip().upper().replace(" ", "")
    if s.endswith("%"):
        total = physical_memory()
        if total is None:
            raise ValueError("the machine's physical memory is unknown: give a size")
        share = _finite(s[:-1])
        if not 0 < share <= 100:
            raise ValueError("a share of the physical memory is a percentage above 0, "
                             "at most 100")
        return max(1, int(total * share / 100))
    for suffix in ("IB", "B"):
        if s.endswith(suffix) and len(s) > len(suffix) and not s[:-len(suffix)][-1].isdigit():
            s = s[:-len(suffix)]
            break
    scale = {"K": 1 << 10, "M": MB, "G": GB, "T": 1 << 40}
    factor = GB
    if s and s[-1] in scale:
        factor = scale[s[-1]]
        s = s[:-1]
    value = _finite(s) * factor
    if value < 1:
        raise ValueError("the size must be positive")
    if value < MB:      # 1K was taken as a limit of 0 MB, reached before anything ran
        raise ValueError("the size must be at least 1M (the verifier itself takes more)")
    if value > MAX_SIZE:
        raise ValueError(f"the size must be at most {MAX_SIZE >> 40}T (no machine has more)")
    return int(value)


def _finite(text: str) -> float:
    """The number ``text``: a ValueError for nan, inf and what is not a number."""
    try:
        value = float(text)
    except ValueError:
        raise ValueError("not a number with an optional unit (K, M, G, T) or %") from None
    if not math.isfinite(value):
        raise ValueError("the size must be a finite number")
    return value


def format_size(n: int) -> str:
    if n >= GB:
        return f"{n / GB:.1f} GB"
    return f"{n / MB:.0f} MB"


def format_seconds(s: float) -> str:
    return f"{s:g} s"


def limit_data_segment(max_memory: int) -> Callable[[], None]:
    """A backstop for the resident-size checks: cap the data segment (``RLIMIT_DATA``) a
    good margin above ``max_memory``, so that an allocation the checks did not see fails
    with ``MemoryError`` (reported as the memory limit) instead of the OS killing the run.
    Never raises the current limit. Returns the function that puts the old limit back."""
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_DATA)
        cap = max_memory + max(GB, max_memory // 2)
        if hard != resource.RLIM_INFINITY:
            cap = min(cap, hard)
        if soft == resource.RLIM_INFINITY or cap < soft:
            resource.setrlimit(resource.RLIMIT_DATA, (cap, hard))
    except (ImportError, ValueError, OSError, AttributeError):
        return lambda: None

    def restore() -> None:
        with contextlib.suppress(ValueError, OSError):
            resource.setrlimit(resource.RLIMIT_DATA, (soft, hard))

    return restore


# ---------------------------------------------------------------------- external tools
def run_limited(cmd: Sequence[str], budget: Budget | None, timeout: float | None = None,
                cwd: str | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``cmd`` with its output captured. ``subprocess.TimeoutExpired`` after
    ``timeout`` seconds, ``LimitReached`` when the budget runs out (the child's resident
    size counts); either way the child (and its process group) is killed first."""
    proc = subprocess.Popen(list(cmd), cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    end = None if timeout is None else time.monotonic() + timeout
    try:
        while True:
            try:
                out, err = proc.communicate(timeout=0.1)
                return subprocess.CompletedProcess(list(cmd), proc.returncode, out, err)
            except subprocess.TimeoutExpired:
                pass
            if end is not None and time.monotonic() > end:
                raise subprocess.TimeoutExpired(list(cmd), timeout or 0.0)
            if budget is not None:
                budget.check(extra=resident_memory(proc.pid))
    finally:
        if proc.poll() is None:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except OSError:
                proc.kill()
            proc.communicate()
