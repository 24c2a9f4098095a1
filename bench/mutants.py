"""Mutation check of the semantics: each named mutant is one small change to the one place
where a rule is defined (rssm_core, the HPN builder, the interpreter's behaviour pattern);
the non-golden tests must kill every one.

For each mutant the script copies the repository (without .git, .venv, .cache) into a
temporary folder, applies the change there (the text to replace must occur exactly once),
and runs the test selection against the copy, stopping at the first failure. It prints a
table of mutants, the test that killed each and the time it took; any survivor makes the run
exit 1 (and so does a mutant whose text is no longer found: the list must follow the code).

    python bench/mutants.py                 # every mutant
    python bench/mutants.py --only mod      # the mutants whose name contains "mod"
    python bench/mutants.py --list          # the mutants and where they apply

The selection (``--tests``) defaults to the behaviour tests that need no external system
(golden-file tests excluded: they would kill anything and prove nothing).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
from mutants_audit import AUDIT  # noqa: E402  (bench/ is no package)

DEFAULT_TESTS = ("tests/semantics", "tests/core", "tests/interp", "tests/verify/test_verify.py",
                 "tests/verify/test_statespace.py", "tests/hpn",
                 "tests/verify/test_userprops.py", "tests/verify/test_stubborn.py",
                 "tests/verify/test_deadmarking.py")
# tests/core/test_mutant_list.py checks that each mutant's text occurs once in the tree: in a
# mutated copy it fails by construction, so it would "kill" every mutant
SELECT = ["-m", "not ros2", "-k", "not golden", "--ignore", "tests/core/test_mutant_list.py"]


@dataclass(frozen=True)
class Mutant:
    name: str
    what: str
    path: str
    old: str
    new: str


MUTANTS = (
    Mutant("mod-sign-of-dividend", "`%` takes the sign of the dividend (C's fmod)",
           "rssm_core/values.py",
           '        raise _fail(where, "remainder by zero")\n    return x % y\n',
           '        raise _fail(where, "remainder by zero")\n'
           '    r = math.fmod(x, y)\n    return int(r) if type(x) is int and type(y) is int else r\n'),
    Mutant("int-division", "`/` of two ints is integer division",
           "rssm_core/values.py",
           "        return float(x / y)\n",
           "        return float(x // y) if type(x) is int and type(y) is int else float(x / y)\n"),
    Mutant("int-overflow-unchecked", "int addition wraps nothing and fails nothing past 64 bits",
           "rssm_core/values.py",
           "    r = x + y\n    return r if INT_MIN <= r <= INT_MAX else int64(r, where)\n",
           "    return x + y\n"),
    Mutant("nonblocking-consumer-skips-waiting-data",
           "a non-blocking consumer may skip its receive while fresh data waits",
           "rssm_core/modes.py",
           "            return (*take, Transition(3, Step.NOTHING_NEW, (Slot.IN, Slot.EMPTY),\n"
           "                                      (Slot.OUT, Slot.EMPTY)))\n",
           "            return (*take, Transition(3, Step.NOTHING_NEW, (Slot.IN, Slot.EMPTY),\n"
           "                                      (Slot.OUT, Slot.EMPTY)),\n"
           "                    Transition(4, Step.NOTHING_NEW, (Slot.IN, Slot.FULL),\n"
           "                               (Slot.OUT, Slot.FULL)))\n"),
    Mutant("blocking-producer-does-not-wait",
           "a blocking producer's send ends before the consumer took the data",
           "rssm_core/modes.py",
           "Transition(3, Step.SENT_WAIT, (Slot.OP,), (Slot.WAIT, Slot.FULL))",
           "Transition(3, Step.SENT_WAIT, (Slot.OP,), (Slot.OUT, Slot.FULL))"),
    Mutant("new-not-cleared", "new(x) is not cleared once the transition function used it",
           "rssm_core/iteration.py",
           "        self.pending = 0\n",
           "        pass\n"),
    Mutant("error-conditions-ignore-failures",
           "an operation that failed in the iteration does not make the error conditions hold",
           "rssm_core/iteration.py",
           "    if failed:\n        for name, kind, _ in conditions:",
           "    if False:\n        for name, kind, _ in conditions:"),
    Mutant("sequence-reversed", "a sequential arrangement `a ; b` runs b first (receive order)",
           "rssm_dsl/hpn/build.py",
           "                    first_s, prev_e = emit(a.items[0])\n"
           "                    for item in a.items[1:]:\n",
           "                    first_s, prev_e = emit(a.items[-1])\n"
           "                    for item in a.items[-2::-1]:\n"),
    Mutant("send-before-compute", "the send arrangement runs before the transition function",
           "rssm_dsl/hpn/build.py",
           '                   [f_page])\n'
           '        t1 = self._trans(N.transition(j, v, w, 1), pid, b.span, f"{who} has computed f")\n'
           '        if snd is not None:\n'
           '            self._arcs(pid, [f_page], t1, [snd])\n'
           '            t2 = self._trans(N.transition(j, v, w, 2), pid, b.span, f"{who} has sent")\n'
           '            self._arcs(pid, [snd], t2, [p2])\n',
           '                   [snd if snd is not None else f_page])\n'
           '        t1 = self._trans(N.transition(j, v, w, 1), pid, b.span, f"{who} has computed f")\n'
           '        if snd is not None:\n'
           '            self._arcs(pid, [snd], t1, [f_page])\n'
           '            t2 = self._trans(N.transition(j, v, w, 2), pid, b.span, f"{who} has sent")\n'
           '            self._arcs(pid, [f_page], t2, [p2])\n'),
    Mutant("overlapping-switches-by-chance",
           "when two switch conditions hold, any may be taken (not the first declared)",
           "rssm_dsl/interp/program.py",
           "            rt.guards[i] = (lambda: own() and not any(g() for g in earlier)) if earlier else own\n",
           "            rt.guards[i] = own\n"),
    Mutant("switch-before-terminal",
           "the next behaviour is chosen from the conditions as they were before the "
           "terminal and error conditions of the last iteration were evaluated",
           "rssm_dsl/interp/program.py",
           "        if s.conds is None:      # a constant-true stop condition: nothing was evaluated\n"
           "            s.evaluate_conditions()\n"
           "        s.last_conds = s.conds or {}\n",
           "        s.last_conds = s.conds or {}\n"
           "        if s.conds is None:      # a constant-true stop condition: nothing was evaluated\n"
           "            s.evaluate_conditions()\n"),
    Mutant("typed-device-never-checked",
           "a device class declaring typed_measurements has not even its first measurement "
           "of an output checked (E803)",
           "rssm_dsl/interp/program.py",
           "        if typed and checked.issuperset(measured):\n",
           "        if typed:\n"),
    Mutant("every-device-trusted",
           "every device's measurements are checked once only, declared or not",
           "rssm_dsl/interp/program.py",
           '    typed = getattr(impl, "typed_measurements", False) is True\n',
           "    typed = True\n"),
    # the stubborn-set conditions (verify/stubborn.py); killed by tests/verify/test_userprops.py
    # and tests/verify/test_stubborn.py (run: --only stubborn)
    Mutant("stubborn-no-visibility",
           "V dropped: an enabled visible transition in a stubborn set does not bring the "
           "other visible ones",
           "rssm_dsl/verify/stubborn.py",
           "                    add |= self.visible\n",
           "                    pass\n"),
    Mutant("stubborn-visible-alone",
           "V dropped for the shortcut: a visible transition in conflict with nothing is a "
           "stubborn set on its own",
           "rssm_dsl/verify/stubborn.py",
           "            if self.dependent[t] == 1 << t and not visible >> t & 1:\n",
           "            if self.dependent[t] == 1 << t:\n"),
    Mutant("stubborn-no-proviso",
           "L dropped: no fully expanded marking on the cycles of the reduced graph "
           "(a transition may be ignored for ever)",
           "rssm_dsl/verify/stubborn.py",
           "                    if stopped is not None or not proviso:\n",
           "                    if True:\n"),
    Mutant("stubborn-no-key-conflicts",
           "D1/D2 dropped for an enabled transition: its dependent transitions are not "
           "added to the set",
           "rssm_dsl/verify/stubborn.py",
           "                add = dependent[t]\n",
           "                add = 0\n"),
    Mutant("stubborn-no-takers",
           "an enabled transition's set lacks those that empty one of its input places (only "
           "those needing what it empties are added)",
           "rssm_dsl/verify/stubborn.py",
           "                self.dependent[t] |= self.leave[p]\n",
           "                pass\n"),
    Mutant("stubborn-no-needers",
           "an enabled transition's set lacks those needing a place it empties",
           "rssm_dsl/verify/stubborn.py",
           "                self.dependent[t] |= nb.consumers[p]\n",
           "                pass\n"),
    Mutant("stubborn-no-scapegoat",
           "D1 dropped for a disabled transition: neither the producers of an unmarked input "
           "place nor a necessary enabling set is added",
           "rssm_dsl/verify/stubborn.py",
           "                    for makers in (producers[q], *self._leaving(m, q)):\n",
           "                    for makers in (0,):\n"),
    Mutant("stubborn-nes-of-the-wrong-place",
           "the necessary enabling set of an unmarked place taken from the semiflow's "
           "unmarked places instead of the marked one",
           "rssm_dsl/verify/stubborn.py",
           "                out.append(self.leave[here.bit_length() - 1])\n",
           "                out.append(self.leave[p])\n"),
    # the relaxation of deadlock freedom (verify/deadmarking.py); killed by
    # tests/verify/test_deadmarking.py (run: --only deadmarking)
    Mutant("deadmarking-first-candidate-only",
           "the search tries only the first possible place of the semiflow it branches on",
           "rssm_dsl/verify/deadmarking.py",
           "            for p in reversed(bits(self.flows[flow] & ~off)):\n",
           "            for p in bits(self.flows[flow] & ~off)[:1]:\n"),
    Mutant("deadmarking-unit-marks",
           "a transition with one input place left open gets it marked instead of unmarked",
           "rssm_dsl/verify/deadmarking.py",
           "                todo.append((open_.bit_length() - 1, False))\n",
           "                todo.append((open_.bit_length() - 1, True))\n"),
    Mutant("deadmarking-units-marked",
           "the input place of a transition with one input is marked instead of unmarked",
           "rssm_dsl/verify/deadmarking.py",
           "        out = [(pre.bit_length() - 1, False) for pre in self.pre if pre & (pre - 1) == 0\n",
           "        out = [(pre.bit_length() - 1, True) for pre in self.pre if pre & (pre - 1) == 0\n"),
    Mutant("stubborn-no-up-set",
           "the up-set dropped: markings where a firing is unsafe may be skipped",
           "rssm_dsl/verify/stubborn.py",
           "        up = self.up_set(m) if self.watched else 0\n",
           "        up = 0\n"),
    # where a property is checked (verify/slicing.py wait_closure); killed by
    # tests/verify/test_userprops.py (run: --only slice)
    Mutant("slice-no-blocking-receive",
           "a property's slice lacks the producers its subsystems receive from blocking",
           "rssm_dsl/verify/slicing.py",
           "            if c.consumer == s and (c.consumer_waits or feeds(c)):\n",
           "            if c.consumer == s and feeds(c):\n"),
    Mutant("slice-no-blocking-send",
           "a property's slice lacks the consumers its subsystems send to blocking",
           "rssm_dsl/verify/slicing.py",
           "            elif c.producer == s and c.producer_waits:\n",
           "            elif c.producer == s and False:\n"),
    Mutant("slice-no-fed-values",
           "a property's slice lacks the producers of the values it tracks (the environment "
           "writes any value there)",
           "rssm_dsl/verify/userprops.py",
           "            if f\"channel {c.name}\" in tracked:\n                return True\n",
           "            if False:\n                return True\n"),
    Mutant("slice-values-of-every-condition",
           "a property's slice holds the producers of the values any condition of the whole "
           "net reads, not only its own subsystems' (a fleet's coordinator brings in every "
           "robot)",
           "rssm_dsl/verify/valuenet.py",
           "                and (within is None or net.transitions[u].subsystem in within)\n",
           "                and (within is None or True)\n"),
    Mutant("slice-env-new-free",
           "a property's slice leaves new(x) of what its environment feeds a free choice, so "
           "its paths copy readings never received and do not replay in the whole net",
           "rssm_dsl/verify/slicing.py",
           "    free = set() if env_new else {",
           "    free = set() if False else {"),
    Mutant("kleene-left-first",
           "a condition is evaluated from the left as the interpreter does: an untracked "
           "left side of `and` hides a false right side",
           "rssm_dsl/verify/dataplan.py",
           "            fn = self._conds[c.name] = _kleene(self.compiler.expr, c.expr)\n",
           "            fn = self._conds[c.name] = self.compiler.expr(c.expr)\n"),
    Mutant("kleene-unknown-is-false",
           "an unknown side of `and` counts as false",
           "rssm_dsl/verify/dataplan.py",
           "            if a is None or b is None:\n                raise _UnknownValue\n",
           "            if a is None or b is None:\n                return False\n"),
    Mutant("properties-no-share",
           "safeness, deadlocks and progress may take the whole run, the properties none",
           "rssm_dsl/verify/verifier.py",
           "        with budget.capped((1 - PROPERTIES_SHARE) * left):\n",
           "        with budget.capped(left):\n"),
    Mutant("slice-response-lost-moving-fixed",
           "Q is taken as lost for good though a subsystem it reads can still move",
           "rssm_dsl/verify/userprops.py",
           "        if a.subsystem_id not in moving:\n",
           "        if True:\n"),
    Mutant("stall-order-iteration-unchecked",
           "the stall order takes a peer's every iteration to meet the channel unchecked",
           "rssm_dsl/verify/stalls.py",
           "        if self._fires(q, mine, after_iter, completes | idle, iters) & iters:\n",
           "        if False:\n"),
    Mutant("slice-quiet-waiting-end",
           "a channel the slice's end waits on is dropped as quiet",
           "rssm_dsl/verify/slicing.py",
           "        return not c.consumer_waits\n",
           "        return True\n"),
)

SURVIVED = "SURVIVED"
ROS = False          # --ros: the ros2-marked tests too
# the mutants written by someone who had not read the tests (issue 33's audit)
ALL = MUTANTS + tuple(Mutant(*fields) for fields in AUDIT)

_IGNORE = shutil.ignore_patterns(".git", ".venv", ".cache", "__pycache__", "out", "node_modules",
                                 ".mypy_cache", ".ruff_cache", ".pytest_cache", "*.egg-info")


def apply(m: Mutant, root: Path) -> None:
    path = root / m.path
    text = path.read_text(encoding="utf-8")
    count = text.count(m.old)
    if count != 1:
        raise LookupError(f"{m.path}: the text of mutant {m.name} occurs {count} times "
                          "(update bench/mutants.py to follow the code)")
    path.write_text(text.replace(m.old, m.new), encoding="utf-8")


def selection() -> list[str]:
    """The pytest options that choose the tests (--ros: the ros2-marked ones too)."""
    return [x for x in SELECT if x not in ("-m", "not ros2")] if ROS else SELECT


def run_tests(root: Path, tests: list[str], timeout: float) -> tuple[str | None, float]:
    """The first failing test (None when every test passed) and the seconds it took."""
    env = dict(os.environ, PYTHONPATH=str(root), PYTHONDONTWRITEBYTECODE="1")
    select = selection()
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider",
           "--no-header", "-rf", *select, *tests]
    start = time.perf_counter()
    try:
        done = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True,
                              timeout=timeout, check=False)
    except subprocess.TimeoutExpired:
        return "(timed out: counts as killed, the mutant hangs the tests)", timeout
    took = time.perf_counter() - start
    if done.returncode == 0:
        return None, took
    failed = re.search(r"^(?:FAILED|ERROR) (.+?)(?: - |$)", done.stdout, re.MULTILINE)
    if failed:
        return failed.group(1), took
    tail = (done.stdout + done.stderr).strip().splitlines()[-1:] or ["?"]
    return f"(pytest exit {done.returncode}: {tail[0][:80]})", took


def killed(m: Mutant, base: Path, tmp: Path, tests: list[str],
           timeout: float) -> tuple[str, float]:
    """Run the tests on a copy of ``base`` with ``m`` applied: what the table says (the
    killing test, or SURVIVED, NOT APPLIED, FLAKY) and the seconds it took. A test that kills
    must pass again on the unmutated copy, or it is flaky and kills nothing."""
    work = tmp / m.name
    shutil.copytree(base, work, symlinks=True)
    try:
        apply(m, work)
    except LookupError as e:
        shutil.rmtree(work, ignore_errors=True)
        return f"{SURVIVED} (NOT APPLIED: {e})", 0.0
    killer, took = run_tests(work, tests, timeout)
    shutil.rmtree(work, ignore_errors=True)
    if killer is None:
        return SURVIVED, took
    if not killer.startswith("("):
        again, _ = run_tests(base, [killer], timeout)
        if again is not None:
            return f"{SURVIVED} (FLAKY: {killer} fails unmutated too)", took
    return killer, took


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default="", help="run the mutants whose name contains this "
                    "(or one of these, comma-separated)")
    ap.add_argument("--tests", nargs="*", default=list(DEFAULT_TESTS))
    ap.add_argument("--timeout", type=float, default=900.0, help="seconds per mutant")
    ap.add_argument("--jobs", type=int, default=1, help="mutants run at once")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("--ros", action="store_true",
                    help="run the ros2-marked tests too, in the repository's ROS venv "
                         "(.cache/ros2-venv, linked into each copy)")
    args = ap.parse_args()
    global ROS
    ROS = args.ros
    chosen = [m for m in ALL if any(part in m.name for part in args.only.split(","))]
    if args.list:
        for m in chosen:
            print(f"{m.name:42} {m.path}: {m.what}")
        return 0
    tests = [t for t in args.tests if (ROOT / t.split("::")[0]).exists()]
    print(f"{len(chosen)} mutants; tests: {' '.join(tests)} ({' '.join(selection())})")
    start = time.perf_counter()
    survivors = 0
    with tempfile.TemporaryDirectory(prefix="rssm-mutants-") as tmp:
        base = Path(tmp) / "repo"
        shutil.copytree(ROOT, base, ignore=_IGNORE)
        if ROS and (ROOT / ".cache" / "ros2-venv").is_dir():
            (base / ".cache").mkdir(exist_ok=True)
            (base / ".cache" / "ros2-venv").symlink_to(ROOT / ".cache" / "ros2-venv")
        clean, took = run_tests(base, tests, args.timeout)
        if clean is not None:
            print(f"the unmutated code fails {clean}: fix that first")
            return 1
        print(f"unmutated: all pass in {took:.1f} s\n")
        print(f"{'mutant':42} {'killed by':90} {'s':>6}")
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            runs = [(m, pool.submit(killed, m, base, Path(tmp), tests, args.timeout))
                    for m in chosen]
            for m, run in runs:
                killer, took = run.result()
                survivors += killer.startswith(SURVIVED)
                print(f"{m.name:42} {killer[:90]:90} {took:6.1f}", flush=True)
    print(f"\n{len(chosen) - survivors} of {len(chosen)} mutants killed "
          f"in {time.perf_counter() - start:.0f} s")
    return 1 if survivors else 0


if __name__ == "__main__":
    sys.exit(main())
