"""User-stated properties: parsing and printing, the checks (E620-E625, W626, E103), the
model (System.properties), the resolved atoms and the evaluation (rssm_dsl.semantics.properties)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from rssm_dsl.emit.dump import dump_text
from rssm_dsl.interp.errors import EvalError
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.semantics.properties import (
    Formula,
    InBehaviour,
    PropertyError,
    UnknownValue,
    Value,
    atoms,
    evaluate,
)
from rssm_dsl.semantics.types import BOOL, FLOAT, ArrayT, RecordT
from rssm_dsl.source import SourceFile
from rssm_dsl.syntax import ast
from rssm_dsl.syntax.format import format_text
from rssm_dsl.syntax.parser import parse
from rssm_dsl.syntax.printer import expr_text, property_text
from tests.conftest import EXAMPLES

# Two agents: `a` (a control subsystem and a virtual effector `motor`), `b` (a control
# subsystem named `main`); PROPS is replaced by the properties of each test.
SPEC = """
const limit: int = 3
record Pose { x: float, ok: bool }

system plant {
  agent a {
    control @ 10 Hz {
      param gain: float = 2.5
      param tries: int = 2
      memory n: int = 0
      memory busy: bool = false
      memory pose: Pose
      memory q: float[3]
      input speed: float from e.motor
      output cmd: float to e.motor

      behaviour idle {
        update cmd { cmd := 0.0 }
        update memory { busy := false  n := n + 1 }
        terminal go when n > limit and speed >= 0.0 and pose.ok and q[0] >= 0.0
      }
      behaviour work {
        update cmd { cmd := gain }
        update memory { busy := true  pose.x := pose.x + 1.0  q[0] := 1.0 }
        terminal done when n > tries and busy
      }
      initial idle
      switch idle -> work when go
      switch work -> idle when done
    }

    effector motor @ 10 Hz {
      input cmd: float from c
      output speed: float to c
      behaviour relay {
        update speed { speed := cmd }
        terminal never when false
      }
      initial relay
    }
  }

  agent b {
    control main @ 10 Hz {
      memory ready: bool = false
      behaviour wait {
        update memory { ready := not ready }
        terminal tick when ready
      }
      behaviour serve {
        update memory { ready := false }
        terminal served when not ready
      }
      initial wait
      switch wait -> serve when tick
      switch serve -> wait when served
    }
  }
PROPS
}
"""


def _compile(tmp_path: Path, props: str) -> Compilation:
    path = tmp_path / "plant.rssm"
    path.write_text(SPEC.replace("PROPS", props), encoding="utf-8")
    return compile_file(path)


def _codes(comp: Compilation) -> list[tuple[str, str]]:
    return [(d.code, d.message) for d in comp.diagnostics]


def _ok(tmp_path: Path, props: str, warnings: tuple[str, ...] = ()) -> Compilation:
    """Compiled with no diagnostic but the given warnings (W626: a value is abstracted)."""
    comp = _compile(tmp_path, props)
    assert comp.ok and all(d.code in warnings for d in comp.diagnostics), _codes(comp)
    assert comp.system is not None
    return comp


# ---------------------------------------------------------------------- syntax


def test_the_spec_without_properties_is_clean(tmp_path: Path) -> None:
    comp = _ok(tmp_path, "")
    assert comp.system is not None and comp.system.properties == ()


def test_properties_parse_between_and_after_agents() -> None:
    text = SPEC.replace("  agent b {", "  property early: always a.c in idle\n  agent b {", 1)
    text = text.replace("PROPS", "  property late: whenever a.c in work eventually b.c in serve")
    result = parse(SourceFile("x.rssm", text))
    assert result.diagnostics == ()
    assert result.module is not None
    [sd] = [d for d in result.module.decls if isinstance(d, ast.SystemDecl)]
    assert [a.name for a in sd.agents] == ["a", "b"]
    early, late = sd.properties
    assert (early.name, early.kind) == ("early", "always")
    assert early.trigger is None and early.goal is None
    assert isinstance(early.condition, ast.InBehaviour)
    assert (late.name, late.kind) == ("late", "response") and late.condition is None
    assert isinstance(late.trigger, ast.InBehaviour) and late.trigger.behaviour == "work"
    assert isinstance(late.goal, ast.InBehaviour) and late.goal.behaviour == "serve"
    assert text[late.name_span.offset:late.name_span.end_offset] == "late"
    goal = late.goal
    assert text[goal.behaviour_span.offset:goal.behaviour_span.end_offset] == "serve"


def _condition(text: str) -> ast.Expr:
    src = f"system s {{ property p: always {text} }}"
    result = parse(SourceFile("x.rssm", src))
    assert result.diagnostics == (), result.diagnostics
    assert result.module is not None
    sd = result.module.decls[0]
    assert isinstance(sd, ast.SystemDecl)
    cond = sd.properties[0].condition
    assert cond is not None
    return cond


def test_in_binds_tighter_than_every_operator() -> None:
    e = _condition("not a.c in x and b.c in y or a.c.n + 1 > 2")
    assert isinstance(e, ast.Binary) and e.op == "or"
    left = e.left
    assert isinstance(left, ast.Binary) and left.op == "and"
    assert isinstance(left.left, ast.Unary) and isinstance(left.left.operand, ast.InBehaviour)
    assert isinstance(left.right, ast.InBehaviour)
    assert expr_text(left.left) == "not a.c in x"


@pytest.mark.parametrize("text", [
    "not (a.c in x and b.c in y)",
    "a.c in x == b.main in y",
    "a.c.pose.x > 1.0 or not a.c.busy",
    "(a.c.n + 1) * 2 <= limit",
    "if a.c in x then a.c.q[0] > 0.0 else true",
])
def test_printing_a_property_reparses_to_the_same_expression(text: str) -> None:
    e = _condition(text)
    again = _condition(expr_text(e))
    assert expr_text(again) == expr_text(e)
    assert _strip(again) == _strip(e)


def _strip(e: Any) -> Any:
    """An AST without its spans (for structural comparison)."""
    if isinstance(e, tuple):
        return tuple(_strip(x) for x in e)
    if hasattr(e, "__dataclass_fields__"):
        return (type(e).__name__, *(_strip(getattr(e, f)) for f in e.__dataclass_fields__
                                    if not f.endswith("span")))
    return e


def test_property_text() -> None:
    src = ("system s { property p: always not (a.c in x and b.c in y) "
           "property q: whenever a.c in x eventually a.c.n >= 2 }")
    result = parse(SourceFile("x.rssm", src))
    assert result.module is not None
    sd = result.module.decls[0]
    assert isinstance(sd, ast.SystemDecl)
    assert [property_text(p) for p in sd.properties] == [
        "property p: always not (a.c in x and b.c in y)",
        "property q: whenever a.c in x eventually a.c.n >= 2"]


def test_the_new_keywords_are_reserved() -> None:
    for word in ("in", "property", "always", "whenever", "eventually"):
        result = parse(SourceFile("x.rssm", f"const {word}: int = 1"))
        assert [d.code for d in result.diagnostics] == ["E005"], word


def test_formatting_lays_out_properties(tmp_path: Path) -> None:
    props = ("property  p1 :always not(a.c in idle and b.c in serve)   // comment\n"
             "property p2: whenever a.c in work\n   eventually   b.main in wait")
    text = SPEC.replace("PROPS", props)
    formatted = format_text(text).text
    assert formatted is not None
    assert ("  property p1: always not (a.c in idle and b.c in serve)  // comment\n"
            "  property p2: whenever a.c in work\n"
            "      eventually b.main in wait\n}\n") in formatted
    assert format_text(formatted).text == formatted


# ---------------------------------------------------------------------- the model


def test_the_model_holds_the_properties(tmp_path: Path) -> None:
    comp = _ok(tmp_path, """
  property safe: always not (a.c in work and b.c in serve)
  property answered: whenever b.main in wait eventually b.c in serve or a.c.busy
