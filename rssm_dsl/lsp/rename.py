"""Rename: the edits that rename a declaration and every use of it, in every file of the
program, and the checks that refuse a new name that would change what the specification
means.

A rename is refused (RenameRefused, with a message that names the clash) when:

- the new name is already declared in the same scope (another field of the record, another
  variable of the subsystem, another behaviour, agent, global...), or is reserved there
  (`end` for a behaviour, the letters of peer names for an agent, the built-in types);
- after the rename some name would refer to another declaration than before: a use of the
  renamed declaration captured by another one that hides it, or a use of another
  declaration captured by the renamed one (found by indexing the renamed program);
- the renamed program would check worse than before (a diagnostic it did not have, e.g. two
  buffers that paired because they had the same name).
"""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Callable, Iterable
from pathlib import Path

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic, DiagnosticBag
from rssm_dsl.lsp.index import BUILTIN_NAMES, Definition, Occurrence, SymbolIndex, build_index
from rssm_dsl.lsp.paths import is_stdlib, path_of_display
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.analyze import analyze
from rssm_dsl.semantics.loader import Program, display_path
from rssm_dsl.semantics.types import SCALARS
from rssm_dsl.syntax.format import keywords

_NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_VARIABLES = ("buf:", "mem:", "param:")
_DEVICE_MEMBERS = ("devbuf:", "devparam:")
_GLOBALS = ("type:", "const:", "extern:", "device:")
_PEER_LETTERS = ("c", "e", "r", "E", "R")
REQUEST_FAILED = -32803     # LSP: a request that is valid but could not be carried out

# display path -> (start, end, new text), code-point offsets in the file's text
FileEdits = dict[str, list[tuple[int, int, str]]]


class RenameRefused(Exception):
    """A rename that would give a specification that means something else, or checks worse;
    the message says why."""


def bad_name(new: str) -> str | None:
    """Why `new` cannot be declared at all (None: it can)."""
    if not _NAME_RE.match(new) or new in keywords() or new in BUILTIN_NAMES:
        return (f"'{new}' is not a name that can be declared "
                "(a keyword, a built-in, or not a name)")
    return None


def target(index: SymbolIndex, file: str, offset: int
           ) -> tuple[Occurrence, Definition] | None:
    """The renameable name at an offset of a file: its occurrence and declaration."""
    occ = index.at(file, offset)
    if occ is None:
        return None
    d = index.definitions.get(occ.key)
    if d is None or not d.renameable or is_stdlib(d.span.file):
        return None
    return occ, d


def where(file: str, line: int) -> str:
    return f"{file}:{line}"


def _refusal(d: Definition, new: str, why: str) -> str:
    return f"cannot rename {d.kind} '{d.name}' to '{new}': {why}"


def _scope_name(index: SymbolIndex, key: str) -> str:
    """How a message names the declaration whose members share a namespace: `record Pose`,
    `subsystem a1.e.lwr`, `behaviour a1.c.cw`..."""
    kind, _, rest = key.partition(":")
    rest = rest.split("|", 1)[-1].split("/", 1)[-1]   # past the system's file and name
    if kind == "type":
        d = index.definitions.get(key)
        return f"{d.kind if d is not None else 'type'} {rest}"
    return {"sub": f"subsystem {rest}", "beh": f"behaviour {rest}",
            "device": f"device type {rest}", "system": f"system {rest}",
            "agent": f"agent {rest}"}.get(kind, rest)


