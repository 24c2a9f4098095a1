"""Time to verdict of `rssmc verify` on random shapes nobody tuned for.

Each family is a seeded random multi-agent system (`random_system`): N agents whose control
subsystems are linked as a ring, a chain or a star; every link's modes are drawn at random
(B: blocking send and receive, N: non-blocking both, W: non-blocking send and blocking
receive, P: blocking send and non-blocking receive); some agents drive a virtual effector with
a real effector device, and about a third of those effectors wait on their controller (a
blocking receive of its command, over a link whose send mode is drawn too); some agents read
a real receptor device through a virtual receptor. Every control subsystem sends on all its
links, then receives on all of them, in every iteration.

Variants:

- ``deadlock``: a cycle of blocking sends is planted (ring: every link sends blocking; star:
  one hub-spoke pair sends blocking both ways). Every subsystem on the cycle waits in its
  send for good: `verify` must report a violation (deadlock, or loss of progress while the
  devices run on), with a firing sequence for each.
- ``live``: every cycle has a non-blocking send (ring: at least one link; star: each
  hub-spoke pair), so the values go round; the expected verdict is VERIFIED.

Each system is checked by `rssmc verify FILE --timeout T --format json` in its own process
(compile and flatten included; killed at T + 60 s if it overruns its own limit), and the line
printed gives: the family, N, places and transitions of the flat net, the wall time, the
verdict, the technique that decided each question (the report's ``properties[...].by``:
full, stubborn sets, sliced, compositional...), the states explored, the violations found
and whether every violation came with a firing sequence.

    python bench/verify_random.py [--sizes 5,10,20,50,100] [--families ring-deadlock,...]
                                  [--seed 1] [--timeout 120] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import random
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

MODES = {"B": ("blocking", "blocking"), "N": ("nonblocking", "nonblocking"),
         "W": ("nonblocking", "blocking"), "P": ("blocking", "nonblocking")}
BLOCKING_SEND = ("B", "P")
FREE_SEND = ("N", "W")

DEVICES = """device effector Servo @ 1 kHz {
  input command: float nonblocking
  output position: float nonblocking
}

device receptor Cam @ 30 Hz {
  output raw: float nonblocking
}

"""

EFFECTOR = """    effector arm @ 500 Hz {{
      input command: float from c {mode}
      input measured: float from E.servo nonblocking
      output setpoint: float to E.servo nonblocking
      output position: float to c nonblocking
      behaviour follow {{
        update setpoint {{ setpoint := command }}
        update position {{ position := measured }}
        terminal never when false
      }}
      initial follow
    }}
    real effector servo: Servo
"""

RECEPTOR = """    receptor eye @ 30 Hz {
      input raw: float from R.cam nonblocking
      output seen: float to c nonblocking
      behaviour filter {
        update seen { seen := raw }
        terminal never when false
      }
      initial filter
    }
    real receptor cam: Cam
