"""Resolve the Python side of a specification: `extern` operations and device classes.

A binding is written ``"pkg.module:attribute"``. Where the module is looked up:

* names under ``rssm_stdlib.`` come from the standard library folder
  (:func:`rssm_dsl.resources.stdlib_dir`), made importable as the package ``rssm_stdlib``
  without copying it (so ``stdlib/lwr4plus/ops.py`` is ``rssm_stdlib.lwr4plus.ops``);
* any other module is looked up in the folders given, in order (the folder of the file that
  declares the binding, then the root specification's: :func:`binding_dirs`), then on
  ``sys.path`` like a normal import. Regular and namespace packages both work.

:func:`find_module` and :func:`static_lookup` answer the same questions without running any
of the user's code (``rssmc check`` and the language server use them); :func:`resolve`
imports the module (``rssmc simulate`` and ``run``). Both read the calls an extern makes with
one rule, :func:`arity_problem`.

Failures are :class:`BindingError` (message and hint), turned into diagnostic E801 by the
caller, which knows the span of the declaration.
"""

from __future__ import annotations

import ast as pyast
import importlib
import importlib.machinery
import importlib.util
import inspect
import stat
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from types import ModuleType
from typing import Any

from rssm_core.records import dataclass
from rssm_dsl.extras import hint_for
from rssm_dsl.resources import stdlib_dir

STDLIB_PACKAGE = "rssm_stdlib"
_lock = threading.Lock()


class BindingError(Exception):
    def __init__(self, message: str, hint: str | None = None) -> None:
        super().__init__(message)
        self.message = message
        self.hint = hint


class ModuleMissing(BindingError):
    """The module of a binding is not where it is looked up (it may be installed where the
    system runs, not here)."""


class ModuleUnreadable(BindingError):
    """The source of a binding's module is too large or too deeply nested for the checker
    to read (:func:`static_lookup`): what it defines is not checked."""


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


def _dotted(name: str) -> bool:
    """``name`` is a dotted Python name (``pkg.module``): nothing a path could be made of
    (``/``, ``..``, a drive), so that it is looked up only as a module."""
    return all(part.isidentifier() for part in name.split("."))


def split_binding(binding: str) -> tuple[str, str]:
    """The module and the attribute of ``module:attribute``, each a dotted Python name; a
    BindingError otherwise (E208 where the binding is declared)."""
    module, sep, attr = binding.partition(":")
    if not sep or not module or not attr:
        raise BindingError(f'binding "{binding}" is not of the form module:attribute')
    if not _dotted(module) or not _dotted(attr):
        raise BindingError(f'binding "{binding}" is not of the form module:attribute: '
                           f'{"the module" if not _dotted(module) else "the attribute"} is not '
                           "a dotted Python name",
                           "write the module as Python imports it (pkg.module), not as a path")
    return module, attr


def _import_top_from(folder: Path, top: str) -> bool:
    """Import the top-level package or module ``top`` from ``folder`` if it is there (a
    namespace package too); whether it is imported now."""
    if top in sys.modules:
        return True
    try:
        spec = importlib.machinery.PathFinder.find_spec(top, [str(folder)])
    except (OSError, ValueError):        # a name too long for the file system: not there
        return False
    if spec is None:
        return False
    module = importlib.util.module_from_spec(spec)
    sys.modules[top] = module
    if spec.loader is None:        # a namespace package: its folders are its __path__
        return True
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(top, None)
        raise
    return True


def _where(top: str, dirs: Sequence[Path]) -> str:
    if top == STDLIB_PACKAGE:
        return "the standard library"
    return ", ".join(str(d) for d in dirs) + " or sys.path" if dirs else "sys.path"


def _not_found(name: str, dirs: Sequence[Path]) -> ModuleMissing:
    return ModuleMissing(f"no module '{name}' in {_where(name.split('.', 1)[0], dirs)}",
                        "check the spelling; user modules live next to the .rssm file that "
                        "declares the binding")


