"""Shared fixtures. `--update-goldens` rewrites golden files (refused in CI)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
# A limit that binds ends a run long before it would end without one; a test checks that, never
# that it ends within a second or two of the limit, which a loaded machine can miss.
FAR_EARLIER = 60.0


def sigint_default() -> None:
    """``preexec_fn`` of a child a test stops with Ctrl-C (SIGINT): a shell's background job
    (``pytest &``, a CI runner) ignores SIGINT and its children inherit that, so the child
    would never see the signal; reset to the default, Python turns it into KeyboardInterrupt."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


LONG = "RSSM_LONG_TESTS"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Cases marked ``long`` (over a minute each, with a faster variant that always runs)
    run only with RSSM_LONG_TESTS=1, so that CI's whole suite stays under 20 minutes."""
    if os.environ.get(LONG):
        return
    skip = pytest.mark.skip(reason=f"a long case (its fast variant runs); {LONG}=1 runs it")
    for item in items:
        if "long" in item.keywords:
            item.add_marker(skip)


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--update-goldens", action="store_true", default=False,
                     help="rewrite golden files from the current output (never in CI)")


@pytest.fixture
def update_goldens(request: pytest.FixtureRequest) -> bool:
    flag = bool(request.config.getoption("--update-goldens"))
    if flag and os.environ.get("CI"):
        pytest.fail("--update-goldens is not allowed in CI")
    return flag


# examples/verify/ systems written the way engineers write them, and examples/ with two robots
# talking: beyond full exploration (the sliced verifier decides them,
# tests/verify/test_slicing.py)
REALISTIC = frozenset({"handover_buggy", "handover", "rover", "palletizer", "panda_handover"})


def example_specs() -> list[Path]:
    """Every example system (examples/diagnostics/ holds specs with expected errors)."""
    return sorted(p for p in EXAMPLES.rglob("*.rssm") if "diagnostics" not in p.parts)