""")
    assert comp.system is not None
    safe, answered = comp.system.properties
    assert (safe.name, safe.kind) == ("safe", "always")
    assert safe.condition is not None and safe.trigger is None and safe.goal is None
    assert safe.expressions == (safe.condition,)
    assert (answered.name, answered.kind) == ("answered", "response")
    assert answered.expressions == (answered.trigger, answered.goal)
    text = (tmp_path / "plant.rssm").read_text(encoding="utf-8")
    assert text[safe.name_span.offset:safe.name_span.end_offset] == "safe"
    assert text[safe.span.offset:safe.span.end_offset].startswith("safe: always not")


def test_properties_do_not_change_the_net(tmp_path: Path) -> None:
    plain = _ok(tmp_path, "")
    with_props = _ok(tmp_path, "  property safe: always not (a.c in work and b.c in serve)")
    assert plain.hpn is not None and with_props.hpn is not None
    assert dump_text(with_props.hpn) == dump_text(plain.hpn)


def test_atoms_are_resolved_in_order(tmp_path: Path) -> None:
    comp = _ok(tmp_path, """
  property p: always not (a.c in work and b.main in serve) or a.motor.speed > 0.0
      or a.c.pose.x < a.c.gain and a.c.q[1] == 0.0 or b.c.ready or a.c in work
