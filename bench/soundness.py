"""Soundness harness: random specs, every engine of `rssmc verify`, verdicts compared and
counterexamples replayed in the interpreter (tests/soundness/checker.py).

    python bench/soundness.py [--count N] [--seed S] [--jobs J] [--seconds T] [--out DIR]

Runs the specs of seeds S .. S+N-1 (tests/soundness/generator.py) and prints the count, the
disagreements, each engine's undecided count and the total time. Each disagreeing spec is
written to DIR (default out/soundness/) as SEED.rssm with what disagreed in its header.
Exit code 1 when a spec disagrees, does not check, or crashes the harness.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.soundness.checker import (  # noqa: E402
    ENGINES,
    Limits,
    SpecResult,
    check_spec,
    known_error,
)
from tests.soundness.generator import generate  # noqa: E402


def run_one(seed: int, limits: Limits) -> tuple[int, SpecResult, frozenset[str], str]:
    spec = generate(seed)
    return seed, check_spec(spec.text, f"seed{seed}", limits), spec.features, spec.text


def write_disagreement(out: Path, seed: int, text: str, result: SpecResult) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"seed{seed}.rssm"
    lines = [f"// soundness harness, seed {seed}: what disagreed"]
    lines += [f"//   {d}" for d in result.disagreements]
    if result.error:
        lines += [f"//   {x}" for x in result.error.splitlines()]
    lines += [f"//   {e}: {o.verdict} (safe={o.safe}, deadlock_free={o.deadlock_free}, "
              f"progress_ok={o.progress_ok}, lost={sorted(o.lost)}, "
              f"properties={o.properties}, {o.method}, {o.seconds:.2f} s)"
              for e, o in result.outcomes.items()]
    path.write_text("\n".join(lines) + "\n" + text, encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--seconds", type=float, default=2.0, help="limit per engine and spec")
    ap.add_argument("--max-states", type=int, default=60_000)
    ap.add_argument("--out", type=Path, default=ROOT / "out" / "soundness")
    ap.add_argument("--verbose", action="store_true", help="one line per spec")
    args = ap.parse_args(argv)
    limits = Limits(args.seconds, args.max_states)
    start = time.monotonic()
    undecided: Counter[str] = Counter()
    features: Counter[str] = Counter()
    kinds: Counter[str] = Counter()
    known: Counter[str] = Counter()
    unexplained = 0
    bad: list[tuple[int, SpecResult]] = []
    replays = 0
    seeds = range(args.seed, args.seed + args.count)
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [pool.submit(run_one, s, limits) for s in seeds]
        for k, fut in enumerate(futures, start=1):
            seed, result, feats, text = fut.result()
            features.update(feats)
            replays += result.replays
            for e, o in result.outcomes.items():
                undecided[e] += o.undecided
            kinds.update(d.what.split(" of ")[0] for d in result.disagreements)
            bugs = {result.known(d) for d in result.disagreements}
            if result.error:
                bugs.add(known_error(result.error))
            known.update(b for b in bugs if b is not None)
            unexplained += None in bugs
            if result.disagreements or result.error:
                bad.append((seed, result))
                path = write_disagreement(args.out, seed, text, result)
                print(f"seed {seed}: {len(result.disagreements)} disagreement(s)"
                      f"{', ' + result.error.splitlines()[0] if result.error else ''} -> "
                      f"{path.relative_to(ROOT) if path.is_relative_to(ROOT) else path}",
                      flush=True)
            elif args.verbose:
                print(f"seed {seed}: ok ({result.seconds:.1f} s)", flush=True)
            if k % 50 == 0:
                print(f"... {k} specs, {len(bad)} disagreeing, "
                      f"{time.monotonic() - start:.0f} s", flush=True)
    total = time.monotonic() - start
    n = len(seeds)
    print(f"specs: {n} (seeds {args.seed}..{args.seed + n - 1}), {args.jobs} job(s), "
          f"limits {limits.seconds:g} s / {limits.max_states:,} states per engine")
    print(f"disagreeing specs: {len(bad)}" + (f" ({dict(kinds)})" if kinds else ""))
    print(f"  explained by known engine bugs (tests/soundness/checker.py KNOWN_BUGS): "
          f"{dict(known) if known else 'none'}")
    print(f"  unexplained (new): {unexplained}")
    print(f"counterexamples replayed: {replays}")
    print("undecided (per engine, specs with some answer not decided within the limits):")
    for e in ENGINES:
        print(f"  {e:<14} {undecided[e]:>6} ({100 * undecided[e] / max(n, 1):.1f} %)")
    print(f"time: {total:.1f} s ({total / max(n, 1):.2f} s per spec)")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
