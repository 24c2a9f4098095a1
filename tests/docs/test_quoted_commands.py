"""Every `$ rssmc ...` block in the README and docs/ is run, and each line it quotes must be
in what the command prints, in order: the same words, and the same numbers within 1 %
(counts and values the run computes); a line about time or memory may show any numbers.
`...` stands for lines left out; a quoted line ending in `...` is a prefix."""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
NUMBER = re.compile(r"-?\d[\d,]*(?:\.\d+)?")
MACHINE = re.compile(r"\d s\b|\d\.\d+ s\b|\bMB\b|\bGB\b|real time|wall|peak|per second|states/s")
# blocks whose output depends on the machine's speed by design (a time limit reached)
SPEED = {"rssmc verify lean64.rssm --reduction compositional --timeout 15"}


def _blocks() -> list[tuple[str, str, list[str]]]:
    found = []
    for doc in DOCS:
        text = doc.read_text(encoding="utf-8")
        for block in re.findall(r"```[^\n]*\n(.*?)```", text, re.S):
            lines = block.rstrip("\n").splitlines()
            if lines and lines[0].startswith("$ rssmc "):
                found.append((doc.relative_to(ROOT).as_posix(), lines[0][2:], lines[1:]))
    return found


BLOCKS = _blocks()


def _skeleton(line: str) -> str:
    return NUMBER.sub("#", line.strip())


def _matches(want: str, got: str) -> bool:
    prefix = want.rstrip().endswith("...")
    w = want.rstrip()[:-3].rstrip() if prefix else want
    g = got[:len(got)] if not prefix else got
    ws, gs = _skeleton(w), _skeleton(g)
    if not (gs.startswith(ws) if prefix else gs == ws):
        return False
    if MACHINE.search(w):
        return True
    return all(abs(a - b) <= max(0.01 * abs(a), 1e-3) for a, b in zip(
        (float(n.replace(",", "")) for n in NUMBER.findall(w)),
        (float(n.replace(",", "")) for n in NUMBER.findall(g)), strict=False))


def test_the_docs_quote_commands() -> None:
    assert len(BLOCKS) >= 5


@pytest.mark.parametrize(("doc", "command", "quoted"), BLOCKS,
                         ids=[f"{d}: {c}" for d, c, _ in BLOCKS])
def test_a_quoted_command_prints_what_the_doc_says(doc: str, command: str,
                                                   quoted: list[str], tmp_path: Path) -> None:
    if command in SPEED:
        pytest.skip("its output is where a time limit stopped it, which depends on the machine")
    args = shlex.split(command)[1:]
    run = subprocess.run([sys.executable, "-m", "rssm_dsl", *args], capture_output=True,
                         text=True, timeout=600, cwd=ROOT)
    printed = (run.stdout + run.stderr).splitlines()
    at = 0
    for want in quoted:
        if want.strip() in ("...", ""):
            continue
        for k in range(at, len(printed)):
            if _matches(want, printed[k]):
                at = k + 1
                break
        else:
            raise AssertionError(f"{doc}: `{command}` does not print (after line {at}):\n"
                                 f"  {want}\nit prints:\n" + "\n".join(printed[:80]))
