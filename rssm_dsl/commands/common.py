"""What the commands share: exit codes, the diagnostics format, the common arguments and
options, the guard that turns a crash into an internal-error report, and the diagnostics
report. `rssm_dsl.cli` imports the commands; the commands import this module, never the CLI.

Exit codes: 0 success (warnings allowed); 1 the specification has errors (or, for verify,
a property is violated); 2 a usage error (for verify, also a specification that does not
compile); 70 internal error; 130 interrupted (Ctrl-C). `rssmc verify` adds 3 inconclusive
and 4 verified without the progress check (rssm_dsl/commands/verify.py).
"""

from __future__ import annotations

import contextlib
import gc
import os
import sys
import traceback
from collections.abc import Callable
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

if TYPE_CHECKING:
    from rssm_dsl.pipeline import Compilation

EXIT_OK, EXIT_ERRORS, EXIT_USAGE, EXIT_INTERNAL = 0, 1, 2, 70
EXIT_INTERRUPTED = 130
EXIT_STUCK = 3           # simulate: a deadlock, or a subsystem stalled while the rest ran


class Format(str, Enum):
    text = "text"
    json = "json"


FileArg = Annotated[Path, typer.Argument(help="The .rssm file of the system.", show_default=False)]
# The output folder is taken as text: a Path option turns `-o ''` into `.`, the current folder.
OUTPUT_METAVAR = "PATH"


def output_folder(given: str | None, default: Path) -> Path | None:
    """The folder of the outputs of a command: ``given`` (``--output``/``-o``) or
    ``default``. None, with the problem printed (E880, a usage error: nothing is written),
    when ``given`` is empty or names something that is not a folder."""
    if given is None:
        return default
    problem = None
    if not given:
        problem = ("the output folder (--output/-o) is empty",
                   "name the folder (-o out/spec; -o . for the current folder), or leave the "
                   "option out for out/<file name>")
    else:
        path = Path(given)
        try:
            taken = path.exists() and not path.is_dir()
            path.resolve()
            in_file = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
            if in_file is not None and not taken:
                problem = (f"the output folder '{_shown(given)}' (--output/-o) is inside "
                           f"'{_shown(str(in_file))}', which is a file, not a folder",
                           "name a folder whose parents are folders")
        except RuntimeError:              # a symbolic link loop
            problem = (f"the output folder '{_shown(given)}' (--output/-o) is a symbolic "
                       "link loop", "name a folder, or remove the links")
            taken = False
        except (OSError, ValueError):     # not looked up here: the writer says why
            taken = False
        if taken:
            from rssm_dsl.diagnostics.diagnostic import bound_text

            problem = (f"the output folder '{bound_text(given)}' (--output/-o) is a file, "
                       "not a folder", "name a folder, or remove the file")
    if problem is None:
        return Path(given)
    typer.echo(f"rssmc: error[E880]: {problem[0]}", err=True)
    typer.echo(f"  help: {problem[1]}", err=True)
    return None


BAD_OPTION_VALUE = "E890"    # an option's value the command does not take (also rssm_dsl/cli.py)


def usage_error(message: str, help: str) -> int:
    """Print a usage error of an option's value (E890: nothing is run or written) with what
    to do, and return the exit code of a usage error. The texts may quote what the user gave:
    they are bounded and their control characters escaped."""
    typer.echo(f"rssmc: error[{BAD_OPTION_VALUE}]: {_shown(message)}", err=True)
    typer.echo(f"  help: {_shown(help)}", err=True)
    return EXIT_USAGE


def _shown(text: str) -> str:
    from rssm_dsl.diagnostics.diagnostic import bound_text

    return bound_text(text)


def output_file_problem(path: Path, option: str, inputs: tuple[Path, ...] = ()) -> bool:
    """Print E880 and return True when the file ``option`` writes cannot be written as a
    file: it is a folder, a FIFO or a device (writing would hang or fill it), a symbolic link
    loop, or one of the command's ``inputs`` (the spec itself would be overwritten)."""
    import stat

    problem = None
    try:
        mode = path.stat().st_mode if path.exists() else None
        if mode is not None and not stat.S_ISREG(mode):
            what = "a folder" if stat.S_ISDIR(mode) else "not a regular file"
            problem = (f"{option} '{_shown(str(path))}' is {what}",
                       f"give {option} the name of a file to write")
        elif mode is not None and any(_same(path, x) for x in inputs):
            problem = (f"{option} '{_shown(str(path))}' is the specification itself",
                       "write it to another file: it would overwrite the spec")
    except RuntimeError:
        problem = (f"{option} '{_shown(str(path))}' is a symbolic link loop",
                   f"give {option} the name of a file to write")
    except (OSError, ValueError):         # not looked up here: the writer says why
        return False
    if problem is None:
        return False
    typer.echo(f"rssmc: error[E880]: {problem[0]}", err=True)
    typer.echo(f"  help: {problem[1]}", err=True)
    return True


