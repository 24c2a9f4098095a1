"""The one module that knows where the grammar and the standard library live.

In a source checkout (or an editable install) they are the top-level `grammar/` and
`stdlib/` folders; in a wheel they are packaged as `rssm_dsl/_data/grammar` and
`rssm_dsl/_data/stdlib` (see pyproject.toml).
"""

from __future__ import annotations

from functools import cache
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def _find(name: str) -> Path:
    for candidate in (_PACKAGE / "_data" / name, _PACKAGE.parent / name):
        if candidate.is_dir():
            return candidate
    raise FileNotFoundError(f"rssm_dsl is installed without its {name}/ folder")


@cache
def grammar_dir() -> Path:
    return _find("grammar")


@cache
def stdlib_dir() -> Path:
    return _find("stdlib")


def grammar_text() -> str:
    return (grammar_dir() / "rssm.lark").read_text(encoding="utf-8")
