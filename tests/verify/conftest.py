"""Verifier tests: make the net kit importable in any pytest import mode; tool markers."""

from __future__ import annotations

import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(__file__))

from rssm_dsl.verify.fourtitwo import find_rays
from rssm_dsl.verify.promela import find_tools


def _spin_missing() -> bool:
    spin, cc = find_tools()
    return spin is None or cc is None


requires_spin = pytest.mark.skipif(_spin_missing(), reason="spin or a C compiler not installed")
requires_4ti2 = pytest.mark.skipif(find_rays() is None, reason="4ti2 (4ti2-rays) not installed")
