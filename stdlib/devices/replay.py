"""A device that replays measurements from a CSV file (a recorded camera, a logged sensor).

Options: ``file`` (default ``<device name>.csv``), ``at_end`` (``hold`` the last row, the
default, or ``loop``). A relative ``file`` is looked up in the device's base folder, made
absolute when the device starts: the specification's folder in the interpreter; in a ROS 2
device node, the agent package's ``share/<package>/data`` folder, where `rssmc ros2` installs
``<device name>.csv``, or the node's parameter ``rssm.base_dir`` (docs/ros2.md).

The header names the leaves of the output buffers: ``distance`` for a scalar output,
``blob.x`` for a record field, ``pose[2]`` for an array element, nested as needed
(``blob.centre[0]``). An output mentioned in the header must have all its leaves; outputs
not mentioned keep their initial values. Booleans are ``true``/``false``/``1``/``0``.

Without a ``time`` column every step measures the next row; with one (seconds, increasing),
a step measures the last row whose time is at most the device's clock.
"""

from __future__ import annotations

import bisect
import csv
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from rssm_dsl.interp.device import DeviceBase, DeviceConfigError, DeviceSpec
from rssm_dsl.interp.values import ValueTypeError, converter
from rssm_dsl.semantics.types import BOOL, FLOAT, INT, ArrayT, RecordT, Type

Row = list[str]
Build = Callable[[Row], Any]


def _scalar(t: Type, col: int, name: str) -> Build:
    def parse(row: Row) -> Any:
        text = row[col].strip()
        try:
            if t == BOOL:
                if text.lower() in ("true", "1"):
                    return True
                if text.lower() in ("false", "0"):
                    return False
                raise ValueError(text)
            return int(text) if t == INT else float(text)
        except ValueError:
            raise DeviceConfigError(f"column {name}: '{text}' is not a {t}") from None
    return parse


def leaves(prefix: str, t: Type) -> list[str]:
    """The column names of the leaves of a value of type ``t`` named ``prefix``."""
    if isinstance(t, ArrayT):
        return [x for i in range(t.size) for x in leaves(f"{prefix}[{i}]", t.element)]
    if isinstance(t, RecordT):
        return [x for n, ft in t.fields for x in leaves(f"{prefix}.{n}", ft)]
    return [prefix]


def _builder(prefix: str, t: Type, columns: dict[str, int]) -> Build:
    if isinstance(t, ArrayT):
        items = [_builder(f"{prefix}[{i}]", t.element, columns) for i in range(t.size)]
        return lambda row: [b(row) for b in items]
    if isinstance(t, RecordT):
        fields = [(n, _builder(f"{prefix}.{n}", ft, columns)) for n, ft in t.fields]
        return lambda row: {n: b(row) for n, b in fields}
    assert t in (BOOL, INT, FLOAT)
    return _scalar(t, columns[prefix], prefix)


class CsvReplay(DeviceBase):
    """Measures the rows of a CSV file, one per step or by their ``time`` column."""

    def __init__(self, spec: DeviceSpec) -> None:
        super().__init__(spec)
        path = Path(spec.options.get("file") or f"{spec.name}.csv")
        if not path.is_absolute():
            path = Path(spec.base_dir).resolve() / path
        self.path = path
        self.loop = spec.options.get("at_end", "hold") == "loop"
        try:
            with path.open(newline="", encoding="utf-8") as f:
                rows = [r for r in csv.reader(f) if r and any(c.strip() for c in r)]
        except OSError as e:
            raise DeviceConfigError(f"cannot read {path}: {e.strerror or e} (a relative file is "
                                    f"looked up in the device's base folder "
                                    f"{Path(spec.base_dir).resolve()})") from e
        if len(rows) < 2:
            raise DeviceConfigError(f"{path} needs a header row and at least one data row")
        header = [h.strip() for h in rows[0]]
        columns = {h: i for i, h in enumerate(header)}
        self.time_col = columns.get("time")
        builders: list[tuple[str, Build, Callable[[Any], Any]]] = []
        for name, t in spec.outputs.items():
            needed = leaves(name, t)
            present = [c for c in needed if c in columns]
            if not present:
                continue
            missing = [c for c in needed if c not in columns]
            if missing:
                raise DeviceConfigError(f"{path}: output '{name}' needs column(s) "
                                        + ", ".join(missing))
            builders.append((name, _builder(name, t, columns), converter(t)))
        known = {c for name, t in spec.outputs.items() for c in leaves(name, t)} | {"time"}
        unknown = [h for h in header if h not in known]
        if unknown:
            raise DeviceConfigError(f"{path}: column(s) {', '.join(unknown)} name no output "
                                    f"leaf of {spec.id}")
        self.rows: list[dict[str, Any]] = []
        self.times: list[float] = []
        for n, row in enumerate(rows[1:], start=2):
            if len(row) != len(header):
                raise DeviceConfigError(f"{path}:{n}: {len(row)} values, the header has "
                                        f"{len(header)}")
            try:
                self.rows.append({name: conv(build(row)) for name, build, conv in builders})
                if self.time_col is not None:
                    self.times.append(float(row[self.time_col]))
            except (DeviceConfigError, ValueTypeError, ValueError) as e:
                raise DeviceConfigError(f"{path}:{n}: {e}") from e
        self.steps = 0
        self.current: Mapping[str, Any] = {}

    def step(self, dt: float) -> None:
        super().step(dt)
        self.steps += 1
        n = len(self.rows)
        if self.time_col is None:
            k = self.steps - 1
        else:
            span = self.times[-1] if self.loop and self.times[-1] > 0 else None
            now = self.time % span if span else self.time
            k = max(0, bisect.bisect_right(self.times, now + 1e-12) - 1)
        self.current = self.rows[k % n if self.loop else min(k, n - 1)]

    def measure(self) -> Mapping[str, Any]:
        return self.current
