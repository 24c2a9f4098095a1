"""The soundness harness (generator.py, checker.py): the generator's own tests, a fixed-seed
batch of random specs on which every engine of `rssmc verify` must agree and every
counterexample must replay, and the regressions the harness found (regressions/*.rssm).

`python bench/soundness.py --count 2000` runs the long batch."""

from __future__ import annotations

import contextlib
import os
import re
from collections import Counter
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any
from unittest import mock

import pytest

from rssm_dsl.verify import verifier
from tests.soundness.checker import (
    ENGINES,
    KNOWN_BUGS,
    Disagreement,
    Limits,
    Outcome,
    SimulationFinding,
    SpecResult,
    check_errors,
    check_spec,
    compare,
    compare_simulation,
    compile_text,
    known_error,
    summary_line,
)
from tests.soundness.generator import FEATURES, generate

HERE = Path(__file__).resolve().parent
REGRESSIONS = sorted((HERE / "regressions").glob("*.rssm"))
BATCH_SEED = 20_000
BATCH_COUNT = 18        # about 2-3 minutes on the project's 2-core machine
COVERAGE_SEEDS = range(300)

# ------------------------------------------------------------------------- generator


def test_the_generator_is_deterministic() -> None:
    assert generate(7).text == generate(7).text
    assert generate(7).text != generate(8).text


@pytest.mark.parametrize("start", range(0, 120, 20))
def test_every_generated_spec_checks_without_errors(start: int) -> None:
    for seed in range(start, start + 20):
        spec = generate(seed)
        comp = compile_text(spec.text, Path(f"/nonexistent/seed{seed}.rssm"))
        assert not check_errors(comp), (seed, check_errors(comp), spec.text)


def test_the_generator_covers_every_feature() -> None:
    seen: Counter[str] = Counter()
    for seed in COVERAGE_SEEDS:
        seen.update(generate(seed).features)
    assert FEATURES - set(seen) == set(), "never generated"
    assert set(seen) <= FEATURES, "a feature not declared in FEATURES"
    # each pairing of modes and each kind of data case several times, not once by luck
    for f in ("mode:bb", "mode:bn", "mode:nb", "mode:nn", "case:bool", "case:enum",
              "case:range", "property:always", "property:response", "ends"):
        assert seen[f] >= 10, (f, seen[f])


def test_a_generated_spec_reads_as_its_features_say() -> None:
    """The features are what the text holds, not just what the generator meant."""
    for seed in range(60):
        spec = generate(seed)
        text = spec.text
        agents = len(re.findall(r"^  agent a\d+ \{", text, re.M))
        assert f"agents:{agents}" in spec.features
        assert ("-> end" in text) == ("ends" in spec.features)
        assert ("real effector" in text) == ("device:effector" in spec.features)
        assert ("real receptor" in text) == ("device:receptor" in spec.features)
        assert ("whenever" in text) == ("property:response" in spec.features)
        assert (": always" in text) == ("property:always" in spec.features)
        assert ("case new(" in text) == any(f.startswith("case:") for f in spec.features)


# ---------------------------------------------------------------------- the checker


def _outcome(engine: str, **kw: Any) -> Outcome:
    base: dict[str, Any] = {"verdict": "verified", "safe": True, "deadlock_free": True,
                            "progress_ok": True, "lost": frozenset(), "properties": {},
                            "method": "full", "seconds": 0.0, "why": None,
                            "checked": frozenset({"a.c", "b.c"})}
    base.update(kw)
    return Outcome(engine, **base)


