"""Shared by the `rssmc run` tests: the CLI as a subprocess, and one default run of the
paper's experiment (traced) that several tests read."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tests.conftest import EXAMPLES, ROOT

LWR4 = EXAMPLES / "lwr4_circle.rssm"


def rssmc(*args: str | Path, cwd: Path | None = None, env: dict[str, str] | None = None,
          python: tuple[str, ...] = ("-m", "rssm_dsl")) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, *python, *map(str, args)], cwd=cwd or ROOT,
                          capture_output=True, text=True, timeout=300,
                          env={**os.environ, **(env or {})})


@dataclass(frozen=True)
class Trajectory:
    t: np.ndarray[Any, Any]
    desired: np.ndarray[Any, Any]
    actual: np.ndarray[Any, Any]
    error: np.ndarray[Any, Any]
    behaviour: list[str]


def read_csv(path: Path) -> Trajectory:
    with path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    def col(*names: str) -> np.ndarray[Any, Any]:
        return np.array([[float(r[n]) for n in names] for r in rows])
    return Trajectory(col("t")[:, 0], col("x_des", "y_des", "z_des"), col("x", "y", "z"),
                      col("error")[:, 0], [r["behaviour"] for r in rows])


@dataclass(frozen=True)
class Run:
    out: Path
    trace: Path
    proc: subprocess.CompletedProcess[str]
    summary: dict[str, Any]


@pytest.fixture(scope="session")
def default_run(tmp_path_factory: pytest.TempPathFactory) -> Run:
    """`rssmc run examples/lwr4_circle.rssm --trace ... --format json`, once."""
    tmp = tmp_path_factory.mktemp("run")
    out, trace = tmp / "out", tmp / "trace.jsonl"
    proc = rssmc("run", LWR4, "-o", out, "--trace", trace, "--format", "json")
    assert proc.returncode == 0, proc.stderr
    return Run(out, trace, proc, json.loads(proc.stdout))
