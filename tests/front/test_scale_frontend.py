"""The front end is linear in its input (issue 32, item 3): one test per family of
bench/frontend_scale.py (many small agents, many buffers between two subsystems, many
switches that may overlap, many case clauses with errors), each stating what the result is
and, where it is natural, a bound on a count of operations; no test measures time. Also the
checks that came with it: W604 is not reported for conditions that test one enum or bool
value exclusively, E306's hint offers only buffers of the buffer's type, and the JSON IR is
the text `json.dumps(..., indent=1)` writes."""

from __future__ import annotations

import json
import random
from pathlib import Path

import pytest

from rssm_dsl.diagnostics import Diagnostic, DiagnosticBag
from rssm_dsl.emit.json_ir import dumps, emit_json, to_json
from rssm_dsl.pipeline import Compilation, compile_file
from rssm_dsl.semantics.channels import ChannelPass
from rssm_dsl.semantics.model import Buffer
from rssm_dsl.semantics.structure import Shell
from rssm_dsl.syntax import ast
from rssm_dsl.synth import (
    erroneous_cases_system,
    many_buffers_system,
    overlapping_switches_system,
    small_agents_system,
)
from tests.conftest import ROOT


def _compile(tmp_path: Path, text: str, name: str = "s.rssm") -> Compilation:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return compile_file(path)


