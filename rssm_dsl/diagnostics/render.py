"""Render diagnostics as text with a caret under the span, or as JSON."""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable

from rssm_dsl.diagnostics.diagnostic import Diagnostic
from rssm_dsl.source import Span

LineSource = Callable[[str, int], str]


def _caret(span: Span, line_text: str) -> str:
    start = max(span.column - 1, 0)
    if span.end_line == span.line:
        width = max(span.end_column - span.column, 1)
    else:
        width = max(len(line_text) - start, 1)
    prefix = "".join(ch if ch == "\t" else " " for ch in line_text[:start])
    return prefix + "^" * width


def render_text(diags: Iterable[Diagnostic], line_of: LineSource) -> str:
    out: list[str] = []
    for d in diags:
        s = d.span
        out.append(f"{s.file}:{s.line}:{s.column}: {d.severity.value}[{d.code}]: {d.message}")
        text = line_of(s.file, s.line)
        if text:
            gutter = f"{s.line:>5} | "
            out.append(gutter + text)
            out.append(" " * (len(gutter) - 2) + "| " + _caret(s, text))
        for r in d.related:
            out.append(f"  {r.span.file}:{r.span.line}:{r.span.column}: note: {r.message}")
        if d.hint:
            out.append(f"  help: {d.hint}")
    return "\n".join(out)


def summary(diags: list[Diagnostic]) -> str:
    errors = sum(1 for d in diags if d.is_error)
    warnings = len(diags) - errors
    return f"{errors} error{'s' * (errors != 1)}, {warnings} warning{'s' * (warnings != 1)}"


def render_json(diags: Iterable[Diagnostic]) -> str:
    return json.dumps([d.to_json() for d in diags], indent=2)
