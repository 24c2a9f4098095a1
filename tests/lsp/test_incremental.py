"""An edit inside one agent is reparsed alone (rssm_dsl/lsp/incremental.py): whatever the
edits, the diagnostics, the outline and the symbol index are those of a full analysis."""

from __future__ import annotations

import json
import random
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, note, settings
from hypothesis import strategies as st
from lsprotocol import types as lsp

from rssm_dsl.lsp.analysis import SYNTAX_CODES, Analysis, LazyIndex, analyze_text
from rssm_dsl.lsp.index import SymbolIndex
from rssm_dsl.lsp.reindex import reindex
from rssm_dsl.lsp.symbols import AgentOutlines, document_symbols, outline_json, outline_values
from rssm_dsl.semantics.loader import display_path
from rssm_dsl.syntax import ast
from tests.lsp.specs import GOOD, MISSING_CASE

_HEAD, _, _REST = GOOD.partition("system lwr4_circle {\n")
_AGENT = _REST[: _REST.rindex("}")]
_BROKEN = MISSING_CASE.partition("system lwr4_circle {\n")[2]
_BROKEN_AGENT = _BROKEN[: _BROKEN.rindex("}")]


def spec(agents: int) -> str:
    """Several copies of the example's agent; the third one misses a data case (E501)."""
    parts = [(_BROKEN_AGENT if i == 3 else _AGENT).replace("agent a1 {", f"agent a{i} {{")
             for i in range(1, agents + 1)]
    return f"{_HEAD}system many {{\n{''.join(parts)}}}\n"


def _diags(a: Analysis) -> list[tuple[str, str, int, int, int, int]]:
    return [(d.code, d.message, d.span.line, d.span.column, d.span.end_line, d.span.end_column)
            for d in a.diagnostics]


def _outline(a: Analysis) -> list[lsp.DocumentSymbol]:
    """The outline as the server makes it: from the stale AST and its shifts when the
    mapped AST is not built yet (as after an incremental analysis)."""
    module, real = a.lazy_module.outline_view()
    return document_symbols(module, a.lines, "utf-16", real)


def _occurrences(a: Analysis) -> set[tuple[str, int, int, str]]:
    return {(o.span.file, o.span.offset, o.span.end_offset, o.key)
            for occs in a.index.occurrences.values() for o in occs
            if not o.key.startswith("local:")}


def _edit(text: str, rng: random.Random) -> str:
    """One edit a person could make inside an agent (sometimes one that breaks it)."""
    lines = text.split("\n")
    inside = [i for i, line in enumerate(lines) if line.startswith("      ")]
    n = rng.choice(inside)
    line = lines[n]
    kind = rng.randrange(6)
    if kind == 0 and re.search(r"\d", line):            # change a number
        digits = [m.start() for m in re.finditer(r"\d", line)]
        at = rng.choice(digits)
        lines[n] = line[:at] + str(rng.randrange(10)) + line[at + 1:]
    elif kind == 1:                                       # a new comment line
        lines.insert(n, "      // note é 😀")
    elif kind == 2 and line.strip():                      # delete a line
        del lines[n]
    elif kind == 3:                                       # split a line in two
        at = line.find(" ", len(line) - len(line.lstrip()) + 1)
        if at > 0:
            lines[n] = line[:at] + "\n        " + line[at + 1:]
    elif kind == 4:                                       # a typo: a syntax error
        lines[n] = line + " +* "
    else:                                                 # rename a name in one place
        lines[n] = re.sub(r"\bphase\b", "phase2", line, count=1)
    return "\n".join(lines)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_incremental_analysis_equals_a_full_one(seed: int, tmp_path_factory: object) -> None:
    rng = random.Random(seed)
    path = Path("/tmp/rssm-incremental-test/many.rssm")
    shown = display_path(path)
    text = spec(5)
    previous = analyze_text("file:///many", path, shown, text, 1, {}, None)
    assert previous.how == "full" and [d[0] for d in _diags(previous)] == ["E501"]
    known: dict[str, AgentOutlines] = {"utf-16": {}, "utf-8": {}}
    for version in range(2, 8):
        text = _edit(text, rng)
        step = analyze_text("file:///many", path, shown, text, version, {}, previous)
        full = analyze_text("file:///many", path, shown, text, version, {}, None)
        for encoding in known:     # the outline sent: agents' JSON reused, moved
            module, real = step.lazy_module.outline_view()
            sent, known[encoding] = outline_json(module, step.lines, encoding, real,
                                                 known[encoding])
            assert json.loads(sent) == outline_values(module, step.lines, encoding, real)
        if any(d.code in SYNTAX_CODES for d in full.diagnostics):
            # the agent-local recovery may differ from the whole file's; both report it
            assert any(d.code in SYNTAX_CODES for d in step.diagnostics)
            previous = step
            continue
        assert _diags(step) == _diags(full)
        assert _outline(step) == _outline(full)
        if step.how == "incremental":
            assert _occurrences(step) == _occurrences(full)
        previous = step