""", warnings=("W626",))
    assert comp.system is not None
    [p] = comp.system.properties
    assert p.condition is not None
    found = atoms(comp.system, p.condition)
    shown = [(type(x).__name__, x.subsystem_id,
              x.behaviour if isinstance(x, InBehaviour) else x.variable_name) for x in found]
    assert shown == [("InBehaviour", "a.c", "work"), ("InBehaviour", "b.c", "serve"),
                     ("Value", "a.e.motor", "speed"), ("Value", "a.c", "pose"),
                     ("Value", "a.c", "q"), ("Value", "b.c", "ready"),
                     ("InBehaviour", "a.c", "work")]
    values = [x for x in found if isinstance(x, Value)]
    assert [(v.kind, v.type) for v in values] == [
        ("output", FLOAT), ("memory", RecordT("Pose", (("x", FLOAT), ("ok", BOOL)))),
        ("memory", ArrayT(FLOAT, 3)), ("memory", BOOL)]
    text = (tmp_path / "plant.rssm").read_text(encoding="utf-8")
    assert [text[x.span.offset:x.span.end_offset] for x in found] == [
        "a.c in work", "b.main in serve", "a.motor.speed", "a.c.pose", "a.c.q", "b.c.ready",
        "a.c in work"]


def test_atoms_of_an_unresolved_expression_raise(tmp_path: Path) -> None:
    comp = _ok(tmp_path, "")
    assert comp.system is not None
    with pytest.raises(PropertyError, match="no behaviour 'nap'"):
        atoms(comp.system, _condition("a.c in nap"))


# ---------------------------------------------------------------------- evaluation


def _state(behaviours: dict[str, str], values: dict[tuple[str, str], Any]
           ) -> tuple[Any, Any]:
    def in_behaviour(sub: str, beh: str) -> bool:
        return behaviours[sub] == beh

    def value(sub: str, name: str) -> Any:
        return values[sub, name]

    return in_behaviour, value


def test_evaluate_an_invariant_over_behaviours(tmp_path: Path) -> None:
    comp = _ok(tmp_path, "  property safe: always not (a.c in work and b.c in serve)")
    assert comp.system is not None
    [p] = comp.system.properties
    assert p.condition is not None
    f = Formula(comp.system, p.condition)
    for a_beh, b_beh, holds in (("idle", "wait", True), ("work", "wait", True),
                                ("idle", "serve", True), ("work", "serve", False)):
        in_b, value = _state({"a.c": a_beh, "b.c": b_beh, "a.e.motor": "relay"}, {})
        assert f(in_b, value) is holds, (a_beh, b_beh)
        assert evaluate(comp.system, p.condition, in_b, value) is holds


def test_evaluate_values_parameters_and_constants(tmp_path: Path) -> None:
    comp = _ok(tmp_path, """
  property p: always a.c.n <= limit + a.c.tries or a.c.pose.x * a.c.gain > 10.0
  property r: whenever a.c in work eventually a.c.q[2] == 1 and not a.c.busy
