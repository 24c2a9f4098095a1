"""The optional dependencies, the extra of ``pyproject.toml`` that installs each, and the
one-line message a command prints when one is missing (instead of a traceback).

The core install (``pip install rssmc``) checks, compiles, verifies, formats, renders and
serves the language server. ``[run]`` adds MuJoCo, Pinocchio and matplotlib for ``rssmc run``
and the LWR4+ devices; ``[video]`` adds PyAV for MP4 output.
"""

from __future__ import annotations

import importlib.util

# top-level module -> the extra that installs it
EXTRA_OF: dict[str, str] = {
    "mujoco": "run",
    "pinocchio": "run",
    "matplotlib": "run",
    "av": "video",
}
MODULES_OF: dict[str, tuple[str, ...]] = {}
for _module, _extra in EXTRA_OF.items():
    MODULES_OF[_extra] = (*MODULES_OF.get(_extra, ()), _module)


def install_command(extra: str) -> str:
    return f"pip install 'rssmc[{extra}]' (in a checkout: pip install -e '.[{extra}]')"


def hint_for(module: str) -> str | None:
    """What to type when ``module`` (or a submodule of it) is missing; None when no extra
    provides it."""
    extra = EXTRA_OF.get(module.split(".", 1)[0])
    return None if extra is None else install_command(extra)


def missing(extra: str) -> list[str]:
    """The modules of ``extra`` that are not installed (found without importing them)."""
    return [m for m in MODULES_OF[extra] if importlib.util.find_spec(m) is None]


def missing_message(what: str, extra: str) -> str | None:
    """One line for a command that needs ``extra``, or None when it is installed."""
    absent = missing(extra)
    if not absent:
        return None
    return (f"rssmc: {what} needs the '{extra}' extra ({', '.join(absent)} not installed): "
            f"{install_command(extra)}")