def _declarations(index: SymbolIndex) -> dict[str, tuple[str, str, str, str | None, bool]]:
    return {k: (d.name, d.kind, d.detail, d.container, d.renameable)
            for k, d in index.definitions.items() if not k.startswith("local:")}


def _same_index(a: SymbolIndex, b: SymbolIndex) -> bool:
    return (a.definitions == b.definitions and a.occurrences == b.occurrences
            and a.scopes == b.scopes and a.links == b.links)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_index_after_an_edit_is_the_previous_one_with_one_agent_indexed_again(
        seed: int) -> None:
    """The index of an incrementally analysed text is made from the previous text's index
    by indexing the edited agent again (rssm_dsl/lsp/reindex.py). Whenever that is done it
    equals the index built from scratch (every definition, occurrence, scope and link, at
    real positions, local values too). In a text without syntax errors it is refused only
    when a declaration's key, kind, type or container changed (the index is built from
    scratch then)."""
    rng = random.Random(seed)
    path = Path("/tmp/rssm-incremental-test/reindex.rssm")
    shown = display_path(path)
    text = spec(5).replace("agent a5 {", "agent a5 {\n    real receptor other: LWR4Plus\n", 1)
    previous = analyze_text("file:///reindex", path, shown, text, 1, {}, None)
    derived = 0
    for version in range(2, 10):
        old_index = previous.index
        was_broken = any(d.code in SYNTAX_CODES for d in previous.diagnostics)
        text = _edit(text, rng)
        step = analyze_text("file:///reindex", path, shown, text, version, {}, previous)
        previous = step
        if step.how != "incremental":
            continue
        assert step.lazy_index.base is not None
        [edit] = step.lazy_index.edits
        whole = LazyIndex(step.program, shifts=step.lazy_index.shifts).get()
        got = reindex(old_index, [edit], shown)
        broken = was_broken or any(d.code in SYNTAX_CODES for d in step.diagnostics)
        if _declarations(old_index) == _declarations(whole) and not broken:
            assert got is not None
        if got is not None:
            derived += 1
            assert _same_index(got, whole)
            assert _same_index(step.index, whole)
    note(f"{derived} indexes made from the previous one")


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_index_after_several_edits_made_at_once_is_the_index_of_the_text(
        seed: int) -> None:
    """Edits typed faster than anything asks for the index: it is made from the last index
    built and all the edits since (consecutive edits of one agent as one), and equals the
    index built from scratch."""
    rng = random.Random(seed)
    path = Path("/tmp/rssm-incremental-test/chain.rssm")
    shown = display_path(path)
    text = spec(5)
    previous = analyze_text("file:///chain", path, shown, text, 1, {}, None)
    assert previous.index is not None
    for version in range(2, 2 + rng.randrange(2, 7)):
        text = _edit(text, rng) if rng.random() < 0.5 else _value_edit(text, rng)
        previous = analyze_text("file:///chain", path, shown, text, version, {}, previous)
    if previous.how == "incremental" and previous.lazy_index.base is not None:
        whole = LazyIndex(previous.program, shifts=previous.lazy_index.shifts).get()
        assert _same_index(previous.index, whole)


