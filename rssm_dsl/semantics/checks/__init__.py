"""Structural checks over the semantic model. Each is one module with one entry point;
the pipeline is the tuple CHECKS, run in order."""

from __future__ import annotations

from collections.abc import Callable

from rssm_dsl.semantics.checks.bindings import check_bindings
from rssm_dsl.semantics.checks.context import CheckContext
from rssm_dsl.semantics.checks.sending import check_default_sends
from rssm_dsl.semantics.checks.switching import check_switching
from rssm_dsl.semantics.checks.usage import check_usage

Check = Callable[[CheckContext], None]

CHECKS: tuple[Check, ...] = (check_switching, check_usage, check_default_sends, check_bindings)

__all__ = ["CHECKS", "Check", "CheckContext"]
