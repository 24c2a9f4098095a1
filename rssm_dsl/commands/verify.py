"""`rssmc verify`: safeness, deadlocks, progress and place invariants of the flattened HPN,
with counterexamples in the specification's words. Exit 0 verified, 1 violated,
2 inconclusive or input error."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Any

import typer

from rssm_dsl.commands.common import EXIT_USAGE, FileArg, Format, guarded, report

EXIT_INCONCLUSIVE = EXIT_USAGE


def verify_cmd(
    file: FileArg,
    max_states: Annotated[int, typer.Option("--max-states", min=1,
                          help="Give up (inconclusive) after exploring this many states.")]
    = 5_000_000,
    timeout: Annotated[float, typer.Option("--timeout", min=0.1,
                       help="Give up (inconclusive) after this many seconds.")] = 300.0,
    format: Annotated[Format, typer.Option("--format", "-f", help="text or json")] = Format.text,
    reduction: Annotated[str, typer.Option(
        help="auto (full exploration; when it does not fit, the compositional check, then "
             "stubborn sets), off (full exploration only), on (stubborn sets only), "
             "compositional (page by page, reduced modulo branching bisimulation)")]
    = "auto",
    invariants: Annotated[bool, typer.Option(help="Compute the minimal P-invariants.")] = True,
    progress_check: Annotated[bool, typer.Option("--progress-check/--no-progress-check",
                              help="Look for subsystems that can get stuck while the rest "
                                   "keeps running.")] = True,
    cross_check: Annotated[bool, typer.Option(
        "--cross-check", help="Also run SPIN (deadlock, safeness), 4ti2 (P-semiflows) and, on "
                              "small nets, cpncheck (the hierarchical .cpn) when installed, "
                              "and compare their verdicts with ours.")] = False,
    promela: Annotated[Path | None, typer.Option(help="Write the net as Promela to this file.")]
    = None,
    show_invariants: Annotated[bool, typer.Option(
        "--show-invariants", help="List every place invariant (in the specification's words).")]
    = False,
) -> None:
    """Prove the system's HPN safe and deadlock-free (and that no subsystem loses progress),
    or print a counterexample as a firing sequence of your behaviours and channels."""

    def run() -> int:
        from rssm_dsl.hpn.flatten import flatten
        from rssm_dsl.pipeline import compile_file
        from rssm_dsl.verify import VerifyOptions, render_text, verify
        from rssm_dsl.verify.statespace import Progress

        if reduction not in ("auto", "on", "off", "compositional"):
            typer.echo(f"rssmc: --reduction must be auto, on, off or compositional, not "
                       f"{reduction!r}", err=True)
            return EXIT_INCONCLUSIVE
        comp = compile_file(file)
        if not comp.ok or comp.hpn is None:
            report(comp, format)
            return EXIT_INCONCLUSIVE
        net = flatten(comp.hpn)
        if promela is not None:
            from rssm_dsl.emit.write import write_outputs
            from rssm_dsl.verify.promela import to_promela

            write_outputs(promela.parent if str(promela.parent) else Path("."),
                          {promela.name: to_promela(net)})
        live = format is Format.text and sys.stderr.isatty()

        def show(p: Progress) -> None:
            typer.echo(f"\r  exploring: {p.states:,} states, depth {p.depth}, "
                       f"frontier {p.frontier:,}   ", err=True, nl=False)

        options = VerifyOptions(max_states=max_states, time_limit=timeout, reduction=reduction,
                                invariants=invariants, check_progress=progress_check,
                                on_progress=show if live else None)
        result = verify(net, options)
        if live:
            typer.echo("\r" + " " * 70 + "\r", err=True, nl=False)
        extra: dict[str, Any] = {}
        text_extra: list[str] = []
        if cross_check:
            extra, text_extra = _cross_check(net, result, comp.hpn)
        if format is Format.json:
            import json

            data = result.to_json()
            if extra:
                data["cross_check"] = extra
            typer.echo(json.dumps(data, indent=2, ensure_ascii=False))
        else:
            typer.echo(render_text(result, max_invariants=10_000 if show_invariants else 0))
            for line in text_extra:
                typer.echo(line)
        return result.exit_code

    guarded(run)


CPNCHECK_MAX_STATES = 5_000


def _cross_check(net: Any, result: Any, hpn: Any = None) -> tuple[dict[str, Any], list[str]]:
    """SPIN and 4ti2 on the same flat net, cpncheck on the unflattened HPN (small nets
    only); their answers beside ours."""
    from rssm_dsl.verify.fourtitwo import semiflows_4ti2
    from rssm_dsl.verify.promela import run_spin

    out: dict[str, Any] = {}
    lines = ["", "independent cross-checks:"]
    spin = run_spin(net, separate=True)
    if not spin.available or not spin.ran:
        lines.append(f"  SPIN: not run ({spin.message})")
        out["spin"] = {"ran": False, "message": spin.message}
    else:
        # a violation SPIN found is definite; "none found" only counts after a complete search
        found = bool(spin.deadlock or spin.unsafe)
        agree = (spin.deadlock == (result.deadlock_free is False)
                 and spin.unsafe == (result.safe is False)) if spin.complete or found else None
        word = {True: "agrees", False: "DISAGREES", None: "incomplete search"}[agree]
        lines.append(f"  SPIN: deadlock={spin.deadlock} unsafe={spin.unsafe}, "
                     f"{spin.states_stored:,} states in {spin.total_seconds:.2f} s: {word}")
        out["spin"] = {"ran": True, "deadlock": spin.deadlock, "unsafe": spin.unsafe,
                       "states": spin.states_stored, "complete": spin.complete,
                       "seconds": round(spin.total_seconds, 3), "agrees": agree}
    fti = semiflows_4ti2(net)
    if not fti.available:
        lines.append(f"  4ti2: not run ({fti.message})")
        out["4ti2"] = {"ran": False, "message": fti.message}
    else:
        lines.append(f"  4ti2: {len(fti.semiflows)} minimal P-semiflows "
                     f"(ours: {len(result.invariants)}) in {fti.seconds:.2f} s")
        out["4ti2"] = {"ran": True, "semiflows": len(fti.semiflows),
                       "ours": len(result.invariants), "seconds": round(fti.seconds, 3)}
    # cpncheck expands the hierarchy of the .cpn export itself: it confirms our flattening
    if hpn is None or result.method != "full" or not result.complete:
        why = "no full exploration of ours to compare with" if hpn is not None else "no HPN"
        lines.append(f"  cpncheck: not run ({why})")
        out["cpncheck"] = {"ran": False, "message": why}
    elif result.states >= CPNCHECK_MAX_STATES:
        lines.append(f"  cpncheck: not run (too large: {result.states:,} states, limit "
                     f"{CPNCHECK_MAX_STATES:,})")
        out["cpncheck"] = {"ran": False, "message": "too large"}
    else:
        from rssm_dsl.verify.cpncheck_oracle import run_cpncheck

        cpn = run_cpncheck(hpn, max_states=2 * CPNCHECK_MAX_STATES)
        if not cpn.ran:
            lines.append(f"  cpncheck: not run ({cpn.message})")
            out["cpncheck"] = {"ran": False, "message": cpn.message}
        else:
            agree = (cpn.complete and cpn.states == result.states
                     and cpn.deadlock_free == result.deadlock_free
                     and cpn.unsafe == (result.safe is False))
            lines.append(f"  cpncheck (hierarchical .cpn): {cpn.states:,} states, "
                         f"{cpn.deadlocks} deadlock(s), unsafe={cpn.unsafe} in "
                         f"{cpn.seconds:.2f} s: {'agrees' if agree else 'DISAGREES'}")
            out["cpncheck"] = {"ran": True, "states": cpn.states, "deadlocks": cpn.deadlocks,
                               "unsafe": cpn.unsafe, "complete": cpn.complete,
                               "seconds": round(cpn.seconds, 3), "agrees": agree}
    return out, lines


def register(app: typer.Typer) -> None:
    app.command("verify")(verify_cmd)
