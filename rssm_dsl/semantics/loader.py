"""Read the root file and everything it imports (user files first, then the stdlib)."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.resources import stdlib_dir
from rssm_dsl.source import SourceFile, Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.parser import parse

MAX_FILE_BYTES = 8 * 1024 * 1024
STDLIB_PREFIX = "<stdlib>/"


@dataclass
class Program:
    root: ast.Module | None
    modules: list[ast.Module] = field(default_factory=list)  # dependencies before dependents
    sources: dict[str, SourceFile] = field(default_factory=dict)  # by display path
    imports: dict[str, list[str]] = field(default_factory=dict)  # display path -> imported paths

    def line(self, file: str, line: int) -> str:
        src = self.sources.get(file)
        return src.line_text(line) if src else ""


def display_path(path: Path) -> str:
    """How a file is named in spans: stdlib files as <stdlib>/..., others relative to the CWD."""
    resolved = path.resolve()
    try:
        return STDLIB_PREFIX + resolved.relative_to(stdlib_dir().resolve()).as_posix()
    except ValueError:
        pass
    try:
        rel = os.path.relpath(resolved)
    except ValueError:
        return resolved.as_posix()
    return Path(rel).as_posix() if not rel.startswith("../../..") else resolved.as_posix()


def read_source(
    path: Path, bag: DiagnosticBag, at: Span, overrides: dict[Path, str] | None = None,
) -> SourceFile | None:
    """Read one file as UTF-8 text; report E001-E004 at `at` instead of raising."""
    shown = display_path(path)
    if overrides and path.resolve() in overrides:
        return SourceFile(shown, overrides[path.resolve()])
    if not path.exists():
        bag.error("E001", f"cannot read '{path}': no such file", at,
                  "check the path; imports are looked up next to the importing file, then in the stdlib")
        return None
    if not path.is_file():
        bag.error("E002", f"'{path}' is not a regular file", at, "give the path of a .rssm file")
        return None
    try:
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            bag.error("E004", f"'{path}' is {size / 1e6:.1f} MB; the limit is "
                      f"{MAX_FILE_BYTES / 1e6:.1f} MB", at, "split the specification into imported files")
            return None
        data = path.read_bytes()
    except OSError as e:
        bag.error("E001", f"cannot read '{path}': {e.strerror or e}", at)
        return None
    if b"\x00" in data:
        bag.error("E003", f"'{path}' is a binary file, not RSSM text", at)
        return None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        bag.error("E003", f"'{path}' is not UTF-8 text (byte {e.start})", at,
                  "save the file as UTF-8")
        return None
    return SourceFile(shown, text.removeprefix("\ufeff"))


def _candidates(imp: ast.Import, importer: Path) -> list[Path]:
    bases = [importer.parent, stdlib_dir()]
    if imp.quoted:
        return [importer.parent / imp.path]
    parts = imp.path.split(".")
    rel = Path(*parts)
    out: list[Path] = []
    for base in bases:
        out.append(base / rel.with_suffix(".rssm"))
        out.append(base / rel / f"{parts[-1]}.rssm")
    return out


class Loader:
    def __init__(self, bag: DiagnosticBag, overrides: dict[Path, str] | None = None) -> None:
        self.bag = bag
        self.overrides = overrides
        self.program = Program(root=None)
        self._done: dict[Path, ast.Module | None] = {}
        self._stack: list[Path] = []

    def load_root(self, path: Path, at: Span) -> Program:
        self.program.root = self._load(path, at)
        return self.program

    def _load(self, path: Path, at: Span) -> ast.Module | None:
        key = path.resolve()
        if key in self._done:
            return self._done[key]
        source = read_source(path, self.bag, at, self.overrides)
        if source is None:
            self._done[key] = None
            return None
        self.program.sources[source.path] = source
        result = parse(source)
        for d in result.diagnostics:
            self.bag.add(d)
        module = result.module
        self._done[key] = module
        if module is None:
            return None
        self._stack.append(key)
        imported: list[str] = []
        for imp in module.imports:
            target = next((c for c in _candidates(imp, path) if c.is_file()), None)
            if target is None:
                self.bag.error(
                    "E009", f"cannot find module '{imp.path}'", imp.span,
                    "modules are looked up next to this file, then in the stdlib "
                    "(e.g. `import std.types`)",
                )
                continue
            tkey = target.resolve()
            if tkey in self._stack:
                cycle = [*self._stack[self._stack.index(tkey):], tkey]
                names = " -> ".join(display_path(p) for p in cycle)
                self.bag.error("E010", f"import cycle: {names}", imp.span,
                               "move the shared declarations into a module both can import")
                continue
            self._load(target, imp.span)
            imported.append(display_path(target))
        self._stack.pop()
        self.program.imports[source.path] = imported
        self.program.modules.append(module)
        return module