"""


@dataclass
class Agent:
    k: int
    outs: list[tuple[int, str]] = field(default_factory=list)   # (to agent, link kind)
    ins: list[tuple[int, str]] = field(default_factory=list)    # (from agent, link kind)
    effector: str | None = None      # link kind of c -> arm.command, None: no effector
    receptor: bool = False


def links(topology: str, n: int) -> list[tuple[int, int]]:
    """The control links (from agent, to agent) of a topology over agents 1..n."""
    if topology == "ring":
        return [(k, k % n + 1) for k in range(1, n + 1)]
    if topology == "chain":
        return [(k, k + 1) for k in range(1, n)]
    if topology == "star":
        return [e for k in range(2, n + 1) for e in ((1, k), (k, 1))]
    raise ValueError(f"unknown topology {topology}")


def random_system(n: int, topology: str, variant: str, seed: int) -> str:
    """The text of a random system (the module docstring); the same arguments give the same
    text."""
    rng = random.Random(f"{topology}-{variant}-{n}-{seed}")
    agents = {k: Agent(k) for k in range(1, n + 1)}
    edges = links(topology, n)
    kinds = {e: rng.choice("BNWP") for e in edges}
    if topology == "ring":
        if variant == "deadlock":
            kinds = {e: rng.choice(BLOCKING_SEND) for e in edges}
        elif all(kinds[e] in BLOCKING_SEND for e in edges):
            kinds[rng.choice(edges)] = rng.choice(FREE_SEND)
    elif topology == "star":
        pairs = [((1, k), (k, 1)) for k in range(2, n + 1)]
        for a, b in pairs:
            if kinds[a] in BLOCKING_SEND and kinds[b] in BLOCKING_SEND:
                kinds[rng.choice((a, b))] = rng.choice(FREE_SEND)
        if variant == "deadlock":
            a, b = rng.choice(pairs)
            kinds[a], kinds[b] = rng.choice(BLOCKING_SEND), rng.choice(BLOCKING_SEND)
    for (u, v), kind in kinds.items():
        agents[u].outs.append((v, kind))
        agents[v].ins.append((u, kind))
    for agent in agents.values():
        if rng.random() < 0.5:
            # a third of the effectors wait on their controller (blocking receive)
            agent.effector = rng.choice("BW") if rng.random() < 1 / 3 else rng.choice("NP")
        agent.receptor = rng.random() < 0.25
    text = "".join(_agent(agent) for agent in agents.values())
    return (f"// bench/verify_random.py: random_system({n}, {topology!r}, {variant!r}, "
            f"{seed})\n{DEVICES}system random_{topology}_{variant}_{n} {{\n{text}}}\n")


def _agent(a: Agent) -> str:
    decls: list[str] = ["      memory token: float = 0.0"]
    updates: list[str] = []
    sends: list[str] = []
    receives: list[str] = []
    for v, kind in a.outs:
        decls.append(f"      output to_a{v}: float to a{v}.c {MODES[kind][0]}")
        updates.append(f"        update to_a{v} {{ to_a{v} := token }}")
        sends.append(f"to_a{v}")
    for u, kind in a.ins:
        decls.append(f"      input from_a{u}: float from a{u}.c {MODES[kind][1]}")
        receives.append(f"from_a{u}")
    if a.effector is not None:
        decls.append(f"      output command: float to e.arm {MODES[a.effector][0]}")
        decls.append("      input position: float from e.arm nonblocking")
        updates.append("        update command { command := token }")
        sends.append("command")
        receives.append("position")
    if a.receptor:
        decls.append("      input seen: float from r.eye nonblocking")
        receives.append("seen")
    terms = [f"from_a{u}" for u, _ in a.ins] or ["token"]
    terms += [f"0.0 * {x}" for x, on in (("position", a.effector), ("seen", a.receptor)) if on]
    feed = " + ".join(terms)
    updates.append(f"        update memory {{ token := {feed} + 1.0 }}")
    clauses = []
    if sends:
        clauses.append(f"        send {' | '.join(sends)}")
    if receives:
        clauses.append(f"        receive {' | '.join(receives)}")
    body = "\n".join([*updates, "        terminal never when false", *clauses])
    control = ("    control c @ 100 Hz {\n" + "\n".join(decls) + "\n"
               f"      behaviour pass {{\n{body}\n      }}\n      initial pass\n    }}\n")
    effector = (EFFECTOR.format(mode=MODES[a.effector][1]) if a.effector is not None else "")
    receptor = RECEPTOR if a.receptor else ""
    return f"  agent a{a.k} {{\n{control}{effector}{receptor}  }}\n"


@dataclass
class Outcome:
    seconds: float
    verdict: str
    by: str
    states: int | None
    violations: int
    traced: str
    places: int | None = None
    transitions: int | None = None


def _techniques(report: dict[str, Any]) -> str:
    props = report.get("properties") or {}
    parts = []
    for key, short in (("deadlock_freedom", "dl"), ("progress", "prog")):
        p = props.get(key) or {}
        status = str(p.get("status") or "-")
        parts.append(f"{short}:{status}" + (f" by {p['by']}" if p.get("by") else ""))
    return ", ".join(parts)


def run_one(path: Path, timeout: float) -> Outcome:
    """`rssmc verify` on one file, in its own process (its JSON report is kept beside the
    file, ``.json``)."""
    cmd = [sys.executable, "-m", "rssm_dsl", "verify", str(path), "--timeout", str(timeout),
           "--format", "json"]
    start = time.monotonic()
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout + 60)
    except subprocess.TimeoutExpired:
        return Outcome(time.monotonic() - start, "KILLED", "-", None, 0, "-")
    seconds = time.monotonic() - start
    path.with_suffix(".json").write_text(proc.stdout, encoding="utf-8")
    try:
        report = json.loads(proc.stdout)
    except json.JSONDecodeError:
        tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        return Outcome(seconds, f"ERROR ({tail[:60]})", "-", None, 0, "-")
    space = report.get("state_space") or {}
    deadlocks = report.get("deadlocks") or []
    progress = report.get("progress") or []
    untraced = report.get("progress_lost_without_trace") or []
    users = [u for u in report.get("user_properties") or [] if u.get("holds") is False]
    violations = len(deadlocks) + len(progress) + len(untraced) + len(users)
    if report.get("unsafe"):
        violations += 1
    if report.get("deadlock_free") is False and not deadlocks:
        violations += 1                       # found, but no firing sequence given
        untraced = [*untraced, "deadlock"]
    missing = len(untraced) + sum(1 for d in deadlocks if not d.get("steps"))
    traced = "-" if violations == 0 else ("all" if missing == 0 else f"{missing} missing")
    return Outcome(seconds, str(report.get("headline") or report.get("verdict")),
                   _techniques(report), space.get("states"), violations, traced)


def net_size(path: Path) -> tuple[int, int]:
    from rssm_dsl.hpn.flatten import flatten
    from rssm_dsl.pipeline import compile_file

    comp = compile_file(path)
    if not comp.ok or comp.hpn is None:
        first = next((d for d in comp.diagnostics if d.is_error), None)
        raise SystemExit(f"{path}: does not compile: {first}")
    net = flatten(comp.hpn)
    return len(net.places), len(net.transitions)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--sizes", default="5,10,20,50,100")
    ap.add_argument("--families", default="ring-deadlock,ring-live,star-live,chain-live")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=120.0)
    ap.add_argument("--keep", type=Path, default=None,
                    help="write the generated specs into this folder")
    args = ap.parse_args()
    print(f"{'family':<14} {'N':>4} {'places':>7} {'trans':>7} {'time s':>8} "
          f"{'verdict':<34} {'states':>9} {'viol':>5} {'traces':<10} technique", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for fam in args.families.split(","):
            topology, variant = fam.split("-")
            for n in (int(x) for x in args.sizes.split(",")):
                path = folder / f"random_{topology}_{variant}_{n}_s{args.seed}.rssm"
                path.write_text(random_system(n, topology, variant, args.seed),
                                encoding="utf-8")
                places, transitions = net_size(path)
                o = run_one(path, args.timeout)
                states = f"{o.states:,}" if o.states is not None else "-"
                print(f"{fam:<14} {n:>4} {places:>7} {transitions:>7} {o.seconds:>8.1f} "
                      f"{o.verdict[:34]:<34} {states:>9} {o.violations:>5} {o.traced:<10} "
                      f"{o.by}", flush=True)


if __name__ == "__main__":
    main()
