"""Work off the event loop that can be stopped: each job runs in a daemon thread of its own
(a long analysis never delays another document's), and `cancel()` stops it by raising
`Cancelled` inside that thread at its next Python instruction (PyThreadState_SetAsyncExc).

The compiler is pure Python, so a superseded analysis of a huge text stops within
microseconds instead of running to its end. `Cancelled` derives from BaseException so that
the compiler's `except Exception` recovery does not swallow it; `with` blocks release their
locks on the way out. At most one `Cancelled` is sent per job, and only while its function
runs: the thread clears any that is still pending before it reports, so none can escape.
"""

from __future__ import annotations

import asyncio
import contextlib
import ctypes
import gc
import logging
import threading
from collections.abc import Callable
from typing import Generic, TypeVar

log = logging.getLogger("rssmc.lsp")
T = TypeVar("T")


class Cancelled(BaseException):
    """Raised inside a job's thread by Job.cancel()."""


def _raise_in(ident: int, exc: type[BaseException] | None) -> None:
    """Make thread `ident` raise `exc` at its next instruction (None: forget a pending one)."""
    arg = ctypes.py_object(exc) if exc is not None else None
    ctypes.pythonapi.PyThreadState_SetAsyncExc(ctypes.c_ulong(ident), arg)


class Job(Generic[T]):
    """`fn()` in a new daemon thread; `future` (of the loop) gets its result, its exception,
    or is cancelled."""

    def __init__(self, fn: Callable[[], T], loop: asyncio.AbstractEventLoop,
                 name: str = "rssm-job") -> None:
        self.loop = loop
        self.future: asyncio.Future[T] = loop.create_future()
        self._fn = fn
        self._lock = threading.Lock()
        self._running = True
        self._cancel_sent = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    @property
    def running(self) -> bool:
        return self._running

    def cancel(self) -> bool:
        """Stop the job (its future is cancelled). False when it had already ended."""
        with self._lock:
            if not self._running or self._cancel_sent or self._thread.ident is None:
                return False
            self._cancel_sent = True
            _raise_in(self._thread.ident, Cancelled)
        return True

    def _run(self) -> None:
        result: T | None = None
        error: Exception | None = None
        try:   # one Cancelled at most is sent: caught here wherever it lands before _settle
            try:
                result = self._fn()
            except Exception as e:
                error = e
        except Cancelled:
            pass
        cancelled = self._settle()
        if cancelled:
            gc.enable()   # in case it stopped inside a gc.disable() section
        del self._fn      # the job's arguments (a document's text...) can go
        with contextlib.suppress(RuntimeError):   # a closed loop: nobody waits any more
            self.loop.call_soon_threadsafe(self._report, result, error, cancelled)

    def _settle(self) -> bool:
        """End the running state; no Cancelled can be raised in this thread afterwards.
        True if the job was cancelled."""
        while True:
            try:
                with self._lock:
                    self._running = False
                    _raise_in(threading.get_ident(), None)
                    return self._cancel_sent
            except Cancelled:   # delivered on the way here: settle again
                continue

    def _report(self, result: T | None, error: Exception | None, cancelled: bool) -> None:
        if self.future.done():
            return
        if cancelled:
            self.future.cancel()
        elif error is not None:
            self.future.set_exception(error)
        else:
            self.future.set_result(result)  # type: ignore[arg-type]


async def run_job(fn: Callable[[], T], name: str = "rssm-work") -> T:
    """Await `fn()` run in a job's thread; cancelling the awaiting task cancels the job."""
    job = Job(fn, asyncio.get_running_loop(), name)
    try:
        return await asyncio.shield(job.future)
    except asyncio.CancelledError:
        job.cancel()
        raise
