"""`rssmc compile --emit mcc`: the Model Checking Contest's input (rssm_dsl/emit/mcc.py).

The property files are checked against the contest's property language as its tools read it
(the grammar below: the elements TAPAAL's verifypn reads in its QueryXMLParser, the fragments
of the examinations as the contest's formula generator documents them); every place they name
must be a place of the PNML; and the formulas are evaluated here, on the state space of
``model.pnml`` explored by a small explicit search of our own, to check they mean what
`rssmc verify` answers (deadlocks, `always`, `whenever ... eventually`).
"""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.conftest import EXAMPLES, ROOT

MCC = "{http://mcc.lip6.fr/}"
PNML = "{http://www.pnml.org/version-2009/grammar/pnml}"

# A system that can finish (both agents switch to `end`), is deadlock-free, and states two
# invariants and two responses over behaviours (one of each violated) and one over a value.
FINISHER = """// counts, rests and ends; the listener ends once it heard
system finisher {
  agent a {
    control c {
      memory i: int = 0
      output out: float to b.c nonblocking

      behaviour count {
        update memory { i := i + 1 }
        update out { out := 1.0 }
        terminal done when i > 3
        send out
      }
      behaviour rest {
        update memory { i := 0 }
        terminal stop when i == 0
      }
      initial count
      switch count -> rest when done
      switch rest -> end when stop
    }
  }
  agent b {
    control c {
      memory x: float = 0.0
      input inp: float from a.c nonblocking
      behaviour listen {
        update memory { x := inp }
        terminal heard when x > 0.5
      }
      initial listen
      switch listen -> end when heard
    }
  }
  property apart: always not (a.c in count and a.c in rest)
  property together: always a.c in count or b.c in listen
  property small: always a.c.i < 10
  property rests: whenever a.c in count eventually a.c in rest
  property counts_again: whenever a.c in rest eventually a.c in count
}
"""


def rssmc(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300)


# ------------------------------------------------------------------ the property language

PATHS = {"exists-path", "all-paths"}
TEMPORAL = {"finally", "globally", "next"}
CONNECTIVES = {"conjunction": 2, "disjunction": 2}        # at least that many operands
COMPARISONS = {"integer-le", "integer-lt", "integer-eq", "integer-ne", "integer-gt",
               "integer-ge"}


def _tag(e: ET.Element) -> str:
    assert e.tag.startswith(MCC), f"{e.tag} is not in the contest's namespace"
    return e.tag[len(MCC):]


def check_integer(e: ET.Element, places: list[str]) -> None:
    tag = _tag(e)
    if tag == "integer-constant":
        assert e.text is not None and int(e.text) >= 0 and len(e) == 0
    elif tag == "tokens-count":
        assert len(e) >= 1
        for p in e:
            assert _tag(p) == "place" and p.text and p.text.strip() and len(p) == 0
            places.append(p.text.strip())
    else:
        raise AssertionError(f"<{tag}> is not an integer expression")


def check_boolean(e: ET.Element, places: list[str], tags: list[str]) -> None:
    """The boolean formulas of the language, recursively; the tags met go to ``tags``."""
    tag = _tag(e)
    tags.append(tag)
    kids = list(e)
    if tag in PATHS or tag in TEMPORAL or tag == "negation":
        assert len(kids) == 1, f"<{tag}> takes one formula"
        check_boolean(kids[0], places, tags)
    elif tag in CONNECTIVES:
        assert len(kids) >= CONNECTIVES[tag], f"<{tag}> takes two formulas or more"
        for k in kids:
            check_boolean(k, places, tags)
    elif tag == "until":
        assert [_tag(k) for k in kids] == ["before", "reach"]
        for k in kids:
            assert len(k) == 1
            check_boolean(k[0], places, tags)
    elif tag in ("deadlock", "true", "false"):
        assert not kids and not (e.text or "").strip()
    elif tag in COMPARISONS:
        assert len(kids) == 2
        for k in kids:
            check_integer(k, places)
    else:
        raise AssertionError(f"<{tag}> is not a formula of the property language")