def import_module(name: str, dirs: Sequence[Path]) -> ModuleType:
    """Import a module of a binding (see the module docstring for where it is looked up)."""
    if not _dotted(name):
        raise BindingError(f"'{name}' is not a dotted Python module name",
                           "write the module as Python imports it (pkg.module), not as a path")
    top = name.split(".", 1)[0]
    try:
        if top == STDLIB_PACKAGE:
            install_stdlib_package()
        else:
            with _lock:
                for folder in dirs:
                    if _import_top_from(folder, top):
                        break
        return importlib.import_module(name)
    except ModuleNotFoundError as e:
        missing = e.name or name
        if missing != name and not name.startswith(missing + ".") and missing != top:
            raise BindingError(f"module '{name}' needs '{missing}', which is not installed",
                               hint_for(missing) or
                               f"install the Python package that provides '{missing}'") from e
        raise _not_found(name, dirs) from e
    except (Exception, SystemExit) as e:     # sys.exit() at import time too
        raise BindingError(f"importing '{name}' failed: {type(e).__name__}: {e}",
                           "fix the module so that it imports cleanly") from e


def resolve(binding: str, dirs: Sequence[Path]) -> object:
    """The object a binding names: ``module:attribute`` (the attribute may be dotted)."""
    module_name, attr = split_binding(binding)
    obj: object = import_module(module_name, dirs)
    for part in attr.split("."):
        if not hasattr(obj, part):
            raise _no_attribute(module_name, attr)
        obj = getattr(obj, part)
    return obj


def _no_attribute(module: str, attr: str) -> BindingError:
    return BindingError(f"module '{module}' has no attribute '{attr}'",
                        f"define {attr} in {module}")


def arity_problem(signature: inspect.Signature, arity: int) -> str | None:
    """Why a callable of this signature cannot take ``arity`` positional arguments, or None."""
    try:
        signature.bind(*range(arity))
    except TypeError as e:
        return str(e)
    return None


def callable_arity_problem(fn: Callable[..., Any], arity: int) -> str | None:
    """:func:`arity_problem` of a Python callable (None when it has no signature to read)."""
    try:
        signature = inspect.signature(fn)
    except (TypeError, ValueError):
        return None
    return arity_problem(signature, arity)


# ------------------------------------------------------------------ without running code
def binding_dirs(declared_in: str | None, root_dir: Path | None) -> list[Path]:
    """Where the modules of a binding are looked up before sys.path: the folder of the file
    that declares it (``declared_in``: the file as spans name it), then the root
    specification's folder. The standard library's bindings name ``rssm_stdlib``."""
    from rssm_dsl.semantics.loader import STDLIB_PREFIX

    out: list[Path] = []
    if declared_in is not None and not declared_in.startswith(STDLIB_PREFIX):
        out.append(Path(declared_in).parent)
    if root_dir is not None and root_dir not in out:
        out.append(root_dir)
    return out


@dataclass(frozen=True)
class ModuleSource:
    """Where a binding's module is, found without running anything."""

    name: str
    folder: Path | None    # the folder its top-level package or module is in (None: sys.path)
    file: Path | None      # its Python source; None for a namespace package or compiled code


def _lookup(part: str, dirs: Sequence[Path]) -> tuple[Path | None, list[Path]] | None:
    """``part`` in ``dirs`` as Python's path finder sees it: (its source file, the folders of
    the package it is), or None. A package beats a module; folders without ``__init__.py``
    together make a namespace package."""
    portions: list[Path] = []
    for d in dirs:
        package = d / part
        try:
            if (package / "__init__.py").is_file():
                return package / "__init__.py", [package]
            if (d / f"{part}.py").is_file():
                return d / f"{part}.py", []
            if any(d.glob(f"{part}.*.so")) or any(d.glob(f"{part}.*.pyd")):
                return None, []
            if package.is_dir():
                portions.append(package)
        except (OSError, ValueError, NotImplementedError):   # a name too long for the file
            continue                                       # system, or not a name: not there
    return (None, portions) if portions else None


