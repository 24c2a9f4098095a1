"""Figures of a run: Cartesian tracking error and the circle the end effector drew."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from rssm_core.records import dataclass
from rssm_dsl.run.recorder import Samples

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Circle:
    """A circle fitted in the horizontal (xy) plane by least squares."""

    centre: tuple[float, float]   # m
    radius: float                 # m
    residual: float               # RMS distance of the points from the circle, m
    height: float                 # mean z, m
    height_spread: float          # max - min of z, m


@dataclass(frozen=True)
class Metrics:
    samples: int
    rms_error: float              # m, over every sample
    max_error: float              # m
    max_error_time: float         # s
    actual_circle: Circle | None
    desired_circle: Circle | None


def fit_circle(points: FloatArray) -> Circle | None:
    """Algebraic (Kåsa) fit of x^2 + y^2 + a x + b y + c = 0 to the xy of ``points``."""
    if len(points) < 3:
        return None
    x, y = points[:, 0], points[:, 1]
    a = np.column_stack([x, y, np.ones_like(x)])
    rhs = -(x * x + y * y)
    (ca, cb, cc), *_ = np.linalg.lstsq(a, rhs, rcond=None)
    cx, cy = -ca / 2.0, -cb / 2.0
    r2 = cx * cx + cy * cy - cc
    if not r2 > 0.0:
        return None
    radius = math.sqrt(r2)
    dist = np.hypot(x - cx, y - cy) - radius
    z = points[:, 2]
    return Circle((float(cx), float(cy)), radius, float(np.sqrt(np.mean(dist * dist))),
                  float(z.mean()), float(z.max() - z.min()))


def errors(samples: Samples) -> FloatArray:
    """Distance between the desired and the actual end-effector position, per sample (m)."""
    diff: FloatArray = np.linalg.norm(samples.desired - samples.actual, axis=1)
    return diff


def measure(samples: Samples) -> Metrics:
    e = errors(samples)
    if len(e) == 0:
        return Metrics(0, float("nan"), float("nan"), float("nan"), None, None)
    k = int(np.argmax(e))
    return Metrics(len(e), float(np.sqrt(np.mean(e * e))), float(e[k]), float(samples.t[k]),
                   fit_circle(samples.actual), fit_circle(samples.desired))