def check_property_set(path: Path, model: str, examination: str) -> list[ET.Element]:
    """The file's structure (property-set > property > id, description, formula); the
    formulas of the examination's fragment; every place a place of ``model.pnml``. Returns
    the formulas."""
    root = ET.parse(path).getroot()
    assert root.tag == f"{MCC}property-set"
    pnml_places = set(read_pnml(path.parent / "model.pnml")[0])
    formulas: list[ET.Element] = []
    ids = []
    for i, prop in enumerate(root):
        assert prop.tag == f"{MCC}property"
        assert [_tag(k) for k in prop] == ["id", "description", "formula"]
        pid = prop.findtext(f"{MCC}id")
        assert pid == f"{model}-{examination}-{i:02d}"
        ids.append(pid)
        formula = prop.find(f"{MCC}formula")
        assert formula is not None and len(formula) == 1
        places: list[str] = []
        tags: list[str] = []
        check_boolean(formula[0], places, tags)
        assert set(places) <= pnml_places, set(places) - pnml_places
        top = [_tag(formula[0]), _tag(formula[0][0])]
        state_tags = set(tags[2:])
        if examination == "ReachabilityDeadlock":
            assert tags == ["exists-path", "finally", "deadlock"]
        elif examination == "ReachabilityCardinality":
            assert top in (["exists-path", "finally"], ["all-paths", "globally"])
            assert not state_tags & (PATHS | TEMPORAL | {"deadlock", "until"})
        elif examination == "CTLCardinality":
            assert "deadlock" not in tags
            for q in formula[0].iter():      # CTL: a temporal operator under each quantifier
                if _tag(q) in PATHS:
                    assert len(q) == 1 and _tag(q[0]) in TEMPORAL | {"until"}
        formulas.append(formula[0])
    assert len(set(ids)) == len(ids) and ids
    return formulas


# ------------------------------------------------------------------ the net and its states

def read_pnml(path: Path) -> tuple[list[str], dict[str, tuple[set[str], set[str]]], set[str]]:
    """Places, transitions (id -> pre-set, post-set) and initially marked places of a
    one-page P/T net in PNML."""
    page = ET.parse(path).getroot().find(f"{PNML}net/{PNML}page")
    assert page is not None
    places = [p.attrib["id"] for p in page.iter(f"{PNML}place")]
    initial = {p.attrib["id"] for p in page.iter(f"{PNML}place")
               if p.find(f"{PNML}initialMarking") is not None}
    trans: dict[str, tuple[set[str], set[str]]] = {
        t.attrib["id"]: (set(), set()) for t in page.iter(f"{PNML}transition")}
    for a in page.iter(f"{PNML}arc"):
        src, dst = a.attrib["source"], a.attrib["target"]
        if dst in trans:
            trans[dst][0].add(src)
        else:
            trans[src][1].add(dst)
    return places, trans, initial


