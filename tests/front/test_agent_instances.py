"""Agents defined once and instantiated (docs/language.md, "Agent definitions";
rssm_dsl/semantics/instances.py): what an instance line declares, which values each instance
has, where its diagnostics point, and that every backend sees one agent per instance."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.pipeline import compile_file
from rssm_dsl.syntax.format import format_text
from rssm_dsl.verify import VerifyOptions, verify
from rssm_dsl.verify.dataplan import value_plan
from tests.conftest import ROOT

FLEET = ROOT / "examples" / "fleet.rssm"

ROBOT = """
agent Robot(boss: agent, shift: 1..4 = 2) {
  control @ 10 Hz {
    input job: bool from boss.c blocking
    output busy: bool to boss.c nonblocking
    memory done: 0..4 = 0

    behaviour free {
      update busy {
        busy := false
      }
      update memory {
        done := 0
      }
      terminal hired when job
    }

    behaviour working {
      update busy {
        busy := true
      }
      update memory {
        done := done + 1
      }
      terminal shift_over when done >= shift
    }

    initial free
    switch free -> working when hired
    switch working -> free when shift_over
  }
}
"""


def _system(robots: str, coord_extra: str = "", props: str = "") -> str:
    """A coordinator sending jobs to r1, r2 and r3 (in turn), and the lines ``robots``."""
    return ROBOT + f"""