def find_module(name: str, dirs: Sequence[Path]) -> ModuleSource:
    """The module of a binding, found as :func:`import_module` finds it, without importing
    it (nor its parent packages)."""
    if not _dotted(name):
        raise BindingError(f"'{name}' is not a dotted Python module name",
                           "write the module as Python imports it (pkg.module), not as a path")
    parts = name.split(".")
    top = parts[0]
    folder: Path | None = None
    hit: tuple[Path | None, list[Path]] | None
    if top == STDLIB_PACKAGE:
        hit = (None, [stdlib_dir()])
    else:
        hit = None
        for d in dirs:
            hit = _lookup(top, [d])
            if hit is not None:
                folder = d
                break
        if hit is None:
            try:
                spec = importlib.util.find_spec(top)
            except (ImportError, ValueError, OSError):
                spec = None
            if spec is None:
                raise _not_found(name, dirs)
            origin = spec.origin if spec.has_location else None
            hit = (Path(origin) if origin and origin.endswith(".py") else None,
                   [Path(p) for p in spec.submodule_search_locations or ()])
    for i, part in enumerate(parts[1:], 1):
        if not hit[1]:
            raise BindingError(f"'{'.'.join(parts[:i])}' is a module, not a package: no "
                               f"module '{name}'", "check the spelling of the module path")
        hit = _lookup(part, hit[1])
        if hit is None:
            raise _not_found(name, dirs)
    return ModuleSource(name, folder, hit[0])


@dataclass(frozen=True)
class Definition:
    """What a module's source defines under a name."""

    kind: str                              # function | class | other
    signature: inspect.Signature | None    # of a function, when its source gives it


def static_lookup(binding: str, dirs: Sequence[Path]) -> Definition | None:
    """What ``module:attribute`` names, read from the module's source without running it;
    None when the source cannot tell (compiled code, a name made at import time). Raises
    BindingError when the module is not found or certainly lacks the name."""
    module_name, attr = split_binding(binding)
    src = find_module(module_name, dirs)
    if src.file is None:
        return None
    names = _definitions(src.file)
    if names is None:
        return None
    first = attr.split(".", 1)[0]
    if first not in names:
        if _OPEN in names:                 # `from x import *` or a module __getattr__
            return None
        raise _no_attribute(module_name, attr)
    found = names[first]
    return found if first == attr else None


_OPEN = "*"                # the source may define names it does not spell out
# file -> (its size and time when read, what it defines or why it cannot be read): one entry
# per file, renewed when the file changes (the language server checks again at every edit)
_parsed: dict[Path, tuple[tuple[int, int], dict[str, Definition] | ModuleUnreadable]] = {}

# What the checker reads of a module's source: Python's syntax tree takes some 600 bytes per
# token, so a module is read when it is at most MAX_MODULE_BYTES long and has at most
# MAX_MODULE_TOKENS tokens (150 MB of tree at most, a second or so); nested deeper than the
# parser's recursion limit, it is not read either.
MAX_MODULE_BYTES = 4 << 20
MAX_MODULE_TOKENS = 250_000


def _definitions(file: Path) -> dict[str, Definition] | None:
    """The top-level names a Python source defines (None when it cannot tell: the file
    cannot be opened, or is not valid Python). ModuleUnreadable when it is too large or too
    deeply nested to read."""
    try:
        st = file.stat()
        stamp = (st.st_size, st.st_mtime_ns)
        cached = _parsed.get(file)
        if cached is None or cached[0] != stamp:
            if not stat.S_ISREG(st.st_mode):
                return None
            cached = _parsed[file] = (stamp, _read_definitions(file, st.st_size))
    except (OSError, SyntaxError, ValueError):
        return None
    if isinstance(cached[1], ModuleUnreadable):     # a new one: a raised one keeps frames
        raise ModuleUnreadable(cached[1].message, cached[1].hint)
    return cached[1]


def _unreadable(file: Path, why: str) -> ModuleUnreadable:
    return ModuleUnreadable(f"the Python module {file} is {why}: what it defines is not checked",
                            "split the module, or compute the large value at run time "
                            "(read it from a data file) instead of writing it out as one "
                            "expression")


