"""Jobs (rssm_dsl/lsp/jobs.py): work in a thread of its own that a newer request can stop."""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time

import pytest

from rssm_dsl.lsp.jobs import Job, run_job

pytestmark = pytest.mark.asyncio


def _spin() -> int:
    n = 0
    while True:
        n += 1
        with contextlib.suppress(Exception):   # such recovery does not swallow a cancel
            n += 1


async def test_a_running_job_is_stopped_by_cancel() -> None:
    """(The job stops at its next instruction; it needs the GIL for that, which a thread an
    earlier test left in one long C call can hold for seconds: hence the generous limit, and
    the threads named when it is reached.)"""
    job = Job(_spin, asyncio.get_running_loop())
    await asyncio.sleep(0.05)
    assert job.running and job.cancel()
    done, _ = await asyncio.wait([job.future], timeout=30)
    assert done, f"not stopped in 30 s; threads: {[t.name for t in threading.enumerate()]}"
    assert job.future.cancelled()
    assert not job.running
    assert not job.cancel()   # once


async def test_results_and_errors_reach_the_loop() -> None:
    assert await run_job(lambda: 6 * 7) == 42
    with pytest.raises(ZeroDivisionError):
        await run_job(lambda: 1 // 0)


async def test_cancels_at_any_moment_never_escape_the_job() -> None:
    """Cancelled at random points, even as they end: every job reports, none leaks a
    Cancelled into its thread's end (threading.excepthook would see it)."""
    seen: list[BaseException] = []
    previous = threading.excepthook
    threading.excepthook = lambda args: seen.append(args.exc_value)  # type: ignore[assignment]
    try:
        loop = asyncio.get_running_loop()
        for k in range(300):
            size = 50 * (k % 7)
            job = Job(lambda size=size: sum(range(size)), loop)  # type: ignore[misc]
            if k % 2:
                await asyncio.sleep(0)
            job.cancel()
            await asyncio.wait([job.future], timeout=5)
            assert job.future.done()
        deadline = time.monotonic() + 5
        while threading.active_count() > 1 and time.monotonic() < deadline:
            await asyncio.sleep(0.01)
    finally:
        threading.excepthook = previous
    assert seen == []
