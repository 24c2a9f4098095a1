"""The limits bind in every phase of `rssmc verify`, also in those that never check the
budget (the compilation, the flattening, a long step outside Python): the watchdog
(rssm_dsl/verify/watchdog.py) interrupts the phase and the command prints the partial report
of what was done (exit 3, or 130 after Ctrl-C); progress lines keep coming in such a phase;
the numeric options refuse nan, infinities and sizes no machine has.

Each slow phase below would take 10 minutes; the runs must end far earlier (under 60 s: no
tight bound, the machine is shared)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from rssm_dsl.cli import make_app
from rssm_dsl.synth import lean_ring_system
from rssm_dsl.verify.budget import Budget, LimitReached
from tests.conftest import EXAMPLES, FAR_EARLIER, ROOT, sigint_default

EXIT_USAGE, EXIT_INCONCLUSIVE, EXIT_INTERRUPTED = 2, 3, 130
SPEC = EXAMPLES / "verify" / "deadlock_pair.rssm"     # small: every phase is quick
SLOW = 600.0                                          # seconds a slowed phase would take


def spin(seconds: float = SLOW) -> None:
    """A pure-Python loop that never checks the budget."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        sum(range(1000))


def slowed(real: Callable[..., Any], phase: str | None = None,
           slow: Callable[[], None] = spin) -> Callable[..., Any]:
    """``real`` after ``slow``; inside ``budget.running(phase)`` when given (an engine that
    names its phase, then gets stuck in a step that does not check)."""
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if phase is None:
            slow()
        else:
            budget = next(a for a in (*args, *kwargs.values()) if isinstance(a, Budget))
            with budget.running(phase):
                slow()
        return real(*args, **kwargs)
    return wrapper


def verify_in_process(*args: str | Path) -> tuple[Any, float]:
    t = time.monotonic()
    result = CliRunner().invoke(make_app(), ["verify", *map(str, args)])
    return result, time.monotonic() - t


# (module, function, phase named in the report, the phase the fake names itself)
PHASES = [
    ("rssm_dsl.pipeline", "compile_file", "the compilation", None),
    ("rssm_dsl.hpn.flatten", "flatten", "the flattening", None),
    ("rssm_dsl.verify.dataplan", "value_plan", "the value plan", None),
    ("rssm_dsl.verify.verifier", "blocking_groups", "the slicing", None),
    ("rssm_dsl.verify.verifier", "track_new", "the data tracking", None),
    ("rssm_dsl.verify.verifier", "one_token_semiflows", "the place invariants", None),
    ("rssm_dsl.verify.verifier", "explore_full", "the full exploration",
     "the full exploration"),
]


@pytest.mark.parametrize(("module", "name", "phase", "names_itself"), PHASES,
                         ids=[p[2].removeprefix("the ").replace(" ", "_") for p in PHASES])
def test_a_phase_that_does_not_check_is_stopped(monkeypatch: pytest.MonkeyPatch, module: str,
                                                name: str, phase: str,
                                                names_itself: str | None) -> None:
    mod = sys.modules.get(module) or __import__(module, fromlist=[name])
    monkeypatch.setattr(mod, name, slowed(getattr(mod, name), names_itself))
    result, wall = verify_in_process(SPEC, "--timeout", "2", "--format", "json")
    assert wall < FAR_EARLIER, wall
    assert result.exit_code == EXIT_INCONCLUSIVE, result.stdout + result.stderr
    report = json.loads(result.stdout)      # one JSON document, nothing else
    assert report["verdict"] == "inconclusive" and report["exit_code"] == EXIT_INCONCLUSIVE
    assert report["headline"] == f"INCONCLUSIVE: time limit of 2 s reached in {phase}"
    assert report["stopped_by"]["kind"] == "time" and report["stopped_by"]["phase"] == phase
    assert report["interrupted_phase"] == phase
    assert all(p["status"] == "not decided" for p in report["properties"].values())
    done = [p["phase"] for p in report["phases_completed"]]
    assert phase not in done
    if phase != "the compilation":
        assert "the compilation" in done
    assert "Traceback" not in result.stderr