""", warnings=("W626",))
    assert comp.system is not None
    p, r = comp.system.properties
    assert p.condition is not None and r.trigger is not None and r.goal is not None
    f = Formula(comp.system, p.condition)
    assert [type(x).__name__ for x in f.atoms] == ["Value", "Value"]  # gain, tries: params
    pose = {"x": 3.0, "ok": True}
    in_b, _ = _state({"a.c": "idle"}, {})
    assert f(in_b, _state({}, {("a.c", "n"): 5, ("a.c", "pose"): pose})[1]) is True
    assert f(in_b, _state({}, {("a.c", "n"): 6, ("a.c", "pose"): pose})[1]) is False
    pose = {"x": 4.5, "ok": True}     # 4.5 * 2.5 > 10
    assert f(in_b, _state({}, {("a.c", "n"): 6, ("a.c", "pose"): pose})[1]) is True
    goal = Formula(comp.system, r.goal)
    q = (0.0, 0.0, 1.0)       # converted to the interpreter's float array
    assert goal(in_b, _state({}, {("a.c", "q"): q, ("a.c", "busy"): False})[1]) is True
    assert goal(in_b, _state({}, {("a.c", "q"): q, ("a.c", "busy"): True})[1]) is False
    with pytest.raises(PropertyError, match=r"a\.c\.q is not a float\[3\]"):
        goal(in_b, _state({}, {("a.c", "q"): (1.0, 2.0), ("a.c", "busy"): True})[1])
    trigger = Formula(comp.system, r.trigger)
    assert trigger(_state({"a.c": "work"}, {})[0], _state({}, {})[1]) is True


def test_evaluate_asks_each_atom_once_and_reports_unknown_values(tmp_path: Path) -> None:
    comp = _ok(tmp_path, "  property p: always a.c in work or a.c in work or b.c.ready")
    assert comp.system is not None
    [p] = comp.system.properties
    assert p.condition is not None
    f = Formula(comp.system, p.condition)
    asked: list[tuple[str, str]] = []

    def in_behaviour(sub: str, beh: str) -> bool:
        asked.append((sub, beh))
        return False

    def value(sub: str, name: str) -> Any:
        asked.append((sub, name))
        return True

    assert f(in_behaviour, value) is True
    assert asked == [("a.c", "work"), ("b.c", "ready")]

    def unknown(sub: str, name: str) -> Any:
        raise KeyError(name)

    with pytest.raises(UnknownValue, match=r"b\.c\.ready"):
        f(in_behaviour, unknown)
    with pytest.raises(UnknownValue, match=r"b\.c\.ready"):
        f(in_behaviour, lambda sub, name: None)


def test_evaluate_fails_like_the_interpreter(tmp_path: Path) -> None:
    comp = _ok(tmp_path, "  property p: always 10 % a.c.n >= 0", warnings=("W626",))
    assert comp.system is not None
    [p] = comp.system.properties
    assert p.condition is not None
    in_b, value = _state({}, {("a.c", "n"): 0})
    with pytest.raises(EvalError):
        evaluate(comp.system, p.condition, in_b, value)
    assert evaluate(comp.system, p.condition, in_b, _state({}, {("a.c", "n"): 3})[1]) is True
    # Python's remainder, as in the interpreter: 10 % -3 == -2
    assert evaluate(comp.system, p.condition, in_b, _state({}, {("a.c", "n"): -3})[1]) is False


# ---------------------------------------------------------------------- diagnostics


@pytest.mark.parametrize(("props", "expected"), [
    ("property p: always b.c in serve and bb.c in wait",
     ("E620", "'bb' is not an agent of system 'plant'")),
    ("property p: always a.motr in relay",
     ("E620", "agent 'a' has no subsystem 'motr'")),
    ("property p: always (a.c.n + 1) in idle", ("E620", "'a.c.n + 1' is not a subsystem")),
    ("property p: always a.c.busy in idle", ("E620", "'a.c.busy' is not a subsystem")),
    ("property p: always a.c in iddle", ("E621", "a.c has no behaviour 'iddle'")),
    ("property p: always b.main in work", ("E621", "b.c has no behaviour 'work'")),
    ("property p: always a.c.bussy", ("E622", "a.c has no variable 'bussy'")),
    ("property p: always busy", ("E622", "'busy' is not a constant; a property reads a "
                                 "subsystem's variable as SUBSYSTEM.NAME")),
    ("property p: always not a.c", ("E622", "'a.c' is a subsystem, not a value")),
    ("property p: always a", ("E622", "'a' is an agent, not a value")),
    ("property p: always a.c.n + 1", ("E623", "the condition of property 'p' is int, not bool")),
    ("property p: whenever a.c.pose eventually a.c in idle",
     ("E623", "the trigger of property 'p' is Pose, not bool")),
    ("property p: always a.c in idle\n  property p: always a.c in work",
     ("E624", "property 'p' is declared twice")),
])
def test_property_errors(tmp_path: Path, props: str, expected: tuple[str, str]) -> None:
    comp = _compile(tmp_path, "  " + props)
    assert [(c, m) for c, m in _codes(comp) if c.startswith("E")] == [expected]
    assert comp.system is not None and comp.hpn is None


def test_property_errors_have_hints(tmp_path: Path) -> None:
    comp = _compile(tmp_path, "  property p: always a.c in iddle or a.c.bussy or bb.c in wait"
                              " or a.motr in relay")
    hints = {d.code + " " + d.message: d.hint for d in comp.diagnostics}
    assert hints == {
        "E621 a.c has no behaviour 'iddle'": "did you mean 'idle'?",
        "E622 a.c has no variable 'bussy'": "did you mean 'busy'?",
        "E620 'bb' is not an agent of system 'plant'":
            "write a subsystem as AGENT.SUBSYSTEM, e.g. `a.c`",
        "E620 agent 'a' has no subsystem 'motr'": "did you mean 'a.motor'?",
    }
    comp = _compile(tmp_path, "  property p: always busy")
    assert [d.hint for d in comp.diagnostics] == ["write `a.c.busy`"]


def test_a_type_error_inside_a_property_is_reported_once(tmp_path: Path) -> None:
    comp = _compile(tmp_path, "  property p: always a.c.busy + 1 > 0")
    assert [c for c, _ in _codes(comp)] == ["E203"]


def test_a_property_cannot_call_an_external_operation(tmp_path: Path) -> None:
    spec = 'extern far(x: float) -> bool = "math:isinf"\n'
    path = tmp_path / "plant.rssm"
    path.write_text(spec + SPEC.replace("PROPS", "  property p: always far(a.c.pose.x)"),
                    encoding="utf-8")
    comp = compile_file(path)
    assert _codes(comp) == [("E103", "'far' is an external operation; a property cannot "
                                     "call one")]


def test_in_outside_a_property(tmp_path: Path) -> None:
    text = SPEC.replace("terminal done when n > tries and busy",
                        "terminal done when n > tries and busy and not b.c in serve")
    text = text.replace("PROPS", "")
    path = tmp_path / "plant.rssm"
    path.write_text(text, encoding="utf-8")
    comp = compile_file(path)
    assert _codes(comp) == [("E625", "'b.c in serve' tests which behaviour a subsystem is in; "
                                     "that is only meaningful in a property")]


def test_values_without_a_finite_domain_are_warned_about_once(tmp_path: Path) -> None:
    comp = _compile(tmp_path, """
  property p: always a.c.n >= 0 and a.c.n < 100 and a.c.busy and a.c.pose.ok
      and a.c.gain > 0.0 and limit > 0