def _same(a: Path, b: Path) -> bool:
    try:
        return a.samefile(b)
    except (OSError, ValueError, RuntimeError):
        return False


FormatOpt = Annotated[Format, typer.Option("--format", "-f", help="How to print diagnostics.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing on success.")]


_one_shot = False


def one_shot(collector: bool = False) -> None:
    """A command that computes once and ends: the cyclic garbage collector off for the rest
    of the command (unless `collector`), and the process ends without tearing its objects
    down (`exit_now`).
    What the compiler allocates lives until the command ends and is freed by reference
    counting; with the collector on, its first pass after compiling rescans every node (0.5 s
    of 4 s on 1 MB of dense expressions), and the interpreter's teardown of the modules and
    the syntax tree at exit is an eighth of `rssmc check`'s run on the LWR4+ example.
    Only for commands that leave nothing to finish at exit: files written and closed, no
    threads, subprocesses or temporary files."""
    global _one_shot
    _one_shot = True
    if not collector:
        gc.disable()


def exit_now(code: object) -> None:
    """After a one-shot command (`one_shot`), flush the output and end the process with
    `code` (a SystemExit's) without the interpreter's teardown; otherwise return."""
    if not _one_shot:
        return
    if isinstance(code, str):
        print(code, file=sys.stderr)
    status = code if isinstance(code, int) else 0 if code is None else 1
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe (`rssmc check f | head -1`)
            stream.flush()
    os._exit(status)


def guarded(fn: Callable[[], int]) -> None:
    """Run a command body; turn an unexpected exception into a clear internal-error report.
    A file that cannot be read or written (no permission, a full disk, an output path too
    long for the file system) is most often the environment's problem: it is told as such,
    exit 2, with a pointer to report it if the paths are right."""
    from rssm_dsl.diagnostics.diagnostic import bound_text
    from rssm_dsl.filenames import UnusableFileName

    try:
        code = fn()
    except (typer.Exit, KeyboardInterrupt):
        raise
    except (OSError, UnusableFileName) as e:
        if isinstance(e, OSError):
            where = f": '{e.filename}'" if e.filename else ""
            what = f"{e.strerror or type(e).__name__}{where}"
        else:
            what = str(e)
        typer.echo(f"rssmc: error[E881]: {bound_text(what)}", err=True)
        typer.echo("  help: check the paths given to the command (the files it writes: "
                   "--output/-o, --trace, ...) and their permissions; if they are right, this "
                   "is a bug in rssmc: please report it (set RSSMC_DEBUG=1 for the traceback)",
                   err=True)
        if os.environ.get("RSSMC_DEBUG"):
            traceback.print_exc()
        raise typer.Exit(EXIT_USAGE) from None
    except Exception as e:
        typer.echo(f"rssmc: internal error [E900]: {type(e).__name__}: {bound_text(str(e))}", err=True)
        typer.echo("  help: this is a bug in rssmc; please report it with the input file"
                   " (set RSSMC_DEBUG=1 for the traceback)", err=True)
        if os.environ.get("RSSMC_DEBUG"):
            traceback.print_exc()
        raise typer.Exit(EXIT_INTERNAL) from None
    raise typer.Exit(code)


def report(comp: Compilation, fmt: Format, quiet: bool = False) -> None:
    """Print the diagnostics of a compilation (text on stderr with a summary line, or JSON
    on stdout)."""
    from rssm_dsl.diagnostics.render import json_chunks, render_text, summary
    from rssm_dsl.source import escape_controls

    diags = list(comp.diagnostics)
    if fmt is Format.json:
        for chunk in json_chunks(diags):
            typer.echo(chunk, nl=False)
        typer.echo()
        return
    if diags:
        typer.echo(render_text(diags, comp.program.line), err=True)
    if diags or not quiet:
        typer.echo(f"{escape_controls(str(comp.path))}: {summary(diags)}", err=True)