def clash(index: SymbolIndex, d: Definition, new: str) -> str | None:
    """Why `new` cannot be the new name of `d` in its scope (None: nothing declared there has
    that name). What a name would hide elsewhere is found by `verify`."""
    if new == d.name:
        return None
    prefix = d.key.split(":", 1)[0] + ":"
    siblings: tuple[str, ...]
    containers: set[str | None] = {d.container}
    reserved: str | None = None
    if prefix in _VARIABLES:
        siblings = _VARIABLES
    elif prefix in _DEVICE_MEMBERS:
        siblings = _DEVICE_MEMBERS
    elif prefix in _GLOBALS:
        siblings = _GLOBALS
        if new in SCALARS:
            reserved = f"'{new}' is a built-in type"
    elif prefix == "cond:":
        # a condition may not have the name of a variable of its subsystem
        siblings = ("cond:", *_VARIABLES)
        owner = index.definitions.get(d.container or "")
        containers.add(owner.container if owner is not None else None)
    elif prefix == "local:":
        # a local value may not hide a variable of its subsystem, a constant or an enum
        siblings = ("local:", *_VARIABLES, "const:", "type:")
        owner = index.definitions.get(d.container or "")
        containers |= {owner.container if owner is not None else None, None}
    else:
        siblings = (prefix,)
        if prefix == "beh:" and new == "end":
            reserved = "'end' names the end of the subsystem in a switch"
        if prefix == "agent:" and new in _PEER_LETTERS:
            reserved = (f"'{new}' would read as a subsystem letter in peer names "
                        "(c, e.NAME, r.NAME, E.NAME, R.NAME)")
    if reserved is not None:
        return _refusal(d, new, reserved)
    for other in index.definitions.values():
        if other.name != new or other.key == d.key or not other.key.startswith(siblings):
            continue
        if prefix in _GLOBALS or other.container in containers:
            if prefix == "local:" and other.key.startswith("local:") \
                    and other.container != d.container:
                continue    # a local value of another behaviour
            scope = "" if other.container is None else \
                f" in {_scope_name(index, other.container)}"
            return _refusal(d, new, f"{other.kind} '{new}' is already declared{scope} "
                            f"({where(other.span.file, other.span.line)})")
    return None


def same_declaration(index: SymbolIndex, d: Definition) -> bool:
    """Does `index` (maybe of another program of the workspace) know the declaration of `d`
    under its key? The keys of records, constants, devices... are their names: two programs
    may declare unrelated records of the same name, in different files."""
    other = index.definitions.get(d.key)
    return other is not None and other.span.file == d.span.file


def file_edits(occurrences: Iterable[Occurrence], new: str) -> FileEdits:
    """The edits that write `new` over the occurrences (those in the standard library left
    alone), by file, without duplicates, in order."""
    out: dict[str, set[tuple[int, int, str]]] = {}
    for o in occurrences:
        if not is_stdlib(o.span.file):
            out.setdefault(o.span.file, set()).add((o.span.offset, o.span.end_offset, new))
    return {f: sorted(edits) for f, edits in out.items()}


def apply_edits(text: str, edits: list[tuple[int, int, str]]) -> str:
    for start, end, new in sorted(edits, reverse=True):
        text = text[:start] + new + text[end:]
    return text


def _shift(edits: list[tuple[int, int, str]], offset: int) -> int:
    """Where `offset` of the text is after the edits (which replace names: an edit that
    starts at `offset` does not move it, one that ends there does)."""
    delta = 0
    for start, end, new in edits:
        if end <= offset:
            delta += len(new) - (end - start)
    return offset + delta


@dataclass
class Checked:
    """A program as the language server sees it: its diagnostics (semantic ones too when it
    has syntax errors) and its symbol index."""

    program: Program
    diagnostics: tuple[Diagnostic, ...]
    index: SymbolIndex


def check_program(path: Path, overrides: dict[Path, str]) -> Checked:
    comp = compile_file(path, overrides, build=False)
    diagnostics = comp.diagnostics
    if comp.system is None and comp.program.root is not None:
        # the loader's errors stop the compiler before the semantic passes (the editor
        # runs them all the same on the partial module)
        bag = DiagnosticBag()
        try:
            analyze(comp.program, bag)
        except Exception:   # a partial module the passes cannot take: its syntax errors say it
            bag = DiagnosticBag()
        known = set(diagnostics)
        diagnostics = diagnostics + tuple(x for x in bag.sorted() if x not in known)
    return Checked(comp.program, diagnostics, build_index(comp.program))


_Resolution = dict[tuple[str, int, int], set[tuple[str, int]]]


