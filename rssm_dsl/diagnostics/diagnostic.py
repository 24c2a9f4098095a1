"""Diagnostics are data: code, severity, message, primary span, related spans, a hint.

Messages and hints quote the user's text (names, paths, strings): they are made safe to print
when a diagnostic is made (:func:`bound_text`), for every output (text, JSON, the language
server): control characters are escaped and a run of non-blank characters longer than
:data:`MAX_QUOTED` is shortened in the middle, so that a 1 MB identifier is not repeated in
full by every diagnostic that names it.
"""

from __future__ import annotations

import re
from dataclasses import field
from typing import Any

from rssm_core.records import dataclass
from rssm_dsl.diagnostics.codes import BY_CODE, Severity
from rssm_dsl.source import Span, escape_controls

DOCS_URL = "https://github.com/rssmc/rssmc/blob/main/docs/diagnostics.md"

MAX_QUOTED = 160       # the longest run of non-blank characters (a name, a path) shown whole
_HEAD, _TAIL = 2 * MAX_QUOTED // 3, MAX_QUOTED // 4
_LONG_WORD = re.compile(rf"\S{{{MAX_QUOTED + 1},}}")


def _shorten(m: re.Match[str]) -> str:
    word = m.group()
    return word[:_HEAD] + "…" + word[-_TAIL:]


def bound_text(text: str) -> str:
    """``text`` safe to print and bounded: each run of more than MAX_QUOTED non-blank
    characters keeps its start and its end around a ``…``, control characters are escaped
    (rssm_dsl.source.escape_controls)."""
    if len(text) > MAX_QUOTED:
        text = _LONG_WORD.sub(_shorten, text)
    return escape_controls(text)


@dataclass(frozen=True, slots=True)
class Related:
    span: Span
    message: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "message", bound_text(self.message))


@dataclass(frozen=True, slots=True)
class Diagnostic:
    code: str
    message: str
    span: Span
    hint: str | None = None
    related: tuple[Related, ...] = field(default=())

    def __post_init__(self) -> None:
        assert self.code in BY_CODE, f"unregistered diagnostic code {self.code}"
        object.__setattr__(self, "message", bound_text(self.message))
        if self.hint is not None:
            object.__setattr__(self, "hint", bound_text(self.hint))

    @property
    def severity(self) -> Severity:
        return BY_CODE[self.code].severity

    @property
    def slug(self) -> str:
        return BY_CODE[self.code].slug

    @property
    def is_error(self) -> bool:
        return self.severity is Severity.ERROR

    def sort_key(self) -> tuple[str, int, int, str]:
        return (self.span.file, self.span.line, self.span.column, self.code)

    def to_json(self) -> dict[str, Any]:
        def span_json(s: Span) -> dict[str, Any]:
            return {
                "file": s.file, "line": s.line, "column": s.column,
                "end_line": s.end_line, "end_column": s.end_column,
            }

        return {
            "code": self.code,
            "name": self.slug,
            "severity": self.severity.value,
            "message": self.message,
            "hint": self.hint,
            "span": span_json(self.span),
            "related": [{"message": r.message, "span": span_json(r.span)} for r in self.related],
            "docs": f"{DOCS_URL}#{self.code.lower()}",
        }


class DiagnosticBag:
    """Collects diagnostics; passes report and go on, they do not raise."""

    def __init__(self) -> None:
        self.items: list[Diagnostic] = []

    def add(self, d: Diagnostic) -> None:
        self.items.append(d)

    def error(
        self, code: str, message: str, span: Span, hint: str | None = None,
        related: tuple[Related, ...] = (),
    ) -> None:
        self.items.append(Diagnostic(code, message, span, hint, related))

    warn = error  # the code decides the severity

    @property
    def has_errors(self) -> bool:
        return any(d.is_error for d in self.items)

    def sorted(self) -> list[Diagnostic]:
        seen: set[tuple[str, str, Span]] = set()
        out: list[Diagnostic] = []
        for d in sorted(self.items, key=Diagnostic.sort_key):
            key = (d.code, d.message, d.span)
            if key not in seen:
                seen.add(key)
                out.append(d)
        return out
