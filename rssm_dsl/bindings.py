"""Resolve the Python side of a specification: `extern` operations and device classes.

A binding is written ``"pkg.module:attribute"``. Where the module is looked up:

* names under ``rssm_stdlib.`` come from the standard library folder
  (:func:`rssm_dsl.resources.stdlib_dir`), made importable as the package ``rssm_stdlib``
  without copying it (so ``stdlib/lwr4plus/ops.py`` is ``rssm_stdlib.lwr4plus.ops``);
* any other module is looked up in the folder of the specification first, then on
  ``sys.path`` like a normal import.

Failures are :class:`BindingError` (message and hint), turned into diagnostic E801 by the
caller, which knows the span of the declaration.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import sys
import threading
from pathlib import Path
from types import ModuleType

from rssm_dsl.extras import hint_for
from rssm_dsl.resources import stdlib_dir

STDLIB_PACKAGE = "rssm_stdlib"
_lock = threading.Lock()


class BindingError(Exception):
    def __init__(self, message: str, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint


def install_stdlib_package() -> ModuleType:
    """Make the stdlib folder importable as ``rssm_stdlib`` (idempotent)."""
    with _lock:
        existing = sys.modules.get(STDLIB_PACKAGE)
        if existing is not None:
            return existing
        folder = stdlib_dir()
        init = folder / "__init__.py"
        spec = importlib.util.spec_from_file_location(
            STDLIB_PACKAGE, init if init.is_file() else None,
            submodule_search_locations=[str(folder)],
        )
        if spec is None:  # pragma: no cover - spec_from_file_location always succeeds here
            raise BindingError(f"cannot make {folder} importable as {STDLIB_PACKAGE}")
        module = importlib.util.module_from_spec(spec)
        sys.modules[STDLIB_PACKAGE] = module
        if spec.loader is not None and init.is_file():
            spec.loader.exec_module(module)
        return module


def split_binding(binding: str) -> tuple[str, str]:
    module, sep, attr = binding.partition(":")
    if not sep or not module or not attr:
        raise BindingError(f'binding "{binding}" is not of the form module:attribute')
    return module, attr


def _import_top_from(folder: Path, top: str) -> None:
    """Import the top-level package or module ``top`` from ``folder`` if it is there."""
    if top in sys.modules:
        return
    spec = importlib.machinery.PathFinder.find_spec(top, [str(folder)])
    if spec is None or spec.loader is None:
        return
    module = importlib.util.module_from_spec(spec)
    sys.modules[top] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(top, None)
        raise


def import_module(name: str, base_dir: Path | None) -> ModuleType:
    """Import a module of a binding (see the module docstring for where it is looked up)."""
    top = name.split(".", 1)[0]
    try:
        if top == STDLIB_PACKAGE:
            install_stdlib_package()
        elif base_dir is not None:
            with _lock:
                _import_top_from(base_dir, top)
        return importlib.import_module(name)
    except ModuleNotFoundError as e:
        where = ("the standard library" if top == STDLIB_PACKAGE else
                 f"{base_dir} or sys.path" if base_dir is not None else "sys.path")
        missing = e.name or name
        if missing != name and not name.startswith(missing + ".") and missing != top:
            raise BindingError(f"module '{name}' needs '{missing}', which is not installed",
                               hint_for(missing) or
                               f"install the Python package that provides '{missing}'") from e
        raise BindingError(f"no module '{name}' in {where}",
                           "check the spelling; user modules live next to the .rssm file") from e
    except Exception as e:
        raise BindingError(f"importing '{name}' failed: {type(e).__name__}: {e}",
                           "fix the module so that it imports cleanly") from e


def resolve(binding: str, base_dir: Path | None) -> object:
    """The object a binding names: ``module:attribute`` (the attribute may be dotted)."""
    module_name, attr = split_binding(binding)
    obj: object = import_module(module_name, base_dir)
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise BindingError(f"module '{module_name}' has no attribute '{attr}'",
                               f"define {attr} in {module_name}")
        obj = getattr(obj, part)
    return obj