def test_the_text_report_names_the_phase_and_what_was_done(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import rssm_dsl.hpn.flatten as flatten

    monkeypatch.setattr(flatten, "flatten", slowed(flatten.flatten))
    result, wall = verify_in_process(SPEC, "--timeout", "2")
    assert wall < FAR_EARLIER and result.exit_code == EXIT_INCONCLUSIVE, result.stdout
    lines = result.stdout.splitlines()
    assert lines[0] == ("system deadlock_pair: INCONCLUSIVE: time limit of 2 s reached in "
                        "the flattening")
    assert "  safeness:   not decided (time limit reached in the flattening)" in lines
    phases = next(line for line in lines if line.startswith("  phases:"))
    assert phases.startswith("  phases:     completed: the compilation (")
    assert "stopped in the flattening after" in phases
    assert "the flattening did not return on its own and was interrupted" in phases
    assert any(line.startswith("  limits:     time 2 s,") for line in lines)


def test_a_sleep_outside_python_is_stopped(monkeypatch: pytest.MonkeyPatch) -> None:
    """A blocking call that releases the GIL (the signal interrupts it)."""
    import rssm_dsl.pipeline as pipeline

    monkeypatch.setattr(pipeline, "compile_file",
                        slowed(pipeline.compile_file, slow=lambda: time.sleep(SLOW)))
    result, wall = verify_in_process(SPEC, "--timeout", "2")
    assert wall < FAR_EARLIER and result.exit_code == EXIT_INCONCLUSIVE, result.stdout
    assert result.stdout.startswith("system deadlock_pair: INCONCLUSIVE: time limit of 2 s "
                                    "reached in the compilation")


def test_progress_lines_in_a_phase_that_does_not_check(monkeypatch: pytest.MonkeyPatch,
                                                       ) -> None:
    import rssm_dsl.pipeline as pipeline

    monkeypatch.setattr(pipeline, "compile_file", slowed(pipeline.compile_file))
    result, _ = verify_in_process(SPEC, "--timeout", "9", "--progress")
    assert result.exit_code == EXIT_INCONCLUSIVE
    lines = [line for line in result.stderr.splitlines() if line.startswith("rssmc verify:")]
    assert len(lines) >= 2, result.stderr           # a line every 2 s from 2 s to 9 s
    assert all(", the compilation, " in line and line.endswith(" resident")
               for line in lines), lines


def test_a_swallowed_stop_ends_the_process_with_the_report(tmp_path: Path) -> None:
    """A phase that catches the watchdog's exception and goes on: the watchdog prints the
    partial report itself and ends the process (os._exit), JSON still one document."""
    script = tmp_path / "swallow.py"
    script.write_text(textwrap.dedent("""
        import sys, time
        import rssm_dsl.pipeline as pipeline
        from rssm_dsl.cli import entry
        from rssm_dsl.verify.budget import LimitReached

        def stubborn(*args, **kwargs):
            end = time.monotonic() + 600
            while time.monotonic() < end:
                try:
                    time.sleep(0.01)
                except LimitReached:
                    pass

        pipeline.compile_file = stubborn
        sys.argv = ["rssmc", "verify", sys.argv[1], "--timeout", "2", "--format", "json"]
        entry()
    """))
    t = time.monotonic()
    r = subprocess.run([sys.executable, str(script), str(SPEC)], cwd=ROOT, capture_output=True,
                       text=True, timeout=300)
    assert time.monotonic() - t < FAR_EARLIER
    assert r.returncode == EXIT_INCONCLUSIVE, r.stdout + r.stderr
    report = json.loads(r.stdout)
    assert report["headline"] == "INCONCLUSIVE: time limit of 2 s reached in the compilation"
    assert report["interrupted_phase"] == "the compilation"
    assert "rssmc: the compilation did not stop within" in r.stderr
    assert "Traceback" not in r.stderr


def test_a_spec_slow_to_compile_end_to_end(tmp_path: Path) -> None:
    """A real spec whose compilation takes far longer than the limit (3,000 agents)."""
    spec = tmp_path / "lean3000.rssm"
    spec.write_text(lean_ring_system(3000))
    t = time.monotonic()
    r = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--timeout",
                        "5", "--progress"], cwd=ROOT, capture_output=True, text=True,
                       timeout=600)
    wall = time.monotonic() - t
    assert r.returncode == EXIT_INCONCLUSIVE, r.stdout + r.stderr
    assert wall < FAR_EARLIER, wall
    head = r.stdout.splitlines()[0]
    assert head.startswith("system lean3000: INCONCLUSIVE: time limit of 5 s reached in the ")
    assert "stopped after" in r.stdout
    progress = [line for line in r.stderr.splitlines() if line.startswith("rssmc verify:")]
    assert progress and any(", the compilation, " in line for line in progress), r.stderr
    assert "Traceback" not in r.stderr