def test_compare_reports_two_decided_answers_that_differ_and_only_those() -> None:
    same = {"off": _outcome("off"), "on": _outcome("on", deadlock_free=None)}
    assert compare(same) == []
    differ = {"off": _outcome("off"), "on": _outcome("on", deadlock_free=False)}
    assert [d.what for d in compare(differ)] == ["deadlock_free"]
    lost = {"off": _outcome("off", progress_ok=False, lost=frozenset({"a.c", "b.c"})),
            "sliced": _outcome("sliced", progress_ok=False, lost=frozenset({"a.c"}))}
    assert [d.what for d in compare(lost)] == ["progress lost"]
    # a check stopped after its first loss (b.c not checked) lists fewer, not differently
    part = {"off": _outcome("off", progress_ok=False, lost=frozenset({"a.c", "b.c"})),
            "auto": _outcome("auto", progress_ok=False, lost=frozenset({"a.c"}),
                             checked=frozenset({"a.c"}))}
    assert compare(part) == []
    props = {"off": _outcome("off", properties={"p": True})}
    assert [d.what for d in compare(props, {"p": False})] == ["property p"]


def test_a_simulation_finding_contradicts_the_engines_that_proved_the_property() -> None:
    outcomes = {"off": _outcome("off"), "on": _outcome("on", deadlock_free=None)}
    found = compare_simulation(outcomes, [SimulationFinding("deadlock", detail="a deadlock")])
    assert [(d.what, d.detail.split()[0]) for d in found] == [("simulation: deadlock", "off")]


def test_a_counterexample_that_does_not_replay_is_a_disagreement() -> None:
    """The replay check can fail: a deadlock's steps cut short leave transitions enabled."""
    from rssm_dsl.hpn.flatten import flatten
    from rssm_dsl.verify import VerifyOptions, verify
    from tests.soundness.checker import replay

    path = Path(__file__).resolve().parents[2] / "examples" / "verify" / "deadlock_pair.rssm"
    comp = compile_text(path.read_text(encoding="utf-8"), path)
    assert comp.hpn is not None
    report = verify(flatten(comp.hpn), VerifyOptions(reduction="off"))
    cx = report.deadlocks[0]
    assert replay(comp, cx)[0]
    cut = type(cx)(cx.kind, cx.steps[:-2], cx.marking)
    ok, message = replay(comp, cut)
    assert not ok and "still enabled" in message


# ---------------------------------------------------------------- the fixed-seed batch


def _batch_spec(seed: int) -> SpecResult:
    """One spec of the fixed-seed batch, checked (in a worker process)."""
    return check_spec(generate(seed).text, f"seed{seed}", Limits(seconds=2.0, max_states=60_000))


def test_a_fixed_seed_batch_of_random_specs_agrees_and_replays() -> None:
    """Every engine agrees on every answer both decide, and every counterexample replays.
    A disagreement with the signature of a known engine bug (checker.KNOWN_BUGS, each
    pinned by a strict xfail below) is listed, not failed on; any other one fails."""
    unexplained: list[str] = []
    known: Counter[str] = Counter()
    # the specs two at a time (the CI machine's two cores; the suite runs one test at a
    # time): each engine's limit is its own time, so the answers it decides are the same
    seeds = range(BATCH_SEED, BATCH_SEED + BATCH_COUNT)
    with ProcessPoolExecutor(max_workers=max(1, min(2, os.cpu_count() or 1))) as pool:
        results = list(pool.map(_batch_spec, seeds))
    for seed, result in zip(seeds, results, strict=True):
        if result.error is not None:
            bug = known_error(result.error)
            assert bug is not None, summary_line(result) + "\n" + result.error
            known[bug] += 1
        for d in result.disagreements:
            bug = result.known(d)
            if bug is None:
                unexplained.append(f"seed {seed}: {d}")
            else:
                known[bug] += 1
    assert not unexplained, "\n".join(unexplained)
    assert set(known) <= set(KNOWN_BUGS)


# ------------------------------------------------------------------------ regressions


def _header(path: Path) -> dict[str, str]:
    out: dict[str, str] = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        m = re.match(r"//\s*(expect|setup|xfail|wrong|undecided):\s*(.*)", line)
        if m:
            out[m.group(1)] = m.group(2).strip()
    return out


