"""Diagnostics: one record rendered as text, JSON and LSP."""

from rssm_dsl.diagnostics.codes import BY_CODE, CODES, Code, Severity
from rssm_dsl.diagnostics.diagnostic import Diagnostic, DiagnosticBag, Related

__all__ = ["BY_CODE", "CODES", "Code", "Diagnostic", "DiagnosticBag", "Related", "Severity"]
