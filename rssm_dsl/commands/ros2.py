"""`rssmc ros2`: generate the ROS 2 packages of a system (docs/ros2.md)."""

from __future__ import annotations

import re
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
    output_folder,
    report,
    usage_error,
)

MAINTAINER = re.compile(r"\s*([^<>]+?)\s*<([^<>\s]+@[^<>\s]+)>\s*\Z")


def ros2(
    file: FileArg,
    output: Annotated[str | None, typer.Option(
        "--output", "-o", metavar=OUTPUT_METAVAR, help="The colcon workspace's src folder to "
        "write (default: out/<file name>/ros2_ws/src).")] = None,
    maintainer: Annotated[str, typer.Option(
        help="Maintainer written into package.xml and setup.py, as 'Name <email>'.")]
    = "rssmc <rssmc@example.com>",
    license: Annotated[str, typer.Option(help="License of the generated packages.")]
    = "Apache-2.0",
    format: FormatOpt = Format.text,
    quiet: QuietOpt = False,
) -> None:
    """Generate a colcon workspace: an interfaces package with the system's message types, a
    runtime package, and per agent an ament_python package with one node per subsystem, a
    launch file and a parameters file. Nothing is written when there are errors."""

    def run() -> int:
        from rssm_dsl.diagnostics.render import render_json, render_text
        from rssm_dsl.pipeline import compile_file
        from rssm_dsl.ros2.generator import generate, write_workspace
        from rssm_dsl.ros2.viewmodel import Options

        target = output_folder(output, Path("out") / file.stem / "ros2_ws" / "src")
        if target is None:
            return EXIT_USAGE
        m = MAINTAINER.match(maintainer)
        if m is None or not license.strip() or any(c in license for c in "<>&\n"):
            return usage_error("--maintainer must be 'Name <email>' and --license a plain "
                               "license name", "for example --maintainer 'Ada Lovelace "
                               "<ada@example.org>' --license Apache-2.0")
        comp = compile_file(file)
        if not comp.ok or comp.system is None:
            report(comp, format, quiet)
            return EXIT_ERRORS
        ws = generate(comp, Options(m.group(1), m.group(2), license.strip()))
        diags = ws if isinstance(ws, list) else [*comp.diagnostics, *ws.warnings]
        if format is Format.json:
            typer.echo(render_json(list(diags)))
        elif diags:
            typer.echo(render_text(list(diags), comp.program.line), err=True)
        if isinstance(ws, list):
            return EXIT_ERRORS
        written = write_workspace(ws, target)
        if not quiet and format is Format.text:
            typer.echo(f"wrote {len(written)} files of {len(ws.packages)} packages "
                       f"({', '.join(ws.packages)}) to {target}", err=True)
            typer.echo(f"build: cd {target.parent} && colcon build", err=True)
        return EXIT_OK

    guarded(run)


def register(app: typer.Typer) -> None:
    app.command("ros2")(ros2)
