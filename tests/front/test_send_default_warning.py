"""W611: a behaviour that sends, by default, an output it never updates, to a consumer that
reacts to fresh data (`case new(x)` of the input it feeds). Every output is sent in every
iteration of every behaviour (docs/language.md, "Buffers and channels"), so such a behaviour
sends the last value again each time, and the consumer takes it as new. The warning's rule,
its exceptions, and that an incremental analysis (the language server's) gives the same
warnings as a full one."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.lsp.analysis import Analysis, analyze_text
from rssm_dsl.pipeline import compile_file
from rssm_dsl.semantics.loader import display_path
from tests.conftest import ROOT

# A robot asks a changer for a tool change: `request` sends true once, `wait` should send
# false. The changer reacts to new(change) only.
SPEC = """\
system tool_change {
  agent robot {
    control @ 10 Hz {
      input done: 0..3 from changer.c
      output change: bool to changer.c blocking
      memory asked: 0..3 = 0

      behaviour request {
        update change { change := true }
        update memory { asked := (asked + 1) % 4 }
        terminal sent when true
      }

      behaviour wait {
        WAIT_UPDATE
        terminal answered when done == asked
        WAIT_SEND
      }

      initial request
      switch request -> wait when sent
      switch wait -> request when answered
    }
  }

  agent changer {
    control @ 10 Hz {
      input change: bool from robot.c
      output done: 0..3 to robot.c
      memory asked: bool = false

      behaviour idle {
        update memory {
          CHANGER_CASES
        }
        terminal requested when asked
      }

      behaviour report {
        update done { done := (done + 1) % 4 }
        terminal reported when true
      }

      initial idle
      switch idle -> report when requested
      switch report -> idle when reported
    }
  }
}
"""
LATCH = "case new(change):\n            asked := change\n          otherwise:\n" \
        "            asked := false"


def _spec(wait_update: str = "", wait_send: str = "", cases: str = LATCH) -> str:
    return (SPEC.replace("WAIT_UPDATE", wait_update).replace("WAIT_SEND", wait_send)
            .replace("CHANGER_CASES", cases))


def _diagnostics(tmp_path: Path, text: str) -> list[Diagnostic]:
    path = tmp_path / "spec.rssm"
    path.write_text(text, encoding="utf-8")
    comp = compile_file(path)
    assert comp.ok, [d.message for d in comp.diagnostics]
    return list(comp.diagnostics)


def test_a_request_sent_again_by_default_is_warned_about(tmp_path: Path) -> None:
    found = _diagnostics(tmp_path, _spec())
    assert [d.code for d in found] == ["W611"]
    d = found[0]
    assert d.message == ("behaviour 'wait' of robot.c sends output 'change' in every "
                         "iteration without updating it: changer.c gets its last value again "
                         "each time, and new(change) holds for it")
    assert (d.span.line, d.span.column) == (14, 17)      # the behaviour's name
    assert d.hint is not None and "update change" in d.hint and "`send`" in d.hint


@pytest.mark.parametrize(("case", "text"), [
    ("the behaviour updates it", _spec(wait_update="update change { change := false }")),
    ("an explicit send arrangement", _spec(wait_send="send change")),
    ("a consumer that reads the value, not new()",
     _spec(cases="asked := change")),
])
def test_no_warning(case: str, text: str, tmp_path: Path) -> None:
    assert [d.code for d in _diagnostics(tmp_path, text)] == [], case


def test_an_update_that_never_assigns_is_no_update(tmp_path: Path) -> None:
    text = _spec(wait_update="update change {\n          let x = 1\n          skip\n        }")
    assert [d.code for d in _diagnostics(tmp_path, text)] == ["W611"]


def test_an_update_that_assigns_in_some_case_is_an_update(tmp_path: Path) -> None:
    text = _spec(wait_update="update change {\n          case new(done):\n"
                 "            change := false\n          otherwise:\n            skip\n"
                 "        }")
    # now the robot reacts to new(done), so the changer's `idle`, which sends `done`
    # without updating it, is warned about instead
    found = _diagnostics(tmp_path, text)
    assert [(d.code, d.message.split(" in every")[0]) for d in found] == [
        ("W611", "behaviour 'idle' of changer.c sends output 'done'")]


def test_an_output_no_behaviour_writes_is_w701_not_w611(tmp_path: Path) -> None:
    text = _spec().replace("        update change { change := true }\n", "")
    assert [d.code for d in _diagnostics(tmp_path, text)] == ["W701"]


def test_outputs_to_devices_and_to_consumers_of_values_are_not_warned_about() -> None:
    # every example: set points re-sent to effectors and devices, levels re-sent to
    # supervisors; the palletizer's heartbeat says it is meant with its `send` arrangements
    for spec in sorted((ROOT / "examples").rglob("*.rssm")):
        if "diagnostics" in spec.parts:
            continue
        assert "W611" not in {d.code for d in compile_file(spec).diagnostics}, spec


def test_once_per_agent_definition(tmp_path: Path) -> None:
    text = """\
agent Station(next: agent, prev: agent) {
  control @ 10 Hz {
    input part: bool from prev.c
    output pass_on: bool to next.c
    memory holding: bool = false

    behaviour take {
      update pass_on { pass_on := false }
      update memory {
        case new(part):
          holding := part
        otherwise:
          skip
      }
      terminal got when holding
    }

    behaviour give {
      update pass_on { pass_on := true }
      update memory { holding := false }
      terminal given when true
    }

    behaviour rest {
      terminal rested when true
    }

    initial take
    switch take -> give when got
    switch give -> rest when given
    switch rest -> take when rested
  }
}

system ring {
  agent s1: Station(next = s2, prev = s3)
  agent s2: Station(next = s3, prev = s1)
  agent s3: Station(next = s1, prev = s2)
}
"""
    found = _diagnostics(tmp_path, text)
    assert [d.code for d in found] == ["W611"]
    assert found[0].message.startswith("behaviour 'rest' of s1.c sends output 'pass_on'")
    assert found[0].message.endswith("(and in 2 more instances of Station)")


def test_the_check_command_exits_0_with_the_warning(tmp_path: Path) -> None:
    path = tmp_path / "spec.rssm"
    path.write_text(_spec(), encoding="utf-8")
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", "check", str(path)],
                         capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert run.returncode == 0
    assert "warning[W611]" in run.stdout + run.stderr


def _codes(text: str, previous: Analysis | None, version: int) -> tuple[Analysis, list[str]]:
    path = Path("/tmp/rssm-w611-test/spec.rssm")
    got = analyze_text("file:///spec", path, display_path(path), text, version, {}, previous)
    return got, [f"{d.code}:{d.span.line}" for d in got.diagnostics]


def test_an_incremental_analysis_warns_as_a_full_one() -> None:
    """The check's work is reused for an agent the edit left alone: an edit of the consumer
    (it stops testing new()) or of the producer (it updates the output) must be seen."""
    texts = [
        _spec(),
        _spec().replace("asked := false\n", "asked := false  // a comment\n"),
        _spec(cases="asked := change"),                     # the consumer reads the value
        _spec(),
        _spec(wait_update="update change { change := false }"),
        _spec(),
    ]
    previous: Analysis | None = None
    hows = []
    for version, text in enumerate(texts, start=1):
        step, incremental = _codes(text, previous, version)
        _, full = _codes(text, None, version)
        assert incremental == full, (version, incremental, full)
        hows.append(step.how)
        previous = step
    assert hows[1:] == ["incremental"] * (len(texts) - 1)
    assert [_codes(t, None, 1)[1] for t in texts[:3]] == [["W611:14"], ["W611:14"], []]
