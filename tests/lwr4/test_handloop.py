"""The hand-written 1 kHz baseline loop tracks the cw-then-ccw circle."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

BENCH = Path(__file__).resolve().parents[2] / "bench" / "lwr4_handloop.py"


def load_bench() -> ModuleType:
    spec = importlib.util.spec_from_file_location("lwr4_handloop", BENCH)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = (
        module  # dataclasses look their module up while being built
    )
    spec.loader.exec_module(module)
    return module


handloop = load_bench()


def fit_circle(xy: NDArray[np.float64]) -> tuple[NDArray[np.float64], float]:
    """Least-squares (Kasa) circle through 2-D points: centre and radius."""
    a = np.column_stack([2.0 * xy, np.ones(len(xy))])
    b = (xy**2).sum(axis=1)
    (cx, cy, c), *_ = np.linalg.lstsq(a, b, rcond=None)
    return np.array([cx, cy]), float(np.sqrt(c + cx**2 + cy**2))


def signed_area(xy: NDArray[np.float64]) -> float:
    """Shoelace area: positive when the path runs counter-clockwise seen from above."""
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


@pytest.fixture(scope="module")
def tracked() -> dict[str, Any]:
    result: dict[str, Any] = handloop.run_hand_loop(damp_velocity_error=True)
    return result


def test_velocity_error_damping_tracks_within_a_millimetre(
    tracked: dict[str, Any],
) -> None:
    cfg = handloop.LoopConfig()
    assert tracked["steps"] == round(2 * cfg.period / 0.001)
    assert tracked["rms_error_m"] < 1e-3
    assert tracked["max_error_m"] < 3e-3
    # Real-time capable with a wide margin even on a loaded machine.
    assert tracked["us_per_step"] < 500.0


def test_path_is_the_commanded_circle_cw_then_ccw(tracked: dict[str, Any]) -> None:
    cfg = handloop.LoopConfig()
    p = np.asarray(tracked["p"])
    t = np.asarray(tracked["t"])
    centre = np.asarray(tracked["centre"])
    assert np.ptp(p[:, 2]) < 3e-3  # horizontal
    fit_centre, radius = fit_circle(p[:, :2])
    assert np.linalg.norm(fit_centre - centre[:2]) < 1e-3
    assert abs(radius - cfg.radius) < 1e-3
    # Every sample lies near the circle, and both turns are complete.
    assert np.abs(np.linalg.norm(p[:, :2] - fit_centre, axis=1) - radius).max() < 3e-3
    first = p[t < cfg.period, :2]
    second = p[t >= cfg.period, :2]
    full_turn = np.pi * cfg.radius**2
    clockwise, counter_clockwise = -full_turn, full_turn
    assert signed_area(first) == pytest.approx(clockwise, rel=0.05)
    assert signed_area(second) == pytest.approx(counter_clockwise, rel=0.05)


def test_paper_damping_lags_far_more(tracked: dict[str, Any]) -> None:
    paper = handloop.run_hand_loop(damp_velocity_error=False)
    assert paper["rms_error_m"] > 4.0 * tracked["rms_error_m"]
    assert 3e-3 < paper["rms_error_m"] < 2e-2


def test_duration_shortens_the_run() -> None:
    short = handloop.run_hand_loop(duration_s=0.5)
    assert short["steps"] == 500
    assert short["t"][-1] == pytest.approx(0.499)
    assert short["p"].shape == (500, 3) and short["q"].shape == (500, 7)