def _resolution(index: SymbolIndex) -> tuple[_Resolution, dict[tuple[str, int], Definition]]:
    """What each occurrence refers to: (file, start, end) -> {(file, offset) of the name of
    its declaration}; and the declarations by that position."""
    out: _Resolution = {}
    defs: dict[tuple[str, int], Definition] = {}
    for file, occs in index.occurrences.items():
        for o in occs:
            d = index.definitions.get(o.key)
            if d is None:
                continue
            at = (d.span.file, d.span.offset)
            defs.setdefault(at, d)
            out.setdefault((file, o.span.offset, o.span.end_offset), set()).add(at)
    return out, defs


def _described(d: Definition | None) -> str:
    if d is None:
        return "nothing"
    return f"{d.kind} '{d.name}' ({where(d.span.file, d.span.line)})"


def _same_resolution(d: Definition, new: str, before: Checked, after: Checked,
                     edits: FileEdits) -> None:
    """Raise RenameRefused if some occurrence refers to another declaration after the
    rename (a use that became unresolved, or is captured by another declaration)."""
    old_refs, old_defs = _resolution(before.index)
    new_refs, new_defs = _resolution(after.index)

    def moved(file: str, offset: int) -> int:
        return _shift(edits.get(file, []), offset)

    renamed_at = (d.span.file, moved(d.span.file, d.span.offset))
    for (file, start, end), targets in sorted(old_refs.items()):
        if file not in after.program.sources:
            continue
        span = (file, moved(file, start), moved(file, end))
        expected = {(f, moved(f, o)) for f, o in targets}
        got = new_refs.get(span, set())
        if got == expected:
            continue
        src = before.program.sources.get(file)
        line = src.position(start)[0] if src is not None else 0
        text = src.text[start:end] if src is not None else "?"
        was = old_defs.get(next(iter(sorted(targets))))
        if not got:
            raise RenameRefused(_refusal(d, new, f"'{text}' at {where(file, line)} would no "
                                         f"longer refer to {_described(was)}"))
        now = new_defs.get(next(iter(sorted(got - expected or got))))
        if now is not None and (now.span.file, now.span.offset) == renamed_at:
            why = (f"it would hide {_described(was)}, which '{text}' at {where(file, line)} "
                   "refers to")
        else:
            why = (f"'{text}' at {where(file, line)} would refer to {_described(now)} "
                   f"instead of {_described(was)}")
        raise RenameRefused(_refusal(d, new, why))


def _no_new_diagnostics(d: Definition, new: str, before: Checked, after: Checked) -> None:
    grown = Counter(x.code for x in after.diagnostics) - Counter(
        x.code for x in before.diagnostics)
    if not grown:
        return
    word = re.compile(rf"(?<![A-Za-z0-9_]){re.escape(new)}(?![A-Za-z0-9_])")
    known = {(x.code, x.message) for x in before.diagnostics}
    added = [x for x in after.diagnostics if x.code in grown
             and (x.code, word.sub(d.name, x.message)) not in known]
    x = (added or [x for x in after.diagnostics if x.code in grown])[0]
    raise RenameRefused(_refusal(d, new, f"the specification would then have {x.code} "
                                 f"{x.message} ({where(x.span.file, x.span.line)})"))


def verify(path: Path, overrides: dict[Path, str], d: Definition, new: str,
           edits: FileEdits, before: Checked | None = None) -> None:
    """Check the program of the root file `path` (`overrides`: the texts of the open
    documents) once renamed by `edits`: raise RenameRefused if a name would refer to
    another declaration, or if it would check worse. Files of `edits` outside this program
    are not checked here."""
    if before is None:
        before = check_program(path, overrides)
    changed = dict(overrides)
    touched = False
    for file, fe in edits.items():
        src = before.program.sources.get(file)
        if src is None or not fe:
            continue
        changed[path_of_display(file)] = apply_edits(src.text, fe)
        touched = True
    if not touched:
        return
    after = check_program(path, changed)
    _same_resolution(d, new, before, after, edits)
    _no_new_diagnostics(d, new, before, after)