class StateSpace:
    """Every reachable marking of a safe net (breadth first), with its successors."""

    def __init__(self, path: Path) -> None:
        _, trans, initial = read_pnml(path)
        start = frozenset(initial)
        self.states: list[frozenset[str]] = [start]
        self.index = {start: 0}
        self.succ: list[list[int]] = []
        for m in self.states:         # grows while we walk it
            out = []
            for pre, post in trans.values():
                if pre <= m:
                    after = (m - pre) | post
                    if after not in self.index:
                        self.index[after] = len(self.states)
                        self.states.append(after)
                    out.append(self.index[after])
            self.succ.append(out)

    def ef(self, target: set[int]) -> set[int]:
        """The states from which some path reaches ``target``."""
        return self.eu(set(range(len(self.states))), target)

    def eu(self, before: set[int], reach: set[int]) -> set[int]:
        """E (before U reach): a path through ``before`` states to a ``reach`` state."""
        pred: list[list[int]] = [[] for _ in self.states]
        for s, out in enumerate(self.succ):
            for t in out:
                pred[t].append(s)
        seen, todo = set(reach), list(reach)
        while todo:
            for p in pred[todo.pop()]:
                if p not in seen and p in before:
                    seen.add(p)
                    todo.append(p)
        return seen

    def sat(self, e: ET.Element) -> set[int]:
        """The states where a CTL formula of the language holds."""
        tag, every = _tag(e), set(range(len(self.states)))
        if tag == "exists-path" and _tag(e[0]) == "until":
            before, reach = (self.sat(k[0]) for k in e[0])
            return self.eu(before, reach)
        if tag in ("exists-path", "all-paths"):
            op = _tag(e[0])
            inner = self.sat(e[0][0])
            if (tag, op) == ("exists-path", "finally"):
                return self.ef(inner)
            if (tag, op) == ("all-paths", "globally"):
                return every - self.ef(every - inner)
            raise AssertionError(f"{tag} {op} is not needed here")
            raise AssertionError(f"{tag} {op} is not needed here")
        if tag == "deadlock":
            return {s for s in every if not self.succ[s]}
        if tag == "true":
            return every
        if tag == "false":
            return set()
        if tag == "negation":
            return every - self.sat(e[0])
        if tag in ("conjunction", "disjunction"):
            parts = [self.sat(k) for k in e]
            out = parts[0]
            for p in parts[1:]:
                out = out & p if tag == "conjunction" else out | p
            return out
        if tag == "integer-le":
            lhs, rhs = (self._integer(k) for k in e)
            return {s for s in every if lhs(s) <= rhs(s)}
        raise AssertionError(f"<{tag}> is not needed here")

    def _integer(self, e: ET.Element) -> Callable[[int], int]:
        if _tag(e) == "integer-constant":
            value = int(e.text or "")
            return lambda s: value
        names = [p.text or "" for p in e]
        return lambda s: sum(1 for n in names if n in self.states[s])

    def holds(self, formula: ET.Element) -> bool:
        return 0 in self.sat(formula)


# ------------------------------------------------------------------ the tests

def compile_mcc(spec: Path, out: Path) -> Path:
    r = rssmc("compile", spec, "-o", out, "--emit", "pnml,mcc", "-q")
    assert r.returncode == 0, r.stderr
    return out / "mcc"


def verify_json(spec: Path) -> dict[str, object]:
    r = rssmc("verify", spec, "--format", "json", "--reduction", "off")
    assert r.returncode in (0, 1), r.stderr
    report: dict[str, object] = json.loads(r.stdout)
    return report


def test_deadlock_pair_files_and_meaning(tmp_path: Path) -> None:
    spec = EXAMPLES / "verify" / "deadlock_pair.rssm"
    mcc = compile_mcc(spec, tmp_path)
    assert sorted(p.name for p in mcc.iterdir()) == [
        "README.txt", "ReachabilityDeadlock.xml", "model.pnml"]   # it states no property
    (formula,) = check_property_set(mcc / "ReachabilityDeadlock.xml", "handshake",
                                    "ReachabilityDeadlock")
    space = StateSpace(mcc / "model.pnml")
    assert space.holds(formula)                     # EF deadlock: TRUE
    assert verify_json(spec)["deadlock_free"] is False


def test_model_pnml_is_the_flat_pnml_with_a_loop_on_the_final_place(tmp_path: Path) -> None:
    spec = EXAMPLES / "verify" / "deadlock_pair.rssm"
    mcc = compile_mcc(spec, tmp_path)
    places, trans, initial = read_pnml(mcc / "model.pnml")
    flat_places, flat_trans, flat_initial = read_pnml(tmp_path / "handshake.pnml")
    assert places == flat_places and initial == flat_initial
    extra = set(trans) - set(flat_trans)
    assert len(extra) == 1 and all(trans[t] == flat_trans[t] for t in flat_trans)
    (loop,) = extra
    pre, post = trans[loop]
    assert pre == post and len(pre) == 1          # the root page's output place