def _read_definitions(file: Path, size: int) -> dict[str, Definition] | ModuleUnreadable:
    if size > MAX_MODULE_BYTES:
        return _unreadable(file, f"too large to read ({size:,} bytes; at most "
                                 f"{MAX_MODULE_BYTES:,})")
    with file.open("rb") as f:
        source = f.read(MAX_MODULE_BYTES + 1)
    if len(source) > MAX_MODULE_BYTES:
        return _unreadable(file, f"too large to read (over {MAX_MODULE_BYTES:,} bytes)")
    # a token takes at least one byte but for the dedents, one per indented line at most
    if len(source) > MAX_MODULE_TOKENS // 2 and _too_many_tokens(source):
        return _unreadable(file, f"too large to read (over {MAX_MODULE_TOKENS:,} tokens)")
    try:
        tree = pyast.parse(source, str(file))
    except RecursionError:
        return _unreadable(file, "too deeply nested to read (an expression or statement "
                                 "nested deeper than Python's parser goes)")
    except MemoryError:
        return _unreadable(file, "too large or too complex to read (Python's parser gave up)")
    try:
        return _top_level(tree.body)
    except RecursionError:      # blocks nested past the recursion limit
        return _unreadable(file, "too deeply nested to read")


def _too_many_tokens(source: bytes) -> bool:
    """Whether ``source`` has more than MAX_MODULE_TOKENS tokens, read as a stream (what
    the tokenizer cannot read is left to the parser)."""
    import io
    import tokenize

    count = 0
    try:
        for _ in tokenize.tokenize(io.BytesIO(source).readline):
            count += 1
            if count > MAX_MODULE_TOKENS:
                return True
    except (tokenize.TokenError, SyntaxError, ValueError):
        return False
    return False


def _top_level(body: list[pyast.stmt]) -> dict[str, Definition]:
    out: dict[str, Definition] = {}
    other = Definition("other", None)
    for node in body:
        if isinstance(node, pyast.FunctionDef | pyast.AsyncFunctionDef):
            out[node.name] = Definition("function", _signature(node.args))
            if node.name == "__getattr__":
                out[_OPEN] = other
        elif isinstance(node, pyast.ClassDef):
            out[node.name] = Definition("class", None)
        elif isinstance(node, pyast.Assign | pyast.AnnAssign | pyast.AugAssign):
            targets = node.targets if isinstance(node, pyast.Assign) else [node.target]
            for t in targets:
                for n in pyast.walk(t):
                    if isinstance(n, pyast.Name):
                        out[n.id] = other
        elif isinstance(node, pyast.Import | pyast.ImportFrom):
            for alias in node.names:
                out[_OPEN if alias.name == "*" else
                    (alias.asname or alias.name).split(".", 1)[0]] = other
        elif isinstance(node, pyast.If | pyast.Try | pyast.With | pyast.For | pyast.While):
            inner = [*node.body, *getattr(node, "orelse", []), *getattr(node, "finalbody", [])]
            for handler in getattr(node, "handlers", []):
                inner += handler.body
            for name, d in _top_level(inner).items():
                out.setdefault(name, d)
        elif not isinstance(node, pyast.Expr | pyast.Pass):
            out[_OPEN] = other             # e.g. globals() written to: cannot tell
    return out


def _signature(args: pyast.arguments) -> inspect.Signature:
    """The signature a `def` declares (defaults stand in as 0: only their presence counts)."""
    P = inspect.Parameter
    positional = [*args.posonlyargs, *args.args]
    first_default = len(positional) - len(args.defaults)
    params = [P(a.arg, P.POSITIONAL_ONLY if i < len(args.posonlyargs) else
                P.POSITIONAL_OR_KEYWORD, default=0 if i >= first_default else P.empty)
              for i, a in enumerate(positional)]
    if args.vararg is not None:
        params.append(P(args.vararg.arg, P.VAR_POSITIONAL))
    params += [P(a.arg, P.KEYWORD_ONLY, default=P.empty if d is None else 0)
               for a, d in zip(args.kwonlyargs, args.kw_defaults, strict=True)]
    if args.kwarg is not None:
        params.append(P(args.kwarg.arg, P.VAR_KEYWORD))
    return inspect.Signature(params)
