"""E306's hint offers a peer buffer of the buffer's own type (issue 32: it offered the first
candidate, of another type, whose pairing would then be E305)."""

from __future__ import annotations

from pathlib import Path

from rssm_dsl.pipeline import compile_file

SPEC = """
device effector Gripper @ 100 Hz {
  input width: float nonblocking
  input closed: bool nonblocking
}

system two_finger {
  agent hand {
    control @ 20 Hz {
      output shut: bool to e.gripper
      behaviour hold {
        update shut {
          shut := true
        }
        terminal never when false
      }
      initial hold
    }
    effector gripper @ 100 Hz {
      input shut: bool from c
      output command: TYPE to E.gripper
      behaviour follow {
        update command {
          command := VALUE
        }
        terminal never when false
      }
      initial follow
    }
    real effector gripper: Gripper
  }
}
"""


def _hint(tmp_path: Path, type_: str, value: str) -> str:
    path = tmp_path / "g.rssm"
    path.write_text(SPEC.replace("TYPE", type_).replace("VALUE", value), encoding="utf-8")
    [e] = [d for d in compile_file(path).diagnostics if d.code == "E306"]
    return e.hint or ""


def test_the_example_is_of_the_buffers_type(tmp_path: Path) -> None:
    assert "`E.gripper.closed`" in _hint(tmp_path, "bool", "shut")
    assert "`E.gripper.width`" in _hint(tmp_path, "float", "0.05")


def test_no_candidate_of_the_type_is_said(tmp_path: Path) -> None:
    assert "none of them is of type int" in _hint(tmp_path, "int", "1")