system crew {{
  agent coord {{
    control @ 10 Hz {{
      output job1: bool to r1.c nonblocking
      output job2: bool to r2.c nonblocking
      output job3: bool to r3.c nonblocking
      input busy1: bool from r1.c nonblocking
      input busy2: bool from r2.c nonblocking
      input busy3: bool from r3.c nonblocking
      memory turn: 0..2 = 0
{coord_extra}
      behaviour dispatch {{
        update job1 {{
          job1 := turn == 0 and not busy1
        }}
        update job2 {{
          job2 := turn == 1 and not busy2
        }}
        update job3 {{
          job3 := turn == 2 and not busy3
        }}
        update memory {{
          turn := (turn + 1) % 3
        }}
        terminal never when false
      }}
      initial dispatch
    }}
  }}
{robots}
{props}
}}
"""


def _compile(tmp_path: Path, text: str, name: str = "crew.rssm"):  # type: ignore[no-untyped-def]
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return compile_file(path)


def test_an_instance_is_its_definitions_agent_under_its_name() -> None:
    """examples/fleet.rssm: `agent r[1..6]: Robot(boss = coord)` declares r1..r6, each with
    the definition's control subsystem (its text, its span), `boss.c` read as `coord.c`,
    `shift` a parameter of its own (the default 2, or the instance's 3 and 4); the agents
    in the order of the text."""
    comp = compile_file(FLEET)
    assert comp.ok and comp.system is not None, comp.diagnostics
    agents = [a.name for a in comp.system.agents]
    assert agents == ["coord", *(f"r{k}" for k in range(1, 9))]
    shifts = {}
    for a in comp.system.agents[1:]:
        [c] = a.subsystems
        assert c.span.line < 40                 # the definition's text
        [job] = c.inputs
        assert job.peer == "coord.c"
        [shift] = c.params
        shifts[a.name] = shift.init.value if shift.init is not None else None  # type: ignore[attr-defined]
    assert shifts == {**{f"r{k}": 2 for k in range(1, 7)}, "r7": 3, "r8": 4}
    assert {ch.id for ch in comp.system.channels} >= {"coord.c.job8->r8.c.job",
                                                      "r8.c.busy->coord.c.busy8"}
    net = flatten(comp.hpn)      # type: ignore[arg-type]
    assert len(net.places) < 2_000                 # the issue: a few thousand at most


def test_each_instance_has_its_own_values(tmp_path: Path) -> None:
    """r1 and r2 take the default shift of 2, r3 a shift of 3: `done` reaches 3 in r3 alone
    (the verifier: the invariant of r3 is violated, those of r1 and r2 hold), and the
    counterexample replays in the interpreter (the same value there)."""
    comp = _compile(tmp_path, _system(
        "  agent r[1..2]: Robot(boss = coord)\n  agent r3: Robot(boss = coord, shift = 3)",
        props="  property r1_short: always r1.c.done <= 2\n"
              "  property r2_short: always r2.c.done <= 2\n"
              "  property r3_short: always r3.c.done <= 2"))
    assert comp.ok, comp.diagnostics
    net = flatten(comp.hpn)
    r = verify(net, VerifyOptions(values=value_plan(comp, net), time_limit=120))
    assert {p.name: p.holds for p in r.user_properties} == {
        "r1_short": True, "r2_short": True, "r3_short": False}
    report = tmp_path / "report.json"
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(tmp_path / "crew.rssm"),
                          "--format", "json"], capture_output=True, text=True, cwd=ROOT,
                         timeout=600)
    assert run.returncode == 1, run.stderr
    report.write_text(run.stdout, encoding="utf-8")
    replay = subprocess.run([sys.executable, "-m", "rssm_dsl", "simulate",
                             str(tmp_path / "crew.rssm"), "--replay", str(report),
                             "--format", "json"], capture_output=True, text=True, cwd=ROOT,
                            timeout=600)
    out = json.loads(replay.stdout)
    assert out["replay"]["reproduced"] is True, out["replay"]


def test_a_problem_in_a_definition_points_there_and_names_the_instance(
        tmp_path: Path) -> None:
    """The coordinator sends no job to r3: r3's `input job` has no partner. The error is
    at the definition's buffer, once, and names r3; r1 and r2 are fine."""
    text = _system("  agent r[1..3]: Robot(boss = coord)").replace(
        "      output job3: bool to r3.c nonblocking\n", "").replace(
        "        update job3 {\n          job3 := turn == 2 and not busy3\n        }\n", "")
    comp = _compile(tmp_path, text)
    errors = [d for d in comp.diagnostics if d.code == "E304"]
    assert len(errors) == 1, comp.diagnostics
    [e] = errors
    assert "r3.c" in e.message and "job" in e.message
    assert text.splitlines()[e.span.line - 1].strip().startswith("input job: bool from boss.c")


def test_instance_lines_that_do_not_fit_their_definition(tmp_path: Path) -> None:
    """E311-E313, each at the instance line, and the line declares no agent."""
    cases = {
        "  agent r[1..3]: Robto(boss = coord)": ("E311", "Robot"),
        "  agent r[1..3]: Robot(shift = 2)": ("E312", "boss"),
        "  agent r[1..3]: Robot(boss = coord, shoft = 2)": ("E312", "shift"),
        "  agent r[1..3]: Robot(boss = r9)": ("E312", "r9"),
        "  agent r[1..3]: Robot(boss = cord)": ("E312", "did you mean 'coord'"),
        "  agent r[1..3]: Robot(boss = coord.c)": ("E312", "`boss = coord`"),
        "  agent r[3..1]: Robot(boss = coord)": ("E313", "0 agents"),
        "  agent r[-1..3]: Robot(boss = coord)": ("E313", "negative"),
    }
    for line, (code, said) in cases.items():
        text = _system(line)
        comp = _compile(tmp_path, text)
        mine = [d for d in comp.diagnostics if d.code == code]
        assert mine, (line, comp.diagnostics)
        assert said in mine[0].message + (mine[0].hint or ""), (line, mine[0])
        assert text.splitlines()[mine[0].span.line - 1] == line
        assert comp.hpn is None
        # what names r1..r3 elsewhere (the coordinator's buffers) is not reported again
        assert {d.code for d in comp.diagnostics if d.is_error} == {code}, comp.diagnostics


def test_a_value_parameter_hidden_by_a_subsystems_own_name(tmp_path: Path) -> None:
    text = _system("  agent r[1..3]: Robot(boss = coord)").replace(
        "    memory done: 0..4 = 0\n", "    memory done: 0..4 = 0\n    memory shift: 1..4 = 2\n")
    comp = _compile(tmp_path, text)
    [e] = [d for d in comp.diagnostics if d.code == "E312"]
    assert "hides the parameter 'shift'" in e.message


def test_fmt_keeps_definitions_and_instance_lines() -> None:
    """The canonical layout of a definition is a block (its body indented by one level),
    the instance lines are one line each, and formatting twice changes nothing."""
    text = FLEET.read_text(encoding="utf-8")
    once = format_text(text).text
    assert once == text
    squashed = text.replace("agent Robot(boss: agent, shift: 1..4 = 2) {\n  control",
                            "agent   Robot( boss :agent,shift: 1..4=2 ){ control")
    again = format_text(squashed).text
    assert again == text


def test_a_problem_of_the_definition_is_reported_once(tmp_path: Path) -> None:
    """Each instance finds a problem of the definition's text again: it is reported once,
    with the first instance's name and the count of the others."""
    text = _system("  agent r[1..3]: Robot(boss = coord)").replace(
        "    memory done: 0..4 = 0\n", "    memory done: 0..4 = 0\n    memory spare: 0..4 = 0\n")
    comp = _compile(tmp_path, text)
    [w] = [d for d in comp.diagnostics if d.code == "W702"]
    assert "r1.c" in w.message and "and in 2 more instances of Robot" in w.message


def test_a_parameter_declared_twice(tmp_path: Path) -> None:
    text = _system("  agent r[1..3]: Robot(boss = coord)").replace(
        "agent Robot(boss: agent, shift", "agent Robot(boss: agent, boss: agent, shift")
    comp = _compile(tmp_path, text)
    [e] = [d for d in comp.diagnostics if d.code == "E101"]
    assert "parameter 'boss'" in e.message and e.span.line == 2
