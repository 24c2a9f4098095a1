"""Diagnostics are data: code, severity, message, primary span, related spans, a hint."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from rssm_dsl.diagnostics.codes import BY_CODE, Severity
from rssm_dsl.source import Span

DOCS_URL = "https://github.com/rssmc/rssmc/blob/main/docs/diagnostics.md"


@dataclass(frozen=True, slots=True)
class Related:
    span: Span
    message: str


@dataclass(frozen=True, slots=True)
class Diagnostic:
    code: str
    message: str
    span: Span
    hint: str | None = None
    related: tuple[Related, ...] = field(default=())

    def __post_init__(self) -> None:
        assert self.code in BY_CODE, f"unregistered diagnostic code {self.code}"

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