@pytest.mark.parametrize(("option", "value", "message"), [
    ("--timeout", "nan", "--timeout nan: give a number of seconds"),
    ("--timeout", "-5", "--timeout"),
    ("--timeout", "-inf", "--timeout"),
    ("--timeout", "0", "--timeout"),
    ("--max-memory", "1e999G", "the size must be a finite number"),
    ("--max-memory", "inf", "the size must be a finite number"),
    ("--max-memory", "nan", "the size must be a finite number"),
    ("--max-memory", "-1G", "the size must be positive"),
    ("--max-memory", "1e30G", "the size must be at most"),
    ("--max-memory", "200%", "a share of the physical memory"),
    ("--max-memory", "lots", "not a number"),
])
def test_bad_numbers_are_usage_errors(option: str, value: str, message: str) -> None:
    result, _ = verify_in_process(SPEC, option, value)
    assert result.exit_code == EXIT_USAGE, result.stdout + result.stderr
    assert message in result.stderr and "Traceback" not in result.stderr
    assert "E900" not in result.stderr and result.stdout == ""


def test_timeout_inf_is_no_time_limit() -> None:
    result, _ = verify_in_process(SPEC, "--timeout", "inf", "--format", "json")
    report = json.loads(result.stdout)
    assert report["limits"]["time_seconds"] is None
    assert report["verdict"] == "violated" and result.exit_code == 1   # its deadlock


def test_the_watchdog_stops_nothing_before_the_deadline() -> None:
    """A budget with a capped first try: the cap's deadline is not the run's, so the
    watchdog records no stop (the verifier clears the cap's own)."""
    from rssm_dsl.verify.watchdog import Watchdog

    budget = Budget(60.0)
    ended: list[str] = []
    with Watchdog(budget, lambda stop, phase: ended.append(phase), tick=0.05, grace=0.1,
                  hard=0.1), budget.capped(0.05):
        time.sleep(0.5)
    assert budget.stop is None and not ended
    budget = Budget(0.1)
    with pytest.raises(LimitReached), Watchdog(budget, lambda stop, phase: None, tick=0.05,
                                               grace=0.1, hard=30), budget.running("the nap"):
        spin(30)
    assert budget.stop is not None and budget.stop.phase == "the nap"


SLOWED_CLI = textwrap.dedent("""
    import sys, time
    import rssm_dsl.pipeline as pipeline
    from rssm_dsl.cli import entry

    held = []
    grow = sys.argv[1] == "grow"

    def slow(*args, **kwargs):
        end = time.monotonic() + 600
        while time.monotonic() < end:
            if grow and len(held) < 400:
                held.append(b"x" * (1 << 20) + bytes(len(held)))    # 1 MB more, touched
            sum(range(1000))

    pipeline.compile_file = slow
    sys.argv = ["rssmc", "verify", *sys.argv[2:]]
    entry()
""")


def slowed_cli(tmp_path: Path, mode: str, *args: str) -> subprocess.Popen[str]:
    script = tmp_path / "slowed.py"
    script.write_text(SLOWED_CLI)
    return subprocess.Popen([sys.executable, str(script), mode, str(SPEC), *args], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=sigint_default)