def _expected(spec: str) -> dict[str, str]:
    return dict(item.split("=", 1) for item in spec.split())


@contextlib.contextmanager
def _limit_after_abstraction() -> Iterator[None]:
    """A limit of the run reached right after verifier._abstraction_first's first pass (the
    conditions as free choices), whatever the machine's speed."""
    original = verifier.verify
    depth = 0

    def wrapped(net: Any, options: Any = None) -> Any:
        nonlocal depth
        depth += 1
        try:
            report = original(net, options)
        finally:
            depth -= 1
        if depth == 0 and options is not None and options.budget is not None:
            options.budget.expire("time", "stopped by the test after the first pass")
        return report

    with mock.patch.object(verifier, "verify", wrapped):
        yield


@contextlib.contextmanager
def _limit_in_property_lasso() -> Iterator[None]:
    """A limit of the run reached as userprops builds a response property's lasso."""
    from rssm_dsl.verify import userprops
    from rssm_dsl.verify.progress import terminal_component as original

    def wrapped(graph: Any, state: int, budget: Any = None) -> Any:
        if budget is not None:
            budget.expire("time", "stopped by the test in the property's lasso")
        return original(graph, state, budget)

    with mock.patch.object(userprops, "terminal_component", wrapped):
        yield


SETUPS = {"limit-after-abstraction": _limit_after_abstraction,
          "limit-in-property-lasso": _limit_in_property_lasso}


def _regression_params() -> list[Any]:
    params = []
    for path in REGRESSIONS:
        xfail = _header(path).get("xfail")
        marks = [pytest.mark.xfail(strict=True, reason=xfail)] if xfail else []
        params.append(pytest.param(path, id=path.stem, marks=marks))
    return params


def _wrong_answers(outcome: Outcome, expect: dict[str, str]) -> list[str]:
    """The decided answers of ``outcome`` that contradict the header's expectation."""
    wrong = []
    for key in ("safe", "deadlock_free", "progress_ok"):
        got = getattr(outcome, key)
        if key in expect and got is not None and str(got).lower() != expect[key]:
            wrong.append(f"{key}={got}")
    if ("lost" in expect and outcome.progress_ok is False
            and sorted(outcome.lost) != sorted(expect["lost"].split(","))):
        wrong.append(f"lost={sorted(outcome.lost)}")
    for key, value in expect.items():
        if key.startswith("property:"):
            got_p = outcome.properties.get(key.split(":", 1)[1])
            if got_p is not None and str(got_p).lower() != value:
                wrong.append(f"{key}={got_p}")
    return wrong


@pytest.mark.parametrize("path", _regression_params())
def test_regression(path: Path) -> None:
    """Every engine on the minimised spec: no answer contradicts the verdict worked out by
    hand (its header), no two engines disagree, every counterexample replays, and every
    engine decides (but those the header's ``undecided:`` names, before a colon)."""
    header = _header(path)
    expect = _expected(header["expect"])
    plain = "setup" not in header
    # engines allowed to leave it open (a state space beyond the test's limits), by name
    may_not_decide = set(header.get("undecided", "").split(":", 1)[0].split())
    setup = SETUPS[header["setup"]]() if not plain else contextlib.nullcontext()
    # (a regression some engine may leave open needs no million markings from it)
    limits = Limits(seconds=60.0, max_states=200_000 if may_not_decide else 1_000_000)
    with setup:
        result = check_spec("", path.stem, limits, path=path)
    assert result.error is None, result.error
    problems: list[str | Disagreement] = list(result.disagreements)
    for e, o in result.outcomes.items():
        problems += [f"{e}: {w}" for w in _wrong_answers(o, expect)]
        if plain and o.undecided and e not in may_not_decide:
            problems.append(f"{e}: undecided ({o.why})")
    assert not problems, "\n".join(map(str, problems))
    assert set(result.outcomes) == set(ENGINES)
