"""The compiler's diagnostic record, converted for LSP (one record, three renderings: text,
JSON and this)."""

from __future__ import annotations

from collections.abc import Callable

from lsprotocol import types as lsp

from rssm_dsl.diagnostics import Diagnostic, Severity
from rssm_dsl.diagnostics.diagnostic import DOCS_URL
from rssm_dsl.lsp.positions import LineIndex
from rssm_dsl.source import Span

_SEVERITY = {
    Severity.ERROR: lsp.DiagnosticSeverity.Error,
    Severity.WARNING: lsp.DiagnosticSeverity.Warning,
    Severity.NOTE: lsp.DiagnosticSeverity.Information,
}
SOURCE = "rssmc"


def docs_url(code: str) -> str:
    return f"{DOCS_URL}#{code.lower()}"


def to_lsp(d: Diagnostic, lines: LineIndex, encoding: str,
           locate: Callable[[Span], lsp.Location | None]) -> lsp.Diagnostic:
    """`lines` is the text of the diagnostic's file; `locate` turns a related span (maybe in
    another file) into a location."""
    message = d.message if d.hint is None else f"{d.message}\nhelp: {d.hint}"
    related: list[lsp.DiagnosticRelatedInformation] = []
    for r in d.related:
        loc = locate(r.span)
        if loc is not None:
            related.append(lsp.DiagnosticRelatedInformation(location=loc, message=r.message))
    return lsp.Diagnostic(
        range=lines.range(d.span, encoding),
        message=message,
        severity=_SEVERITY[d.severity],
        code=d.code,
        code_description=lsp.CodeDescription(href=docs_url(d.code)),
        source=SOURCE,
        related_information=related or None,
        data={"name": d.slug},
    )