def _counting_resolves(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    calls = [0]
    resolve = ChannelPass._resolve

    def counted(self: ChannelPass, owner: Shell, peer: ast.PeerRef,
                report: bool = True) -> tuple[Shell, str | None] | None:
        calls[0] += 1
        return resolve(self, owner, peer, report)

    monkeypatch.setattr(ChannelPass, "_resolve", counted)
    return calls


# ---------------------------------------------------------------- the four families

def test_many_small_agents_compile_to_a_net_linear_in_them(tmp_path: Path) -> None:
    sizes = {}
    for n in (20, 80):
        comp = _compile(tmp_path, small_agents_system(n), f"a{n}.rssm")
        assert comp.diagnostics == () and comp.hpn is not None and comp.system is not None
        assert len(comp.system.channels) == n
        h = comp.hpn
        sizes[n] = (len(h.pages), len(h.places), len(h.transitions), len(h.arcs))
    # the system's own elements plus the same number per agent
    per_agent = [(b - a) / 60 for a, b in zip(sizes[20], sizes[80], strict=True)]
    assert all(x == int(x) for x in per_agent)
    assert sizes[80] == tuple(a + 60 * int(p) for a, p in zip(sizes[20], per_agent, strict=True))


@pytest.mark.parametrize("n", [40, 400])
def test_many_buffers_between_two_subsystems_pair_once_each(
        n: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    calls = _counting_resolves(monkeypatch)
    comp = _compile(tmp_path, many_buffers_system(n))
    assert comp.system is not None
    pairs = {(c.producer.name, c.consumer.name) for c in comp.system.channels}
    assert pairs == {(f"b{i}", f"b{i}") if i % 2 == 0 else (f"o{i}", f"i{i}")
                     for i in range(n)}
    # only the inputs, never read
    assert [d.code for d in comp.diagnostics] == ["W701"] * n
    # each buffer's peer is resolved once reporting and once silently (it was resolved
    # again for every candidate of every buffer: cubic)
    assert calls[0] <= 2 * 2 * n


def test_overlapping_switches_are_reported_once_per_switch(tmp_path: Path) -> None:
    n = 300
    comp = _compile(tmp_path, overlapping_switches_system(n))
    w604 = [d for d in comp.diagnostics if d.code == "W604"]
    assert len(w604) == n - 1 and len(comp.diagnostics) == n - 1   # not n (n - 1) / 2
    first = w604[0].related[0].span
    for k, d in enumerate(sorted(w604, key=lambda d: d.span.line), start=1):
        # the k-th switch after the first overlaps the k switches before it: it names the
        # first (the one taken) and counts the others
        assert d.related[0].span == first
        assert d.message.startswith("switches from 'b' of a1.c overlap when 'done' ended it: both "
                                    "hold, and the one declared first is taken")
        assert d.message.endswith(
            "taken" if k == 1 else
            f"(this switch also overlaps {k - 1} other switch{'es' if k > 2 else ''} "
            "declared before it)")


def test_two_overlapping_switches_keep_their_warning(tmp_path: Path) -> None:
    [d] = _compile(tmp_path, overlapping_switches_system(2)).diagnostics
    assert d.code == "W604"
    assert d.message == ("switches from 'b' of a1.c overlap when 'done' ended it: both hold, and the "
                         "one declared first is taken")
    assert d.related[0].message == "this switch also holds, and is declared first: it is taken"


def test_many_case_clauses_with_errors(tmp_path: Path, monkeypatch: pytest.MonkeyPatch
                                       ) -> None:
    inspected = [0]
    is_error = Diagnostic.is_error

    def counted(self: Diagnostic) -> bool:
        inspected[0] += 1
        return bool(is_error.fget(self))  # type: ignore[attr-defined]

    monkeypatch.setattr(Diagnostic, "is_error", property(counted))
    n = 600
    comp = _compile(tmp_path, erroneous_cases_system(n))
    codes = [d.code for d in comp.diagnostics]
    # E506 (data in a case condition) and E503 (new() of no input) for every clause that
    # has them; the clauses `new(v)` all overlap the first: one E502 for the combination
    # they cover (a case stands for the first two clauses that cover it)
    assert codes.count("E506") == len(range(0, n, 3))
    assert codes.count("E503") == len(range(1, n, 3))
    assert codes.count("E502") == 1
    assert len(codes) == len(range(0, n, 3)) + len(range(1, n, 3)) + 1
    # whether a clause added an error is asked of the diagnostics it added, not of all
    # those so far (quadratic: 3,000 clauses took 8 s)
    assert inspected[0] <= 20 * n


# ---------------------------------------------------------------- the pairing is the rule

class _Reference(ChannelPass):
    """The pairing as it was written before the index (every candidate checked against
    every buffer): the rule of docs/language.md, "Pairing"."""

    def _candidates(self, shell: Shell, buf: Buffer, peer: Shell, opposite: ast.Direction
                    ) -> list[Buffer]:
        def points_back(b: Buffer) -> bool:
            if peer.device:
                return True
            ref = peer.peers.get(b.name)
            r = self._resolve(peer, ref, report=False) if ref is not None else None
            return r is not None and r[0] is shell and r[1] in (None, buf.name)

        def claimed(b: Buffer) -> bool:
            for other in shell.buffers:
                if other is buf or other.direction is not buf.direction:
                    continue
                ref = shell.peers.get(other.name)
                r = self._resolve(shell, ref, report=False) if ref is not None else None
                if r is not None and r[0] is peer and (
                        r[1] == b.name or (r[1] is None and other.name == b.name)):
                    return True
            return False

        out = [b for b in peer.buffers if b.direction is opposite and points_back(b)
               and not claimed(b)]
        same = [b for b in out if b.name == buf.name]
        return same if len(out) > 1 and same else out


def _random_buffers(rng: random.Random) -> str:
    names = ["a", "b", "q", "x", "y"]
    types = ["int", "float", "bool"]
    device = ("device effector Dev @ 100 Hz {\n  input u: float nonblocking\n"
              "  input a: int nonblocking\n  output w: float nonblocking\n}\n")
    agents = []
    for k in (1, 2):
        subs = ["c", "e.m"]
        decls = []
        for s in subs:
            peers = [p for p in subs if p != s] + (
                ["a2.c" if k == 1 else "a1.c"] if s == "c" else ["E.dev"])
            bufs = []
            for _ in range(rng.randint(0, 6)):
                d = rng.choice(["input", "output"])
                peer = rng.choice(peers)
                if rng.random() < 0.3:
                    peer += "." + rng.choice([*names, "u", "w"])
                bufs.append(f"      {d} {rng.choice(names)}: {rng.choice(types)} "
                            f"{'to' if d == 'output' else 'from'} {peer}\n")
            kind = "control" if s == "c" else "effector m"
            decls.append(f"    {kind} {{\n{''.join(bufs)}      behaviour r {{ terminal never "
                         "when false }\n      initial r\n    }\n")
        agents.append(f"  agent a{k} {{\n{''.join(decls)}    real effector dev: Dev\n  }}\n")
    return device + "system s {\n" + "".join(agents) + "}\n"


def test_the_indexed_pairing_pairs_as_the_rule_does(tmp_path: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    rng = random.Random(32)
    for i in range(150):
        text = _random_buffers(rng)
        fast = _compile(tmp_path, text, f"r{i}.rssm")
        with monkeypatch.context() as m:
            m.setattr("rssm_dsl.semantics.analyze.ChannelPass", _Reference)
            slow = _compile(tmp_path, text, f"r{i}.rssm")
        assert fast.diagnostics == slow.diagnostics, text
        assert (fast.system is None) == (slow.system is None)
        if fast.system is not None and slow.system is not None:
            assert fast.system.channels == slow.system.channels, text


# ---------------------------------------------------------------- W604: exclusive conditions

SWITCHING = """enum St { x, y, z }
system s {
  agent a1 {
    control {
      memory s: St = St.x
      memory flag: bool = false
      memory n: int = 0
      behaviour b {
        update memory { n := n + 1 }
TERMINALS
      }
      behaviour t1 { terminal never when false }
      behaviour t2 { terminal never when false }
      initial b
SWITCHES
    }
  }
}
"""


def _switching(tmp_path: Path, terminals: list[str], switches: list[str]) -> list[str]:
    text = (SWITCHING.replace("TERMINALS", "\n".join(f"        {t}" for t in terminals))
            .replace("SWITCHES", "\n".join(f"      {s}" for s in switches)))
    return sorted(d.code for d in _compile(tmp_path, text).diagnostics
                  if d.code in ("W604", "E603"))


@pytest.mark.parametrize(("terminals", "switches", "want"), [
    # terminal conditions that test one enum value exclude each other...
    (["terminal tx when s == St.x", "terminal ty when s == St.y"],
     ["switch b -> t1 when tx", "switch b -> t2 when ty"], []),
    (["terminal tx when s == St.x", "terminal ty when St.y == s", "terminal tz when s == St.z"],
     ["switch b -> t1 when tx", "switch b -> t2 when ty", "switch b -> end when tz"], []),
    (["terminal tx when s == St.x", "terminal nx when s != St.x"],
     ["switch b -> t1 when tx", "switch b -> t2 when nx"], []),
    # ... as do those that test one bool value
    (["terminal on when flag", "terminal off when not flag"],
     ["switch b -> t1 when on", "switch b -> t2 when off"], []),
    (["terminal on when flag", "terminal off when not flag"],
     ["switch b -> t1 when on", "switch b -> t2 when not flag"], []),
    # and comparisons of one value with bounds
    (["terminal low when n < 3", "terminal high when n > 3", "terminal mid when n == 3"],
     ["switch b -> t1 when low", "switch b -> t2 when high", "switch b -> end when mid"], []),
    # conditions that do not exclude each other still overlap
    (["terminal tx when s == St.x", "terminal big when n > 3"],
     ["switch b -> t1 when tx", "switch b -> t2 when big"], ["W604"]),
    (["terminal on when flag", "terminal again when flag"],
     ["switch b -> t1 when on", "switch b -> t2 when again"], ["W604"]),
    (["terminal tx when s == St.x", "terminal ty when s == St.y"],
     ["switch b -> t1 when tx", "switch b -> t2 when ty or n > 3",
      "switch b -> end otherwise"], ["W604"]),
])
def test_exclusive_conditions_do_not_overlap(terminals: list[str], switches: list[str],
                                             want: list[str], tmp_path: Path) -> None:
    assert _switching(tmp_path, terminals, switches) == want


# ---------------------------------------------------------------- E306: the hint's buffers

E306 = """device effector Hand @ 100 Hz {
  input width: float nonblocking
  input closed: bool nonblocking
  input force: float nonblocking
  input grip: bool nonblocking
}

system s {
  agent a1 {
    control {
      output go: bool to e.h
      behaviour r { update go { go := true } terminal never when false }
      initial r
    }
    effector h {
      input go: bool from c
      output cmd: TYPE to E.hand
      behaviour r { update cmd { cmd := VALUE } terminal never when false }
      initial r
    }
    real effector hand: Hand
  }
}
"""


def _e306_hint(tmp_path: Path, type_: str, value: str) -> str:
    comp = _compile(tmp_path, E306.replace("TYPE", type_).replace("VALUE", value))
    [e] = [d for d in comp.diagnostics if d.code == "E306"]
    assert e.message == ("several buffers of a1.E.hand could match 'cmd': width, closed, "
                         "force, grip")
    return e.hint or ""


def test_e306_offers_the_buffers_of_the_type_only(tmp_path: Path) -> None:
    hint = _e306_hint(tmp_path, "bool", "true")
    assert "`E.hand.closed`" in hint and "`E.hand.grip`" in hint
    assert "width" not in hint and "force" not in hint
    hint = _e306_hint(tmp_path, "float", "0.5")
    assert "`E.hand.width`" in hint and "`E.hand.force`" in hint
    assert "closed" not in hint and "grip" not in hint


def test_e306_offers_no_buffer_of_another_type(tmp_path: Path) -> None:
    hint = _e306_hint(tmp_path, "int", "1")
    assert "none of them is of type int" in hint
    assert not any(f"E.hand.{b}" in hint for b in ("width", "closed", "force", "grip"))


# ---------------------------------------------------------------- the JSON IR's text

def test_the_json_ir_is_the_standard_encoders_text(tmp_path: Path) -> None:
    texts = [(ROOT / "examples" / "lwr4_circle.rssm").read_text(encoding="utf-8"),
             small_agents_system(3), many_buffers_system(4), overlapping_switches_system(3)]
    for i, text in enumerate(texts):
        path = tmp_path / f"j{i}.rssm"
        path.write_text(text, encoding="utf-8")
        if i == 0:
            path = ROOT / "examples" / "lwr4_circle.rssm"
        hpn = compile_file(path).hpn
        assert hpn is not None
        [written] = emit_json(hpn).values()
        assert written == json.dumps(to_json(hpn), indent=1) + "\n"


def test_dumps_is_json_dumps_with_an_indent() -> None:
    rng = random.Random(7)
    scalars = [None, True, False, 0, -3, 2**70, 1.5, float("nan"), float("inf"),
               -float("inf"), "", "plain", 'q"uo\\te', "é\u2028\n"]
    keys = ["k", "é", "", 1, 2.5, True, None, 0, False]

    def value(depth: int) -> object:
        r = rng.random()
        if depth > 3 or r < 0.4:
            return rng.choice(scalars)
        if r < 0.7:
            return [value(depth + 1) for _ in range(rng.randint(0, 3))]
        if r < 0.8:
            return tuple(value(depth + 1) for _ in range(rng.randint(0, 3)))
        return {rng.choice(keys): value(depth + 1) for _ in range(rng.randint(0, 3))}

    for _ in range(2000):
        v = value(0)
        assert dumps(v) == json.dumps(v, indent=1)


def test_the_bag_is_not_rescanned(monkeypatch: pytest.MonkeyPatch) -> None:
    """DiagnosticBag is unchanged: the behaviour pass asks about the diagnostics a clause
    added (behaviours._errors_since), which this pins down."""
    from rssm_dsl.semantics.behaviours import _errors_since
    from rssm_dsl.source import Span

    bag = DiagnosticBag()
    at = Span("f", 1, 1, 1, 2)
    bag.error("E506", "x", at)
    mark = len(bag.items)
    assert not _errors_since(bag, mark)
    bag.warn("W604", "y", at)
    assert not _errors_since(bag, mark)
    bag.error("E503", "z", at)
    assert _errors_since(bag, mark)


def test_e306_names_a_few_candidates_and_counts_the_rest(tmp_path: Path) -> None:
    """A device with many inputs: the message names the first four and counts the others
    (the trial of issue 32 met a message listing every one)."""
    many = E306.replace("  input grip: bool nonblocking\n",
                        "  input grip: bool nonblocking\n  input tilt: float nonblocking\n"
                        "  input spin: float nonblocking\n")
    comp = _compile(tmp_path, many.replace("TYPE", "bool").replace("VALUE", "true"))
    [e] = [d for d in comp.diagnostics if d.code == "E306"]
    assert e.message == ("several buffers of a1.E.hand could match 'cmd': width, closed, "
                         "force, grip and 2 more")