def _written(before: Checked, edits: FileEdits, name: str) -> FileEdits:
    """The edits over text that is the old name (an occurrence whose span is not, in a
    broken text, is left alone: if something referred to the declaration there, `verify`
    finds it no longer does)."""
    out: FileEdits = {}
    for file, fe in edits.items():
        src = before.program.sources.get(file)
        kept = [e for e in fe if src is None or src.text[e[0]:e[1]] == name]
        if kept:
            out[file] = kept
    return out


def _device_of(index: SymbolIndex, instance: str) -> str | None:
    """The device type of a device instance (`real effector lwr: LWR4Plus`)."""
    d = index.definitions.get(instance)
    return d.detail.rsplit(": ", 1)[-1] if d is not None and ": " in d.detail else None


def partners(index: SymbolIndex, d: Definition) -> list[Definition]:
    """The buffers at the other end of the channels of buffer `d` that have its name: the
    name may be what pairs them (among several candidates the same name wins), so they may
    have to be renamed with it."""
    if not d.key.startswith(("buf:", "devbuf:")):
        return []
    found: set[str] = set()
    link = index.links.get(d.key, "")
    if link.startswith("sub:"):
        found.add(f"buf:{link[4:]}.{d.name}")
    elif link.startswith("inst:"):
        found.add(f"devbuf:{_device_of(index, link)}.{d.name}")
    for key, named in index.links.items():
        if not key.endswith(f".{d.name}"):
            continue
        device = f"device:{_device_of(index, named)}" if named.startswith("inst:") else None
        if d.container in (named, device):
            found.add(key)
    direction = d.kind.split()[0]
    out = [p for p in (index.definitions.get(k) for k in sorted(found))
           if p is not None and p.key != d.key and p.name == d.name and p.renameable
           and not is_stdlib(p.span.file) and p.kind.split()[0] != direction]
    return out


def plan(path: Path, overrides: dict[Path, str], file: str, offset: int, new: str,
         references: Callable[[Definition], Iterable[Occurrence]] | None = None
         ) -> FileEdits:
    """The edits that rename the name at `offset` of `file` (a file of the program of the
    root file `path`; `overrides`: the texts of the open documents) to `new`, which
    `bad_name` accepts. `references`: every occurrence of a declaration (those of the
    program when None; see `same_declaration`). Raises RenameRefused.

    When renaming a buffer alone would break a channel that pairs it by its name, the
    buffers of that name at the other end are renamed with it."""
    before = check_program(path, overrides)
    found = target(before.index, file, offset)
    if found is None:
        raise RenameRefused("this is not a name that can be renamed here")
    d = found[1]
    index = before.index

    def refs(x: Definition) -> list[Occurrence]:
        """Those of this program as it is now (the indexes of the workspace may be older),
        and those of other files."""
        own = index.references(x.key)
        if references is None:
            return own
        return own + [o for o in references(x) if o.span.file not in before.program.sources]

    why = clash(before.index, d, new)
    if why is not None:
        raise RenameRefused(why)
    if new == d.name:
        return {}
    edits = _written(before, file_edits(refs(d), new), d.name)
    try:
        verify(path, overrides, d, new, edits, before)
        return edits
    except RenameRefused as refused:
        group = partners(before.index, d)
        if not group or any(clash(before.index, p, new) for p in group):
            raise
        both = _written(before, file_edits([*refs(d), *(o for p in group for o in refs(p))],
                                           new), d.name)
        try:
            verify(path, overrides, d, new, both, before)
        except RenameRefused:
            raise refused from None
        return both


def rename_in_program(path: Path, overrides: dict[Path, str], offset: int, new: str
                      ) -> FileEdits:
    """Rename the name at `offset` of the root file `path` in its program (what the server
    does with the references of the program alone). Raises RenameRefused (also for a name
    that cannot be declared)."""
    reason = bad_name(new)
    if reason is not None:
        raise RenameRefused(reason)
    return plan(path, overrides, display_path(path), offset, new)
