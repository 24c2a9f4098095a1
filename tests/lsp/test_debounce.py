"""The debounce of a change has a leading edge (issue 32, item 4: an edit's diagnostics in
under 20 ms): the first change after a pause is analysed at once; a change within a burst
of typing waits DEBOUNCE_SECONDS, and each cancels what the one before started, so a burst
is analysed once, at its end. The clock is the test's, not the machine's."""

from __future__ import annotations

import pytest

from rssm_dsl.lsp import server as server_module
from rssm_dsl.lsp.server import DEBOUNCE_SECONDS, RssmServer

URI = "file:///tmp/debounce.rssm"


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> Clock:
    c = Clock()
    monkeypatch.setattr(server_module, "time", type("Time", (), {"monotonic": staticmethod(c)}))
    return c


class _Running:
    running = True


def test_a_change_after_a_pause_is_analysed_at_once_one_in_a_burst_waits(clock: Clock) -> None:
    ls = RssmServer()
    assert DEBOUNCE_SECONDS > 0
    assert ls.change_delay(URI) == 0.0                       # the first change
    clock.now += DEBOUNCE_SECONDS / 2
    assert ls.change_delay(URI) == DEBOUNCE_SECONDS          # typing on
    clock.now += DEBOUNCE_SECONDS / 2
    assert ls.change_delay(URI) == DEBOUNCE_SECONDS          # still within the burst
    clock.now += 2 * DEBOUNCE_SECONDS
    assert ls.change_delay(URI) == 0.0                       # after a pause
    assert ls.change_delay("file:///tmp/other.rssm") == 0.0  # per document


def test_a_change_while_an_analysis_is_pending_or_running_waits(clock: Clock) -> None:
    ls = RssmServer()
    ls.jobs[URI] = _Running()  # type: ignore[assignment]
    assert ls.change_delay(URI) == DEBOUNCE_SECONDS
    del ls.jobs[URI]
    clock.now += 2 * DEBOUNCE_SECONDS
    ls.timers[URI] = object()  # type: ignore[assignment]
    assert ls.change_delay(URI) == DEBOUNCE_SECONDS
    del ls.timers[URI]
    clock.now += 2 * DEBOUNCE_SECONDS
    assert ls.change_delay(URI) == 0.0
