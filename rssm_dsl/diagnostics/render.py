"""Render diagnostics as text with a caret under the span, or as JSON.

The text output is bounded whatever the input:

- a diagnostic shows a window of at most :data:`MAX_EXCERPT` columns of its source line
  around the span (:func:`excerpt`), ``...`` marking what is cut on either side;
- control characters of the source are shown escaped (``\\x07``, ``\\u202e``), the caret
  under the escaped text: a spec file never sends a terminal an escape sequence;
- at most :data:`MAX_SHOWN_PER_FILE` diagnostics of one file are printed (its errors
  first), then ``... and K more errors (and W more warnings) in FILE``; the summary line of
  the command still gives the true totals.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Iterator

from rssm_dsl.diagnostics.diagnostic import Diagnostic
from rssm_dsl.source import Span, escape_char, escape_controls

LineSource = Callable[[str, int], str]

MAX_EXCERPT = 100          # columns of a source line shown around a span (plus the "..."s)
CONTEXT_BEFORE = 30        # columns shown before the span when the line has to be cut
MAX_SHOWN_PER_FILE = 50    # diagnostics of one file printed as text; the rest are counted
CUT = "..."


def _width(pieces: list[str]) -> int:
    return sum(len(p) for p in pieces)


def _take(pieces: list[str], room: int) -> list[str]:
    """The longest prefix of ``pieces`` that fits in ``room`` columns."""
    out: list[str] = []
    used = 0
    for p in pieces:
        if used + len(p) > room:
            break
        out.append(p)
        used += len(p)
    return out


def excerpt(line: str, start: int, end: int) -> tuple[str, str]:
    """The shown part of ``line`` and the caret line under it, for the span of characters
    ``line[start:end]`` (0-based; an empty span gets one caret). At most MAX_EXCERPT columns
    of the line are shown (each escaped character counts its escape's width), with up to
    CONTEXT_BEFORE columns before the span when the line is cut; the span itself is cut when
    longer. The caret line copies the tabs before the span, so the caret stays aligned."""
    n = len(line)
    start = min(max(start, 0), n)
    end = min(max(end, start), n)
    # every character takes at least one column: no more than MAX_EXCERPT on either side
    lo = max(0, start - MAX_EXCERPT)
    span_hi = min(end, start + MAX_EXCERPT)
    after_hi = min(n, span_hi + MAX_EXCERPT)
    before = [escape_char(c) for c in line[lo:start]]
    span = [escape_char(c) for c in line[start:span_hi]]
    after = [escape_char(c) for c in line[span_hi:after_hi]]

    if lo == 0 and _width(before) + _width(span) <= MAX_EXCERPT:
        kept_before = before
    else:
        kept_before = _take(before[::-1], CONTEXT_BEFORE)[::-1]
    left_cut = lo > 0 or len(kept_before) < len(before)
    used = _width(kept_before)
    kept_span = _take(span, MAX_EXCERPT - used) or span[:1]
    span_cut = len(kept_span) < len(span) or span_hi < end
    used += _width(kept_span)
    kept_after = [] if span_cut else _take(after, MAX_EXCERPT - used)
    right_cut = span_cut or len(kept_after) < len(after) or after_hi < n

    shown = (CUT if left_cut else "") + "".join(kept_before + kept_span + kept_after) + (
        CUT if right_cut else "")
    prefix = "".join("\t" if p == "\t" else " " * len(p) for p in kept_before)
    caret = (" " * len(CUT) if left_cut else "") + prefix + "^" * max(_width(kept_span), 1)
    return shown, caret


def _span_excerpt(span: Span, line_text: str) -> tuple[str, str]:
    start = span.column - 1
    end = span.end_column - 1 if span.end_line == span.line else len(line_text)
    return excerpt(line_text, start, end)


def _shown(diags: list[Diagnostic], limit: int) -> set[int]:
    """The indices of the diagnostics printed: per file, its first ``limit`` errors, then
    its first warnings while fewer than ``limit`` are printed."""
    errors: dict[str, list[int]] = {}
    others: dict[str, list[int]] = {}
    for i, d in enumerate(diags):
        (errors if d.is_error else others).setdefault(d.span.file, []).append(i)
    shown: set[int] = set()
    for file in {*errors, *others}:
        kept = errors.get(file, [])[:limit]
        shown.update(kept)
        shown.update(others.get(file, [])[: limit - len(kept)])
    return shown


def _count(n: int, what: str) -> str:
    return f"{n} more {what}{'s' * (n != 1)}"


def _more(file: str, errors: int, warnings: int) -> str:
    if errors and warnings:
        told = f"{_count(errors, 'error')} (and {_count(warnings, 'warning')})"
    else:
        told = _count(errors, "error") if errors else _count(warnings, "warning")
    return f"... and {told} in {escape_controls(file)}"


def render_text(diags: Iterable[Diagnostic], line_of: LineSource,
                limit: int = MAX_SHOWN_PER_FILE) -> str:
    """The diagnostics as text: at most ``limit`` per file, each with a bounded excerpt of
    its line (see the module docstring)."""
    items = list(diags)
    shown = _shown(items, limit)
    hidden: dict[str, list[int]] = {}      # file -> [errors, warnings] not printed
    out: list[str] = []
    for i, d in enumerate(items):
        s = d.span
        if i not in shown:
            hidden.setdefault(s.file, [0, 0])[0 if d.is_error else 1] += 1
            continue
        file = escape_controls(s.file)
        out.append(f"{file}:{s.line}:{s.column}: {d.severity.value}[{d.code}]: {d.message}")
        text = line_of(s.file, s.line)
        if text:
            gutter = f"{s.line:>5} | "
            shown_text, caret = _span_excerpt(s, text)
            out.append(gutter + shown_text)
            out.append(" " * (len(gutter) - 2) + "| " + caret)
        for r in d.related:
            out.append(f"  {escape_controls(r.span.file)}:{r.span.line}:{r.span.column}: "
                       f"note: {r.message}")
        if d.hint:
            out.append(f"  help: {d.hint}")
    out.extend(_more(file, e, w) for file, (e, w) in hidden.items())
    return "\n".join(out)


def summary(diags: list[Diagnostic]) -> str:
    errors = sum(1 for d in diags if d.is_error)
    warnings = len(diags) - errors
    return f"{errors} error{'s' * (errors != 1)}, {warnings} warning{'s' * (warnings != 1)}"


def json_chunks(diags: Iterable[Diagnostic]) -> Iterator[str]:
    """The text of :func:`render_json` in pieces, one diagnostic at a time, to be written as
    they come: a program with many diagnostics never holds all of their JSON at once."""
    first = True
    for d in diags:
        item = "  " + json.dumps(d.to_json(), indent=2).replace("\n", "\n  ")
        yield ("[\n" if first else ",\n") + item
        first = False
    yield "[]" if first else "\n]"


def render_json(diags: Iterable[Diagnostic]) -> str:
    """Every diagnostic, uncapped: the JSON output is read by programs (editors, CI
    annotations) that filter and count themselves and must see what the summary counts. It
    stays proportional to the input: no diagnostic embeds its source line, messages are
    bounded when made (rssm_dsl.diagnostics.diagnostic.bound_text), and the diagnostics are
    encoded one at a time (:func:`json_chunks`; the text is that of
    ``json.dumps(list, indent=2)``)."""
    return "".join(json_chunks(diags))
