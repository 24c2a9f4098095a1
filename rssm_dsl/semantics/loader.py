"""Read the root file and everything it imports (user files first, then the stdlib).

Besides reading, the loader reports what is wrong with a file as text rather than as RSSM:
the file itself (E001-E004), a line separator in a comment (W012), and the names that cannot
become the file names they give the outputs (E011, rssm_dsl/filenames.py). A lookup that
fails in any way (a path too long for the system, a NUL in it) is a module not found (E009).
:func:`read_source` is the one place a spec file is read (every command, the editor): a path
that cannot be read (a symbolic link loop, no permission), that is no regular file (a
folder, a FIFO, a device) or that is too large is a coded diagnostic, never an exception. A
quoted import of a file that is not a spec (no ``.rssm`` suffix: ``import "/etc/passwd"``)
is refused before it is read (E014), so nothing of it is shown.
"""

from __future__ import annotations

import errno
import os
import re
import stat
from dataclasses import field
from pathlib import Path

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import DiagnosticBag
from rssm_dsl.filenames import MAX_NAME_LENGTH, is_file, name_problem
from rssm_dsl.resources import stdlib_dir
from rssm_dsl.source import MAX_FILE_BYTES, SourceFile, Span, describe_char, file_kind
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.parser import parse

SPEC_SUFFIX = ".rssm"
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


def resolved(path: Path) -> Path:
    """``path.resolve()``, or the absolute path when it cannot be resolved: a symbolic link
    loop (``RuntimeError`` before Python 3.13, ``OSError`` after), a NUL in the path. Reading
    such a path is then reported by :func:`read_source` (E001)."""
    try:
        return path.resolve()
    except (OSError, RuntimeError, ValueError):
        return Path(os.path.abspath(path))


def display_path(path: Path) -> str:
    """How a file is named in spans: stdlib files as <stdlib>/..., others relative to the CWD."""
    full = resolved(path)
    try:
        return STDLIB_PREFIX + full.relative_to(stdlib_dir().resolve()).as_posix()
    except ValueError:
        pass
    try:
        rel = os.path.relpath(full)
    except ValueError:
        return full.as_posix()
    return Path(rel).as_posix() if not rel.startswith("../../..") else full.as_posix()


def read_source(
    path: Path, bag: DiagnosticBag, at: Span, overrides: dict[Path, str] | None = None,
) -> SourceFile | None:
    """Read one file as UTF-8 text; report E001-E004 at `at` instead of raising."""
    shown = display_path(path)
    if overrides:
        key = resolved(path)
        if key in overrides:
            return SourceFile(shown, overrides[key])
    try:
        info = path.stat()
    except (OSError, ValueError) as e:   # ValueError: a NUL in the path
        bag.error("E001", f"cannot read '{path}': {_lookup_failure(e)}", at,
                  "check the path; imports are looked up next to the importing file, then in the stdlib")
        return None
    if not stat.S_ISREG(info.st_mode):
        bag.error("E002", f"'{path}' is not a regular file{file_kind(info.st_mode)}", at,
                  "give the path of a .rssm file")
        return None
    try:
        size = info.st_size
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


def _lookup_failure(e: OSError | ValueError) -> str:
    if isinstance(e, ValueError) or e.errno in (errno.ENOENT, errno.ENOTDIR):
        return "no such file"
    if e.errno == errno.ENAMETOOLONG:
        return "the path is too long for the file system"
    if e.errno == errno.ELOOP:
        return "too many levels of symbolic links (a symbolic link loop?)"
    return e.strerror or str(e)


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
        key = resolved(path)
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
        check_line_separators(source, self.bag)
        module = result.module
        self._done[key] = module
        if module is None:
            return None
        check_file_names(module, self.bag)
        self._stack.append(key)
        imported: list[str] = []
        for imp in module.imports:
            target = self._find(imp, path)
            if target is None:
                continue
            tkey = resolved(target)
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

    def _find(self, imp: ast.Import, importer: Path) -> Path | None:
        """The file an import names, or None with the problem reported: no file (E009), or
        a quoted path that names a file that is not a spec (E014: it is never read, so
        nothing of it is shown, in the terminal or the editor).
        A path, quoted or dotted, that is there but is no regular file or cannot be looked
        up (a FIFO, a symbolic link loop, no permission) is returned: :func:`read_source`
        says why (E001, E002), the same for `import "fifo.rssm"` and `import fifo`."""
        candidates = _candidates(imp, importer)
        target = next((c for c in candidates if is_file(c)), None)
        if target is None:
            target = next((c for c in candidates if _exists(c)), None)
        if target is None:
            self.bag.error(
                "E009", f"cannot find module '{imp.path}'", imp.span,
                "modules are looked up next to this file, then in the stdlib "
                "(e.g. `import std.types`)",
            )
            return None
        if target.suffix != SPEC_SUFFIX:           # only a quoted path can name one
            self.bag.error("E014", f"'{imp.path}' is not an RSSM module: an import names a "
                           f"{SPEC_SUFFIX} file", imp.span,
                           f"import a specification file (name{SPEC_SUFFIX}) or a module "
                           "(`import std.types`); the file was not read")
            return None
        return target