def _value_edit(text: str, rng: random.Random) -> str:
    """A parameter value changed in agent a2 or a4 (edits of one agent follow each other)."""
    at = text.index(rng.choice(["agent a2 {", "agent a4 {"]))
    value = re.compile(r"float = (\d+\.\d+)")
    m = value.search(text, at)
    assert m is not None
    return text[:m.start(1)] + f"0.0{rng.randrange(1, 10)}" + text[m.end(1):]


def test_consecutive_edits_of_one_agent_are_one_edit_of_the_index(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import rssm_dsl.lsp.analysis as analysis_module

    built: list[int] = []
    real = analysis_module.build_index
    monkeypatch.setattr(analysis_module, "build_index",
                        lambda program: built.append(1) or real(program))
    path = Path("/tmp/rssm-incremental-test/merge.rssm")
    shown = display_path(path)
    text = spec(5)
    a = analyze_text("file:///merge", path, shown, text, 1, {}, None)
    assert a.index is not None
    rng = random.Random(3)
    steps = ["agent a2 {", "agent a2 {", "agent a4 {", "agent a4 {", "agent a2 {"]
    for version, agent in enumerate(steps, start=2):
        at = text.index(agent)
        m = re.compile(r"float = (\d+\.\d+)").search(text, at)
        assert m is not None
        text = text[:m.start(1)] + f"0.0{rng.randrange(1, 10)}" + text[m.end(1):]
        a = analyze_text("file:///merge", path, shown, text, version, {}, a)
        assert a.how == "incremental"
    assert len(a.lazy_index.edits) == 3      # a2 twice, a4 twice, a2
    made = a.index
    assert len(built) == 1                   # the first text's; the rest made from it
    whole = LazyIndex(a.program, shifts=a.lazy_index.shifts).get()
    assert _same_index(made, whole)


def test_an_edit_that_keeps_the_declarations_indexes_one_agent_again(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A value changed in agent a2: the index is the previous one with a2 indexed again,
    not built from scratch; a memory variable added to a3: built from scratch."""
    import rssm_dsl.lsp.analysis as analysis_module

    built: list[int] = []
    real = analysis_module.build_index

    def counting(program: Any) -> SymbolIndex:
        built.append(1)
        return real(program)

    monkeypatch.setattr(analysis_module, "build_index", counting)
    path = Path("/tmp/rssm-incremental-test/keeps.rssm")
    shown = display_path(path)
    text = spec(4)
    a = analyze_text("file:///keeps", path, shown, text, 1, {}, None)
    assert a.index is not None and len(built) == 1
    at = text.index("agent a2 {")
    t2 = text[:at] + text[at:].replace("float = 0.05", "float = 0.07", 1)
    b = analyze_text("file:///keeps", path, shown, t2, 2, {}, a)
    assert b.how == "incremental" and b.index is not None and len(built) == 1
    at = t2.index("agent a3 {")
    t3 = t2[:at] + t2[at:].replace("memory phase: float = 0.0",
                                   "memory phase: float = 0.0\n      memory turns: int = 0", 1)
    c = analyze_text("file:///keeps", path, shown, t3, 3, {}, b)
    assert c.how == "incremental" and c.index is not None and len(built) == 2
    assert any(k.endswith("a3.c.turns") for k in c.index.definitions)


def test_a_query_inside_an_agent_reads_that_agent_without_mapping_the_ast() -> None:
    """After an incremental analysis, `view_at` gives the agent under the cursor with its
    stale spans and the one shift that makes them real: every update target, field access
    and declaration name of the mapped AST is found in the view at the same place."""
    path = Path("/tmp/rssm-incremental-test/view.rssm")
    shown = display_path(path)
    text = spec(4)
    a = analyze_text("file:///view", path, shown, text, 1, {}, None)
    at = text.index("agent a2 {")
    t2 = text[:at] + text[at:].replace("memory phase", "// one more line\n      memory phase", 1)
    b = analyze_text("file:///view", path, shown, t2, 2, {}, a)
    assert b.how == "incremental"
    at = t2.index("agent a3 {")
    t3 = t2[:at] + t2[at:].replace("float = 0.05", "float = 0.075", 1)
    c = analyze_text("file:///view", path, shown, t3, 3, {}, b)
    assert c.how == "incremental" and not c.lazy_module.ready

    def places(agent: ast.AgentDecl) -> list[tuple[str, int]]:
        found = [(s.name, s.name_span.offset) for s in agent.subsystems]
        for s in agent.subsystems:
            found += [(b.name, b.name_span.offset) for b in s.buffers]
            for bd in s.behaviours:
                found += [(u.target, u.target_span.offset) for u in bd.updates]
        return found

    views = [(agent, c.lazy_module.view_at(offset))
             for agent, offset in [(ag, ag.span.offset + k) for ag in _agents(c)
                                   for k in (1, 40, 200)]]
    mapped = c.module
    assert mapped is not None and c.lazy_module.ready
    real_agents = {ag.name: ag for ag in _agents_of(mapped)}
    for agent, view in views:
        assert view.module is not None
        [alone] = _agents_of(view.module)
        assert alone.name == agent.name
        assert [(n, o + view.delta) for n, o in places(alone)] == \
            places(real_agents[agent.name])
    # outside every agent: the whole AST
    assert c.lazy_module.view_at(0).delta == 0


def test_the_outline_after_an_edit_reuses_the_json_of_the_other_agents() -> None:
    """A line added in agent a2: the outline sent reuses a1's JSON as it was, a3's and
    a4's moved one line down, and outlines a2 again; it is the outline made from scratch."""
    path = Path("/tmp/rssm-incremental-test/outline.rssm")
    shown = display_path(path)
    text = spec(4)
    a = analyze_text("file:///outline", path, shown, text, 1, {}, None)
    sent, known = outline_json(a.module, a.lines, "utf-16", lambda s: s, {})
    at = text.index("agent a2 {")
    t2 = text[:at] + text[at:].replace("memory phase", "// a note\n      memory phase", 1)
    b = analyze_text("file:///outline", path, shown, t2, 2, {}, a)
    module, real = b.lazy_module.outline_view()
    sent, now = outline_json(module, b.lines, "utf-16", real, known)
    by_name = {x.agent.name: x for x in now.values()}
    before = {x.agent.name: x for x in known.values()}
    assert by_name["a1"] is before["a1"]
    assert by_name["a2"].agent is not before["a2"].agent
    for name in ("a3", "a4"):
        assert by_name[name].agent is before[name].agent
        assert by_name[name].line == before[name].line + 1
    assert json.loads(sent) == outline_values(b.module, b.lines, "utf-16")


def _agents_of(module: ast.Module) -> list[ast.AgentDecl]:
    return [ag for d in module.decls if isinstance(d, ast.SystemDecl) for ag in d.agents]


def _agents(a: Analysis) -> list[ast.AgentDecl]:
    """The agents of an analysis at real positions (mapped from the stale AST once)."""
    module, real = a.lazy_module.outline_view()
    assert module is not None
    return [replace(ag, span=real(ag.span)) for ag in _agents_of(module)]


def test_edits_inside_an_agent_are_reparsed_alone() -> None:
    path = Path("/tmp/rssm-incremental-test/alone.rssm")
    shown = display_path(path)
    text = spec(4)
    a = analyze_text("file:///alone", path, shown, text, 1, {}, None)
    # in agent a2: a value, then a new line; in agent a4: a line removed
    at = text.index("agent a2 {")
    t2 = text[:at] + text[at:].replace("float = 0.05", "float = 0.07", 1)
    b = analyze_text("file:///alone", path, shown, t2, 2, {}, a)
    assert b.how == "incremental"
    marker = "agent a4 {\n"
    t3 = t2.replace(marker, marker + "    // a comment line\n")
    c = analyze_text("file:///alone", path, shown, t3, 3, {}, b)
    assert c.how == "incremental"
    [e501] = c.diagnostics
    assert e501.code == "E501"
    line = t3.splitlines()[e501.span.line - 1]
    assert line[e501.span.column - 1:e501.span.end_column - 1] == "torque"
    before = "\n".join(t3.splitlines()[: e501.span.line - 1])
    assert before.count("agent a") == 3 and "agent a3 {" in before   # still in agent a3
    # a syntax error inside agent a2 is reparsed alone too: a2 reports it, a3 keeps its E501
    t3b = t3.replace("terminal full_circle when phase >= 2.0 * pi",
                     "terminal full_circle when phase >= 2.0 *", 3)
    t3b = t3b.replace("terminal full_circle when phase >= 2.0 *",
                      "terminal full_circle when phase >= 2.0 * pi", 2)
    broken = analyze_text("file:///alone", path, shown, t3b, 5, {}, c)
    assert broken.how == "incremental"
    assert [d.code for d in broken.diagnostics] == ["E005", "E501"]
    assert _outline(broken)[0].children is not None and len(_outline(broken)[0].children) == 4
    repaired = analyze_text("file:///alone", path, shown, t3, 6, {}, broken)
    assert repaired.how == "incremental" and _diags(repaired) == _diags(c)
    # an edit outside every agent: a full analysis
    t4 = t3.replace("import std.types", "import std.types\n")
    assert analyze_text("file:///alone", path, shown, t4, 4, {}, c).how == "full"


def test_an_incremental_analysis_keeps_the_checks_of_the_loader() -> None:
    """What the loader checks in a file it reads is reported after an edit too: a line
    separator in a comment (W012, the edit stays incremental), a name too long for a file
    name (E011, an error that stops the compiler's analysis: the whole text is analysed)."""
    path = Path("/tmp/rssm-incremental-test/loader.rssm")
    shown = display_path(path)
    text = spec(4)
    a = analyze_text("file:///loader", path, shown, text, 1, {}, None)
    t2 = text.replace("agent a2 {\n", "agent a2 {\n    // one\u2028two\n", 1)
    b = analyze_text("file:///loader", path, shown, t2, 2, {}, a)
    assert b.how == "incremental"
    assert _diags(b) == _diags(analyze_text("file:///loader", path, shown, t2, 2, {}, None))
    assert sorted(d.code for d in b.diagnostics) == ["E501", "W012"]
    t3 = t2.replace("agent a2 {", f"agent a2{'x' * 120} {{", 1)
    c = analyze_text("file:///loader", path, shown, t3, 3, {}, b)
    assert _diags(c) == _diags(analyze_text("file:///loader", path, shown, t3, 3, {}, None))
    assert "E011" in [d.code for d in c.diagnostics]


def test_the_semantic_passes_run_again_on_the_edited_agent_only(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """After an edit inside agent a2, the structure and behaviour passes analyse a2 alone;
    the other agents' work (and a3's E501) is reused. An edit outside the agents (a
    constant) makes every agent be analysed again, and its effect reaches them all."""
    import rssm_dsl.semantics.analyze as analyze_module

    analysed: list[str] = []
    real = analyze_module._agent_work

    def counting(a: ast.AgentDecl, *args: Any) -> Any:
        analysed.append(a.name)
        return real(a, *args)

    monkeypatch.setattr(analyze_module, "_agent_work", counting)
    path = Path("/tmp/rssm-incremental-test/memo.rssm")
    shown = display_path(path)
    text = spec(4).replace("import std.types\n", "import std.types\nconst gain: float = 0.05\n")
    a = analyze_text("file:///memo", path, shown, text, 1, {}, None)
    assert sorted(analysed) == ["a1", "a2", "a3", "a4"]
    analysed.clear()
    at = text.index("agent a2 {")
    t2 = text[:at] + text[at:].replace("float = 0.05", "float = gain", 1)
    b = analyze_text("file:///memo", path, shown, t2, 2, {}, a)
    assert b.how == "incremental" and analysed == ["a2"]
    assert _diags(b) == _diags(analyze_text("file:///memo", path, shown, t2, 2, {}, None))
    assert [d.code for d in b.diagnostics] == ["E501"]
    analysed.clear()
    # the constant becomes a bool: a2 now reads a bool where a float is due
    t3 = t2.replace("const gain: float = 0.05", "const gain: bool = true")
    c = analyze_text("file:///memo", path, shown, t3, 3, {}, b)
    assert sorted(analysed) == ["a1", "a2", "a3", "a4"]
    assert "E201" in [d.code for d in c.diagnostics]
    assert _diags(c) == _diags(analyze_text("file:///memo", path, shown, t3, 3, {}, None))


def test_the_checks_of_unchanged_agents_are_reused_and_those_of_the_edited_one_rerun(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Switch checks are kept per subsystem (CheckContext.reuse): an edit in a1 keeps a3's
    W604 (overlapping switches) without checking a3 again; the same overlap written into
    a2 is found there. Each time, the diagnostics are those of a full analysis."""
    path = Path("/tmp/rssm-incremental-test/checks.rssm")
    shown = display_path(path)
    switch = "      switch ccw -> cw when full_circle\n"
    overlap = switch + "      switch ccw -> ccw when full_circle\n"
    text = spec(3)
    at = text.index("agent a3 {")
    text = text[:at] + text[at:].replace(switch, overlap, 1)

    def w604(a: Analysis) -> list[int]:
        return [d.span.line for d in a.diagnostics if d.code == "W604"]

    import rssm_dsl.semantics.checks.switching as switching

    checked: list[str] = []
    real = switching._check_subsystem

    def counting(ctx: Any, s: Any, unchecked: set[str]) -> None:
        checked.append(s.agent)
        real(ctx, s, unchecked)

    monkeypatch.setattr(switching, "_check_subsystem", counting)
    a = analyze_text("file:///checks", path, shown, text, 1, {}, None)
    assert len(w604(a)) == 1 and set(checked) == {"a1", "a2", "a3"}
    checked.clear()
    at = text.index("agent a1 {")
    t2 = text[:at] + text[at:].replace("memory phase", "// a\n      memory phase", 1)
    b = analyze_text("file:///checks", path, shown, t2, 2, {}, a)
    assert b.how == "incremental" and w604(b) == [w604(a)[0] + 1]
    assert set(checked) == {"a1"}
    assert _diags(b) == _diags(analyze_text("file:///checks", path, shown, t2, 2, {}, None))
    at = t2.index("agent a2 {")
    t3 = t2[:at] + t2[at:].replace(switch, overlap, 1)
    c = analyze_text("file:///checks", path, shown, t3, 3, {}, b)
    assert c.how == "incremental" and len(w604(c)) == 2
    assert _diags(c) == _diags(analyze_text("file:///checks", path, shown, t3, 3, {}, None))
    t4 = t3[:at] + t3[at:].replace(overlap, switch, 1)
    d = analyze_text("file:///checks", path, shown, t4, 4, {}, c)
    assert d.how == "incremental" and w604(d) == w604(b)


def test_completion_needs_nothing_built_after_an_edit() -> None:
    """Right after an incremental analysis, completion reads names only: the stale AST
    (with the edited agent's new declarations) and the index of the text before, whose
    declarations outside the system are the same. Completing from them gives what
    completing from the mapped AST and the new index gives."""
    from rssm_dsl.lsp.completion import complete

    path = Path("/tmp/rssm-incremental-test/complete.rssm")
    shown = display_path(path)
    text = spec(3)
    a = analyze_text("file:///complete", path, shown, text, 1, {}, None)
    a.lazy_index.get()
    at = text.index("agent a2 {")
    t2 = text[:at] + text[at:].replace("memory phase: float = 0.0",
                                       "memory phase: float = 0.0\n      memory spare: float = 0.0", 1)
    b = analyze_text("file:///complete", path, shown, t2, 2, {}, a)
    assert b.how == "incremental"
    assert not b.lazy_index.ready and not b.lazy_module.ready
    assert b.lazy_index.outside() is a.lazy_index.value
    names = b.lazy_module.names()
    assert names is not None and "spare" in [
        m.name for d in names.decls if isinstance(d, ast.SystemDecl)
        for ag in d.agents if ag.name == "a2" for s in ag.subsystems for m in s.memory]
    offset = t2.index(":= ", t2.index("agent a2 {")) + 3

    def labels(module: ast.Module | None, index: Any) -> list[str]:
        return sorted(i.label for i in complete(module, index, t2, offset, b.program, b.system))

    quick = labels(names, b.lazy_index.outside())
    assert "spare" in quick
    assert quick == labels(b.module, b.index)