""")
    assert comp.ok and comp.system is not None and len(comp.system.properties) == 1
    warnings = [(d.code, d.message.split(":")[0]) for d in comp.diagnostics]
    assert warnings == [("W626", "property 'p' reads a.c.n (int)"),
                        ("W626", "property 'p' reads a.c.pose (Pose)")]
    assert all("the property is checked with that value abstracted" in d.message
               for d in comp.diagnostics)


def test_what_properties_read_counts_as_used(tmp_path: Path) -> None:
    # b.c.ready is written, and read by no behaviour
    text = SPEC.replace("terminal tick when ready", "terminal tick when true")
    text = text.replace("terminal served when not ready", "terminal served when true")
    path = tmp_path / "plant.rssm"
    path.write_text(text.replace("PROPS", ""), encoding="utf-8")
    assert [d.code for d in compile_file(path).diagnostics] == ["W702"]
    path.write_text(text.replace("PROPS", "  property p: always b.c.ready or b.c in wait"),
                    encoding="utf-8")
    assert compile_file(path).diagnostics == ()


def test_the_handover_with_two_properties_resolves_them(tmp_path: Path) -> None:
    text = (EXAMPLES / "verify" / "handover.rssm").read_text(encoding="utf-8")
    path = tmp_path / "handover.rssm"
    path.write_text(text.rstrip().removesuffix("}") + """
  property no_stale_clamp: always not (base.c in unload and base.c.clamped)
  property delivered: whenever arm.c in release eventually base.c in deliver
}
""", encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok and not comp.diagnostics and comp.system is not None
    always, response = comp.system.properties
    assert always.kind == "always" and response.kind == "response"
    assert always.condition is not None
    assert response.trigger is not None and response.goal is not None
    assert atoms(comp.system, response.trigger) == [
        InBehaviour("arm.c", "release", response.trigger.span)]
    assert atoms(comp.system, response.goal) == [
        InBehaviour("base.c", "deliver", response.goal.span)]
    found = atoms(comp.system, always.condition)
    assert [(type(x).__name__, x.subsystem_id) for x in found] == [
        ("InBehaviour", "base.c"), ("Value", "base.c")]
    value = found[1]
    assert isinstance(value, Value)
    assert (value.variable_name, value.type, value.kind) == ("clamped", BOOL, "output")
    f = Formula(comp.system, always.condition)

    def in_unload(sub: str, beh: str) -> bool:
        return beh == "unload"

    assert f(in_unload, lambda sub, name: False) is True
    assert f(in_unload, lambda sub, name: True) is False
