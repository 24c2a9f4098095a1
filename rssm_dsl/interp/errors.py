"""Errors raised while the interpreter runs: each carries the diagnostic to report."""

from __future__ import annotations

from rssm_dsl.diagnostics import Diagnostic, Related
from rssm_dsl.source import Span


class EvalError(Exception):
    """An operation failed (E802), returned a value of the wrong type (E803), or another
    run-time problem with a span in the specification."""

    def __init__(self, code: str, message: str, span: Span, hint: str | None = None,
                 related: tuple[Related, ...] = ()) -> None:
        super().__init__(message)
        self.code = code
        self.message = message
        self.span = span
        self.hint = hint
        self.related = related

    def diagnostic(self) -> Diagnostic:
        return Diagnostic(self.code, self.message, self.span, self.hint, self.related)


class StopSimulation(BaseException):
    """Raised by a device or an observer of one to end the run, with the reason and message
    the run's result and the trace's `end` event carry: a clean end (the run is ok, `rssmc
    simulate` exits 0), or with ``failed=True`` a failure the device detected (exit 1). It
    derives from BaseException so that the error handling of operations (E802) never
    mistakes it for an error of the operation."""

    def __init__(self, reason: str, message: str, failed: bool = False) -> None:
        super().__init__(message)
        self.reason = reason
        self.message = message
        self.failed = failed


class SetupError(Exception):
    """The simulation cannot start: the diagnostics say why (bindings, devices, options)."""

    def __init__(self, diagnostics: list[Diagnostic]) -> None:
        super().__init__("; ".join(d.message for d in diagnostics))
        self.diagnostics = diagnostics