def test_the_memory_limit_binds_in_a_phase_that_does_not_check(tmp_path: Path) -> None:
    """The compilation grows by 1 MB at a time up to 400 MB; the limit is 150 MB above what
    a small run holds in a process of its own (not in this one, which holds the whole test
    session's memory)."""
    small = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(SPEC), "--format",
                            "json"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    limit = (json.loads(small.stdout)["peak_memory_bytes"] >> 20) + 150
    t = time.monotonic()
    p = slowed_cli(tmp_path, "grow", "--max-memory", f"{limit}M", "--format", "json")
    out, err = p.communicate(timeout=300)
    assert time.monotonic() - t < FAR_EARLIER
    assert p.returncode == EXIT_INCONCLUSIVE, out + err
    report = json.loads(out)
    assert report["stopped_by"]["kind"] == "memory"
    assert report["headline"].startswith(f"INCONCLUSIVE: memory limit of {limit} MB reached "
                                         "in the compilation")
    assert report["interrupted_phase"] == "the compilation"


def test_ctrl_c_in_a_phase_that_does_not_check(tmp_path: Path) -> None:
    p = slowed_cli(tmp_path, "spin", "--timeout", "300", "--format", "json")
    time.sleep(3)
    sent = time.monotonic()
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=300)
    assert time.monotonic() - sent < FAR_EARLIER
    assert p.returncode == EXIT_INTERRUPTED, out + err
    report = json.loads(out)
    assert report["exit_code"] == EXIT_INTERRUPTED
    assert report["headline"] == "INCONCLUSIVE: interrupted (Ctrl-C) in the compilation"
    assert "stopping at the next check" in err and "Traceback" not in err


def test_a_cross_check_stopped_by_the_watchdog_keeps_the_verdict(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import rssm_dsl.commands.verify as command

    monkeypatch.setattr(command, "_spin", slowed(command._spin))
    result, wall = verify_in_process(SPEC, "--timeout", "8", "--cross-check")
    assert wall < FAR_EARLIER
    assert result.exit_code == 1, result.stdout + result.stderr     # its deadlock
    assert result.stdout.startswith("system handshake: VIOLATED")
    assert ("independent cross-checks: stopped (time limit of 8 s reached in the "
            "cross-checks)") in result.stdout


def test_the_partial_json_has_every_key_of_the_full_report(
        monkeypatch: pytest.MonkeyPatch) -> None:
    import rssm_dsl.pipeline as pipeline

    full, _ = verify_in_process(SPEC, "--format", "json")
    monkeypatch.setattr(pipeline, "compile_file", slowed(pipeline.compile_file))
    partial, _ = verify_in_process(SPEC, "--timeout", "1", "--format", "json")
    assert partial.exit_code == EXIT_INCONCLUSIVE
    keys = set(json.loads(partial.stdout))
    assert set(json.loads(full.stdout)) <= keys
    assert {"phases_completed", "interrupted_phase"} <= keys


def test_a_partial_report_lists_every_property_as_not_decided(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """A limit that stops a phase after the compilation: the report lists the spec's
    properties, each not decided with the limit as the reason (JSON and text)."""
    import rssm_dsl.hpn.flatten as flatten

    spec = Path(__file__).parent / "specs" / "hub_stops.rssm"
    monkeypatch.setattr(flatten, "flatten", slowed(flatten.flatten))
    result, _ = verify_in_process(spec, "--timeout", "2", "--format", "json")
    assert result.exit_code == EXIT_INCONCLUSIVE, result.stdout + result.stderr
    report = json.loads(result.stdout)
    props = {p["name"]: p for p in report["user_properties"]}
    assert set(props) == {"r1_works", "r2_works", "no_work_before_go"}
    assert all(p["holds"] is None and "time limit of 2 s reached in the flattening" in p["why"]
               for p in props.values())
    text, _ = verify_in_process(spec, "--timeout", "2")
    lines = text.stdout.splitlines()
    assert "properties stated in the spec (3):" in lines
    assert any(line.startswith("  r1_works (") and ": not decided: whenever" in line
               for line in lines)
