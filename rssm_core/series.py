"""Series of a run, defined once: values of chosen variables over time, stored by column.

A trace (trace.py) records every firing, so its size grows with the firings; a *series file*
records only what a user chose to look at, one sample per iteration of the subsystem that
owns it, so its size grows with the series times their samples. It is a NumPy ``.npz``
archive (compressed) with these arrays:

| key        | shape, dtype          | what                                                   |
|------------|-----------------------|--------------------------------------------------------|
| ``meta``   | () str (JSON)         | ``{"format": 1, "system": NAME, "series": [S, ...]}``  |
| ``t<k>``   | (n_k,) float64        | sample times of series k, seconds                      |
| ``v<k>``   | (n_k,) float64        | its values: the number, or the index into ``labels``   |

Each ``S`` is ``{"name", "subsystem", "kind", "labels"}``: ``name`` is the user's
(``a1.c.phase``, ``a1.e.arm.cmd.x``, ``a1.c.q[2]``, ``a1.c.behaviour``), ``kind`` is
``"number"`` (bool, int, float, range: one component) or ``"category"`` (the active
behaviour, an enum: ``v`` indexes ``labels``). A vector or record value is stored as one
series per component. :func:`write_series` writes a file, :func:`read_series` reads one back,
:func:`select_series` chooses series by name (shell patterns).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import field
from fnmatch import fnmatchcase
from pathlib import Path
from typing import Any

from rssm_core.records import dataclass

SERIES_FORMAT = 1
KINDS = ("number", "category")


class SeriesFormatError(Exception):
    """A file that is not a series file of this format."""


@dataclass
class Series:
    name: str
    subsystem: str
    kind: str                              # "number" | "category"
    labels: list[str] = field(default_factory=list)
    t: list[float] | Any = field(default_factory=list)     # list while recording, array read
    v: list[float] | Any = field(default_factory=list)

    def label_index(self, label: str) -> int:
        if label not in self.labels:
            self.labels.append(label)
        return self.labels.index(label)


def encode_series(system: str, series: list[Series]) -> bytes:
    """The series file of ``series`` (the bytes of a ``.npz``)."""
    import io

    import numpy as np

    meta = {"format": SERIES_FORMAT, "system": system,
            "series": [{"name": s.name, "subsystem": s.subsystem, "kind": s.kind,
                        "labels": s.labels} for s in series]}
    arrays: dict[str, Any] = {"meta": np.array(json.dumps(meta))}
    for k, s in enumerate(series):
        arrays[f"t{k}"] = np.asarray(s.t, dtype=np.float64)
        arrays[f"v{k}"] = np.asarray(s.v, dtype=np.float64)
    out = io.BytesIO()
    np.savez_compressed(out, **arrays)
    return out.getvalue()


def write_series(path: Path, system: str, series: list[Series]) -> None:
    """Write the series to ``path`` (``.npz``)."""
    path.write_bytes(encode_series(system, series))


def read_series(path: Path) -> tuple[str, list[Series]]:
    """The system's name and its series, as written by :func:`write_series`; each checked
    (:func:`malformed`). Anything else is :class:`SeriesFormatError`."""
    import numpy as np

    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            if not isinstance(meta, dict):
                raise SeriesFormatError("not a series file: its meta is no JSON object")
            if meta.get("format") != SERIES_FORMAT:
                raise SeriesFormatError(f"series format {meta.get('format')!r}, not "
                                        f"{SERIES_FORMAT}")
            out = [Series(s["name"], s["subsystem"], s["kind"], list(s["labels"]),
                          data[f"t{k}"], data[f"v{k}"])
                   for k, s in enumerate(meta["series"])]
            system = str(meta["system"])
    except SeriesFormatError:
        raise
    except RecursionError:
        raise SeriesFormatError("not a series file: its meta is nested too deeply") from None
    except (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError,
            json.JSONDecodeError) as e:
        raise SeriesFormatError(f"not a series file: {e}") from None
    for one in out:
        problem = malformed(one)
        if problem is not None:
            raise SeriesFormatError(f"series '{one.name}': {problem}")
    return system, out


def malformed(s: Series) -> str | None:
    """What is wrong with a series read from a file, or None."""
    import numpy as np

    if not isinstance(s.name, str) or not isinstance(s.subsystem, str):
        return "its name or subsystem is not a string"
    if s.kind not in KINDS:
        return f"kind {s.kind!r} is neither {' nor '.join(KINDS)}"
    if not all(isinstance(x, str) for x in s.labels):
        return "its labels are not strings"
    t, v = np.asarray(s.t), np.asarray(s.v)
    if t.ndim != 1 or v.ndim != 1 or t.shape != v.shape:
        return f"its times {t.shape} and values {v.shape} are not two columns of one length"
    if not (np.issubdtype(t.dtype, np.number) and np.issubdtype(v.dtype, np.number)):
        return "its times or values are not numbers"
    if not np.isfinite(t.astype(np.float64)).all():
        return "a time is not a finite number"
    return None


def matches(name: str, patterns: Sequence[str]) -> bool:
    """A series name chosen by one of the shell patterns (``a1.c.*``, ``*.behaviour``,
    ``a1.c.q[[]2]``), case-sensitive: what ``--select`` means."""
    return any(fnmatchcase(name, p) for p in patterns)


def select_series(series: list[Series], patterns: Sequence[str]) -> tuple[list[Series], list[str]]:
    """The series chosen by ``patterns`` (see :func:`matches`), in file order, and the
    patterns that choose none."""
    chosen = [s for s in series if matches(s.name, patterns)]
    unmatched = [p for p in patterns if not any(matches(s.name, [p]) for s in series)]
    return chosen, unmatched
