"""Verifier tests: make the net kit importable in any pytest import mode; tool markers."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any, TypeVar

import pytest

sys.path.insert(0, os.path.dirname(__file__))

from rssm_dsl.verify.fourtitwo import find_rays
from rssm_dsl.verify.promela import find_tools


def _spin_missing() -> bool:
    spin, cc = find_tools()
    return spin is None or cc is None


F = TypeVar("F", bound=Callable[..., Any])

_skip_spin = pytest.mark.skipif(_spin_missing(), reason="spin or a C compiler not installed")
_skip_4ti2 = pytest.mark.skipif(find_rays() is None, reason="4ti2 (4ti2-rays) not installed")


def requires_spin(test: F) -> F:
    """Runs SPIN: marked ``external``, skipped only when spin or a C compiler is missing."""
    marked: F = pytest.mark.external(_skip_spin(test))
    return marked


def requires_4ti2(test: F) -> F:
    """Runs 4ti2: marked ``external``, skipped only when 4ti2-rays is missing."""
    marked: F = pytest.mark.external(_skip_4ti2(test))
    return marked
