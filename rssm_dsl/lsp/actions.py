"""Quick fixes for the common mistakes:

- E501 (a data-availability combination no case covers): add the missing `case`s, or an
  `otherwise:` case;
- E603 (after a behaviour ends no switch condition may hold): add `switch B -> end
  otherwise` (or to another behaviour);
- E304 (a buffer with no matching buffer on its peer): declare the missing buffer in the
  peer subsystem (not offered when the peer already declares something of that name).

Every fix gives a text that parses and checks no worse than before, and removes the
diagnostic it is preferred for (tests/lsp/test_actions_property.py applies each to every
example of examples/diagnostics/ and to mutations of them).
"""

from __future__ import annotations

import re

from lsprotocol import types as lsp

from rssm_core.records import dataclass
from rssm_dsl.lsp.index import block_close, subsystem_key, system_id
from rssm_dsl.lsp.positions import LineIndex, line_end, line_start
from rssm_dsl.semantics import cases as case_rule
from rssm_dsl.semantics.behaviours import (
    _NotData,
    combination_text,
    eval_availability,
    split_inputs,
)
from rssm_dsl.source import Span
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.printer import type_text

_LETTER = {"control": "c", "effector": "e", "receptor": "r"}


@dataclass(frozen=True)
class Where:
    system: ast.SystemDecl
    agent: ast.AgentDecl
    sub: ast.SubsystemDecl


def _subsystems(module: ast.Module) -> list[Where]:
    return [Where(d, a, s) for d in module.decls if isinstance(d, ast.SystemDecl)
            for a in d.agents for s in a.subsystems]


def _indent_of(text: str, offset: int) -> str:
    start = line_start(text, offset)
    line = text[start:line_end(text, start)]
    return line[: len(line) - len(line.lstrip(" \t"))]