@pytest.fixture(scope="module")
def finisher(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    # user text with XML's special characters: the file name appears in the descriptions
    folder = tmp_path_factory.mktemp("mcc") / "a&b<c>"
    folder.mkdir()
    spec = folder / "finisher.rssm"
    spec.write_text(FINISHER, encoding="utf-8")
    return spec, compile_mcc(spec, folder / "out")


def test_final_marking_is_not_a_deadlock(finisher: tuple[Path, Path]) -> None:
    spec, mcc = finisher
    (formula,) = check_property_set(mcc / "ReachabilityDeadlock.xml", "finisher",
                                    "ReachabilityDeadlock")
    report = verify_json(spec)
    assert report["deadlock_free"] is True
    assert not StateSpace(mcc / "model.pnml").holds(formula)
    # without the loop the finished system is a dead marking: EF deadlock would be TRUE
    assert StateSpace(mcc.parent / "finisher.pnml").holds(formula)


def test_properties_mean_what_verify_answers(finisher: tuple[Path, Path]) -> None:
    spec, mcc = finisher
    report = verify_json(spec)
    verdicts = {u["name"]: u["holds"] for u in report["user_properties"]}  # type: ignore[attr-defined]
    space = StateSpace(mcc / "model.pnml")
    always = check_property_set(mcc / "ReachabilityCardinality.xml", "finisher",
                                "ReachabilityCardinality")
    response = check_property_set(mcc / "CTLCardinality.xml", "finisher", "CTLCardinality")
    assert [space.holds(f) for f in always] == [verdicts["apart"], verdicts["together"]]
    assert [space.holds(f) for f in response] == [verdicts["rests"],
                                                  verdicts["counts_again"]]
    assert [verdicts["apart"], verdicts["together"]] == [True, False]
    assert [verdicts["rests"], verdicts["counts_again"]] == [True, False]
    # the descriptions keep the user's text, escaped in the file and read back whole
    root = ET.parse(mcc / "ReachabilityCardinality.xml").getroot()
    desc = [p.findtext(f"{MCC}description") or "" for p in root]
    assert "a&b<c>" in desc[0] and "always not (a.c in count and a.c in rest)" in desc[0]
    assert "a&amp;b&lt;c&gt;" in (mcc / "ReachabilityCardinality.xml").read_text("utf-8")
    # the property over a value is not written, and the README says why
    readme = (mcc / "README.txt").read_text("utf-8")
    assert "small (" in readme and "a.c.i, which is not a place of the PNML" in readme


def test_a_response_lost_by_one_choice_is_false_in_the_contest_formula(tmp_path: Path) -> None:
    """coin_toss (tests/verify/specs): from `start` a path home exists, yet one choice (tails)
    ends the system without coming home. The formula written, AG (not P or not E (not Q U
    not EF Q)), is false on the PNML's state space, as verify answers; AG (not P or EF Q)
    would be true."""
    spec = ROOT / "tests" / "verify" / "specs" / "coin_toss.rssm"
    mcc = compile_mcc(spec, tmp_path / "out")
    returns, tossed = check_property_set(mcc / "CTLCardinality.xml", "coin", "CTLCardinality")
    space = StateSpace(mcc / "model.pnml")
    verdicts = {u["name"]: u["holds"]  # type: ignore[index]
                for u in verify_json(spec)["user_properties"]}  # type: ignore[attr-defined]
    assert [space.holds(returns), space.holds(tossed)] == [verdicts["returns"],
                                                            verdicts["tossed"]] == [False, True]
    # the older reading: the negated EU dropped, EF Q in its place
    disjunction = returns[0][0]                    # all-paths / globally / disjunction
    p_not, no_eu = disjunction                     # not P', not E (... U ...)
    reach = no_eu[0][0][1]                         # exists-path / until / reach
    q = reach[0][0][0][0]                          # not / exists-path / finally / Q'
    weak = ET.Element(f"{MCC}all-paths")
    disj = ET.SubElement(ET.SubElement(weak, f"{MCC}globally"), f"{MCC}disjunction")
    disj.append(p_not)
    ET.SubElement(ET.SubElement(disj, f"{MCC}exists-path"), f"{MCC}finally").append(q)
    assert space.holds(weak)
