"""`rssmc check` and `rssmc compile`."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from rssm_dsl.commands.common import (
    EXIT_ERRORS,
    EXIT_OK,
    EXIT_USAGE,
    OUTPUT_METAVAR,
    FileArg,
    Format,
    FormatOpt,
    QuietOpt,
    guarded,
    one_shot,
    output_folder,
    report,
)


def check(file: FileArg, format: FormatOpt = Format.text) -> None:
    """Parse and check a specification; print diagnostics. Exit 1 if there are errors."""

    def run() -> int:
        from rssm_dsl.pipeline import compile_file

        one_shot()
        # every diagnostic comes from the checks; building the HPN adds none
        comp = compile_file(file, build=False)
        report(comp, format)
        return EXIT_OK if comp.ok else EXIT_ERRORS

    guarded(run)


def compile_cmd(
    file: FileArg,
    output: Annotated[str | None, typer.Option("--output", "-o", metavar=OUTPUT_METAVAR,
                      help="Output folder (default: out/<file name>).")] = None,
    emit: Annotated[str, typer.Option(help="Comma-separated outputs: json, dump, dot, pnml, "
                                       "pnml-paged, cpn, mcc (Model Checking Contest input: "
                                       "mcc/model.pnml and property files).")]
    = "json,dump,dot,pnml",
    format: FormatOpt = Format.text,
    quiet: QuietOpt = False,
) -> None:
    """Check a specification and write its five-layer HPN (JSON IR, text dump, DOT, PNML).
    Nothing is written when there are errors."""

    def run() -> int:
        from rssm_dsl.emit.outputs import STREAMS, write_compiled
        from rssm_dsl.pipeline import compile_file

        one_shot()
        target = output_folder(output, Path("out") / file.stem)
        if target is None:
            return EXIT_USAGE
        kinds = [k.strip() for k in emit.split(",") if k.strip()]
        unknown = [k for k in kinds if k not in STREAMS]
        if unknown:
            typer.echo(f"rssmc: unknown --emit {', '.join(unknown)}; choose from "
                       f"{', '.join(STREAMS)}", err=True)
            return EXIT_USAGE
        comp = compile_file(file)
        report(comp, format, quiet)
        if not comp.ok or comp.hpn is None:
            return EXIT_ERRORS
        written = write_compiled(target, kinds, comp.hpn, comp.system)
        if not quiet and format is Format.text:
            h = comp.hpn
            typer.echo(f"HPN of system {h.system}: {len(h.pages)} pages, {len(h.places)} places, "
                       f"{len(h.transitions)} transitions, {len(h.fusions)} fusion places",
                       err=True)
            typer.echo(f"wrote {len(written)} files to {target}", err=True)
        return EXIT_OK

    guarded(run)


def register(app: typer.Typer) -> None:
    app.command("check")(check)
    app.command("compile")(compile_cmd)