class Fixer:
    def __init__(self, uri: str, module: ast.Module, text: str, lines: LineIndex,
                 encoding: str) -> None:
        self.uri = uri
        self.module = module
        self.text = text
        self.lines = lines
        self.encoding = encoding

    # ------------------------------------------------------------------ edits
    def _action(self, title: str, diag: lsp.Diagnostic, offset: int, new_text: str,
                preferred: bool = False) -> lsp.CodeAction:
        pos = self.lines.position(offset, self.encoding)
        edit = lsp.TextEdit(range=lsp.Range(start=pos, end=pos), new_text=new_text)
        return lsp.CodeAction(
            title=title, kind=lsp.CodeActionKind.QuickFix, diagnostics=[diag],
            is_preferred=preferred or None,
            edit=lsp.WorkspaceEdit(changes={self.uri: [edit]}),
        )

    def _after_line(self, offset: int) -> int:
        """The offset of the end of the line holding `offset`."""
        return line_end(self.text, offset)

    def _before_closer(self, name_end: int) -> tuple[int, str]:
        """Where to insert lines before the `}` that closes the block opened after a name
        (ending at name_end). Returns (offset, prefix): prefix starts a new line if needed."""
        close = block_close(self.text, name_end) - 1
        start = line_start(self.text, close)
        if self.text[start:close].strip() == "":
            return start, ""
        return close, "\n"

    # ------------------------------------------------------------------ fixes
    def fixes(self, diag: lsp.Diagnostic) -> list[lsp.CodeAction]:
        code = diag.code
        offset = self.lines.offset(diag.range.start, self.encoding)
        if code == "E501":
            return self._cases(diag, offset)
        if code == "E603":
            return self._switch(diag, offset)
        if code == "E304":
            return self._buffer(diag, offset)
        return []

    def _cases(self, diag: lsp.Diagnostic, offset: int) -> list[lsp.CodeAction]:
        for w in _subsystems(self.module):
            for bd in w.sub.behaviours:
                for u in bd.updates:
                    if u.target_span.offset <= offset <= u.target_span.end_offset:
                        return self._case_fixes(diag, w.sub, bd, u)
        return []

    def _case_fixes(self, diag: lsp.Diagnostic, sub: ast.SubsystemDecl,
                    bd: ast.BehaviourDecl, u: ast.UpdateDecl) -> list[lsp.CodeAction]:
        inputs = tuple(b.name for b in sub.buffers if b.direction is ast.Direction.INPUT)
        conditions: list[ast.Expr] = [c.condition for c in u.cases if c.condition is not None]
        missing: list[str] = []
        # over the inputs the behaviour's case clauses read, as E501 reports them (beyond
        # FULL_SPLIT of them: only the `otherwise:` fix, no enumeration)
        split = split_inputs(bd.updates, inputs)
        combos = (case_rule.combinations(split, len(inputs))
                  if len(split) <= case_rule.FULL_SPLIT else [])
        for combo in combos:
            covered = False
            for cond in conditions:
                try:
                    covered = covered or eval_availability(cond, inputs, combo)
                except _NotData:
                    continue
            if not covered:
                missing.append(combination_text(inputs, combo))
        at, prefix = self._before_closer(u.target_span.end_offset)
        indent = _indent_of(self.text, u.target_span.offset) + "  "
        body = indent + "  "
        out: list[lsp.CodeAction] = []
        if missing:
            text = "".join(f"{indent}case {m}:\n{body}skip\n" for m in missing)
            plural = "s" if len(missing) > 1 else ""
            out.append(self._action(f"Add the missing data-availability case{plural} "
                                    f"({'; '.join(missing)})", diag, at,
                                    prefix + text, preferred=True))
        if not any(c.condition is None for c in u.cases):
            out.append(self._action("Add an `otherwise:` case", diag, at,
                                    f"{prefix}{indent}otherwise:\n{body}skip\n"))
        return out

    def _switch(self, diag: lsp.Diagnostic, offset: int) -> list[lsp.CodeAction]:
        m = re.search(r"behaviour '([A-Za-z_][A-Za-z0-9_]*)'", diag.message)
        if m is None:
            return []
        name = m.group(1)
        for w in _subsystems(self.module):
            if not (w.sub.span.offset <= offset <= w.sub.span.end_offset):
                continue
            if not any(b.name == name for b in w.sub.behaviours):
                continue
            anchors: list[Span] = [x.span for x in w.sub.switches]
            anchors += [x.span for x in w.sub.initial]
            if anchors:
                last = max(anchors, key=lambda x: x.end_offset)
                at = self._after_line(last.end_offset)
                indent = _indent_of(self.text, last.offset)
                lead, trail = "\n", ""
            else:
                at, lead = self._before_closer(w.sub.name_span.end_offset)
                indent = _indent_of(self.text, w.sub.span.offset) + "  "
                trail = "\n"
            targets = ["end"] + [b.name for b in w.sub.behaviours if b.name != name]
            return [self._action(f"Add `switch {name} -> {t} otherwise`", diag, at,
                                 f"{lead}{indent}switch {name} -> {t} otherwise{trail}",
                                 preferred=(t == "end"))
                    for t in targets]
        return []

    def _buffer(self, diag: lsp.Diagnostic, offset: int) -> list[lsp.CodeAction]:
        first = diag.message.split("\n")[0]
        named = re.match(r"^(\S+) has no (?:input|output) buffer '([A-Za-z_][A-Za-z0-9_]*)'",
                         first)
        on = re.search(r" on (\S+)$", first)
        if named is None and on is None:
            return []
        peer_id = named.group(1) if named else on.group(1)  # type: ignore[union-attr]
        subs = _subsystems(self.module)

        def holds(b: ast.BufferDecl) -> bool:
            spans = [b.span] + ([b.peer.span] if b.peer is not None else [])
            return any(s.offset <= offset <= s.end_offset for s in spans)

        here = next(((w, b) for w in subs for b in w.sub.buffers if holds(b)), None)
        peer = next((w for w in subs
                     if subsystem_key(system_id(w.system), w.agent.name, w.sub).split("/")[-1]
                     == peer_id), None)
        if here is None or peer is None:
            return []
        owner, buf = here
        if owner.agent is not peer.agent:
            relative = f"{owner.agent.name}.c"
        elif owner.sub.kind is ast.SubsystemKind.CONTROL:
            relative = "c"
        else:
            relative = f"{_LETTER[owner.sub.kind.value]}.{owner.sub.name}"
        output = buf.direction is ast.Direction.INPUT
        name = named.group(2) if named else buf.name
        taken = {x.name for x in peer.sub.buffers} | {x.name for x in peer.sub.memory} | {
            x.name for x in peer.sub.params}
        if name in taken:
            return []   # another declaration of the peer has the name: no buffer can have it
        # the type as the printer writes it (its span stops before an array's `]`)
        decl = (f"{'output' if output else 'input'} {name}: {type_text(buf.type)} "
                f"{'to' if output else 'from'} {relative}")
        if buf.mode is not None and buf.mode_span is not None:
            decl += f" {buf.mode.value}"
        members: list[Span] = [x.span for x in peer.sub.buffers]
        if not members:
            members = [x.span for x in peer.sub.memory] + [x.span for x in peer.sub.params]
        if members:
            anchor = max(members, key=lambda x: x.end_offset)
            at = self._after_line(anchor.end_offset)
            text = f"\n{_indent_of(self.text, anchor.offset)}{decl}"
        else:
            brace = self.text.find("{", peer.sub.name_span.end_offset)
            at = self._after_line(brace)
            text = f"\n{_indent_of(self.text, peer.sub.span.offset)}  {decl}"
        return [self._action(f"Declare `{decl}` in {peer_id}", diag, at, text,
                             preferred=True)]