def _exists(path: Path) -> bool:
    """Whether there is a directory entry at ``path`` (a broken or looping link counts)."""
    try:
        return os.path.lexists(path)
    except (OSError, ValueError):
        return False


# ---------------------------------------------------------------- W012: U+2028 in comments

LINE_SEPARATORS = "\u2028\u2029\x85"   # not line terminators in RSSM (rssm_dsl/source.py)
_LEXEME_START = re.compile(r'"|//|/\*')
_STRING = re.compile(r'"(?:[^"\\\n]|\\.)*"')      # the grammar's STRING


def line_separators_in_comments(text: str) -> tuple[int, int] | None:
    """(offset of the first, count) of the line separators (U+2028, U+2029, U+0085) inside
    ``//`` comments of ``text``, or None when there are none. Strings and block comments are
    skipped as the lexer skips them; linear in the length of the text."""
    if not any(c in text for c in LINE_SEPARATORS):
        return None
    first, count = -1, 0
    i, n = 0, len(text)
    while (m := _LEXEME_START.search(text, i)) is not None:
        at = m.start()
        if m.group() == '"':
            string = _STRING.match(text, at)
            if string is not None:
                i = string.end()
            else:                                  # an unclosed string skips its line (E006)
                end = text.find("\n", at)
                i = n if end < 0 else end
        elif m.group() == "/*":
            end = text.find("*/", at + 2)
            if end < 0:
                break                              # an unclosed `/*` runs to the end (E007)
            i = end + 2
        else:
            end = text.find("\n", at)
            end = n if end < 0 else end
            for c in LINE_SEPARATORS:
                k = text.find(c, at, end)
                if k >= 0:
                    first = k if first < 0 else min(first, k)
                    count += text.count(c, at, end)
            i = end
    return (first, count) if count else None


def check_line_separators(source: SourceFile, bag: DiagnosticBag) -> None:
    found = line_separators_in_comments(source.text)
    if found is None:
        return
    first, count = found
    others = f"; the comments of this file hold {count} such characters" if count > 1 else ""
    bag.warn("W012", f"{describe_char(source.text[first])} does not end a line in RSSM; the "
             f"comment runs on to the next line break{others}", source.span(first, first + 1),
             "use a line break (\\n) to end a line: U+2028, U+2029 and U+0085 are ordinary "
             "characters in RSSM")


# ---------------------------------------------------------------- E011: names of files

_NAMES_WHAT = {
    "system": "it names the output files (<system>.hpn.json, <system>.html, the ROS 2 "
              "packages <system>_<agent>)",
    "agent": "it names the ROS 2 package <system>_<agent> and its launch file",
    "subsystem": "it names the module of its ROS 2 node (node_<letter>_<subsystem>.py)",
    "device": "it names the module of its ROS 2 node (device_<letter>_<device>.py)",
    "record": "it names the ROS 2 message file <Record>.msg",
}


def _file_names(module: ast.Module) -> list[tuple[str, str, Span]]:
    """(kind, name, span of the name) of every name of ``module`` that becomes (part of) a
    file or directory name in some output."""
    out: list[tuple[str, str, Span]] = []
    for decl in module.decls:
        if isinstance(decl, ast.RecordDecl):
            out.append(("record", decl.name, decl.name_span))
        elif isinstance(decl, ast.SystemDecl):
            out.append(("system", decl.name, decl.name_span))
            for agent in decl.agents:
                out.append(("agent", agent.name, agent.name_span))
                out += [("subsystem", s.name, s.name_span) for s in agent.subsystems]
                out += [("device", d.name, d.name_span) for d in agent.devices]
            for inst in decl.instances:     # r1, ..., r8 of `agent r[1..8]: ...`: the last
                last = max(inst.hi or 0, -(inst.lo or 0))        # is the longest
                out.append(("agent", f"{inst.name}{last}" if inst.lo is not None
                            else inst.name, inst.name_span))
        elif isinstance(decl, ast.AgentDef):
            out += [("subsystem", s.name, s.name_span) for s in decl.subsystems]
            out += [("device", d.name, d.name_span) for d in decl.devices]
    return out


def check_file_names(module: ast.Module, bag: DiagnosticBag) -> None:
    for kind, name, span in _file_names(module):
        problem = name_problem(name)
        if problem is not None:
            bag.error("E011", f"the {kind} name '{name}' cannot become a file name: {problem}",
                      span, f"shorten the {kind} name to at most {MAX_NAME_LENGTH} characters; "
                      f"{_NAMES_WHAT[kind]}")
