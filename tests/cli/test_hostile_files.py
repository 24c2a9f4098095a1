"""Hostile files given to the commands: each is a coded diagnostic, never a traceback nor an
internal error (E900, exit 70), and a failed command writes nothing.

1. a root spec that is a symbolic link loop: E001 from every command (read_source, the one
   place spec files are read);
2. trace and replay files that are no regular files (a FIFO, /dev/zero), nested too deeply,
   not UTF-8, with integers of too many digits: E852 (`render --trace`, `simulate --replay`);
3. a quoted import of a file that is not a spec: E014, and nothing of the file is shown;
4. `fmt` on a FIFO: E002; `compile -o ''` (which meant the current folder): E880;
5. the trace of a system that finished replays to its end: exit 0;
6. a seeded fuzz of a real trace (truncated, bytes flipped, nested, huge numbers, wrong
   types) fed to `simulate --replay` and `render --trace` in-process.

The few cases that could block or read without end (a FIFO, /dev/zero) run as subprocesses
with a timeout; the others in-process (typer's CliRunner), which is much faster.
"""

from __future__ import annotations

import gc
import json
import os
import random
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner, Result

from rssm_dsl.cli import make_app
from rssm_dsl.commands import common
from rssm_dsl.pipeline import compile_file
from tests.conftest import EXAMPLES, ROOT

FINISHES = EXAMPLES / "semantics" / "iteration.rssm"     # both subsystems reach their end
INTERNAL = 70


@pytest.fixture(autouse=True)
def _collector_back() -> Iterator[None]:
    """A one-shot command run in-process turns the cyclic collector off (one_shot): on again
    after each test."""
    yield
    common._one_shot = False
    gc.enable()


def invoke(*args: str | Path) -> Result:
    result = CliRunner().invoke(make_app(), [str(a) for a in args])
    assert result.exit_code != INTERNAL, result.output
    assert "Traceback" not in result.output and "[E900]" not in result.output, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), (
        repr(result.exception))
    return result


def rssmc(*args: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    done = subprocess.run([sys.executable, "-m", "rssm_dsl", *map(str, args)], cwd=cwd,
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert done.returncode != INTERNAL, done.stderr
    assert "Traceback" not in done.stderr + done.stdout, done.stderr
    return done


def coded(output: str, code: str) -> bool:
    return f"[{code}]" in output


@pytest.fixture(scope="module")
def finished_trace(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The trace of a run of a system that finishes (all its subsystems reach an end)."""
    path = tmp_path_factory.mktemp("trace") / "finished.jsonl"
    result = CliRunner().invoke(make_app(), ["simulate", str(FINISHES), "--trace", str(path),
                                             "-q"])
    assert result.exit_code == 0, result.output
    last = json.loads(path.read_text(encoding="utf-8").splitlines()[-1])
    assert last["event"] == "end" and last["reason"] == "finished"
    return path


# ---------------------------------------------------------------- 1. a symbolic link loop

@pytest.mark.parametrize("command", ["check", "compile", "render", "ros2", "simulate",
                                     "verify", "fmt"])
def test_a_root_spec_that_is_a_symlink_loop_is_E001_everywhere(tmp_path: Path,
                                                               command: str) -> None:
    loop = tmp_path / "l.rssm"
    loop.symlink_to("l.rssm")
    out = tmp_path / "out"
    args: list[str | Path] = [command, loop]
    if command in ("compile", "render", "ros2"):
        args += ["-o", out]
    result = invoke(*args)
    assert result.exit_code in (1, 2), result.output   # verify, fmt: 2 (usage); others: 1
    assert coded(result.output, "E001") and "symbolic link" in result.output
    assert not out.exists()


@pytest.mark.parametrize("form", ['"other.rssm"', "other"])
@pytest.mark.parametrize(("kind", "code"), [("loop", "E001"), ("fifo", "E002"),
                                           ("folder", "E002")])
def test_an_import_that_names_no_readable_file_says_why_at_the_import(
        tmp_path: Path, kind: str, code: str, form: str) -> None:
    """Quoted (`import "other.rssm"`) or dotted (`import other`), the same reason: the
    dotted form said "cannot find module" (E009) of a FIFO that is there."""
    target = tmp_path / "other.rssm"
    if kind == "loop":
        target.symlink_to("other.rssm")
    elif kind == "fifo":
        os.mkfifo(target)                 # never opened: the loader looks before it reads
    else:
        target.mkdir()
    spec = tmp_path / "s.rssm"
    spec.write_text(f"import {form}\n" + (FINISHES.read_text(encoding="utf-8")))
    comp = compile_file(spec)
    (d,) = [d for d in comp.diagnostics if d.is_error]
    assert d.code == code and d.span.line == 1


# ---------------------------------------------------------------- 2. trace and replay files

@pytest.mark.parametrize("kind", ["fifo", "dev-zero", "folder"])
def test_a_trace_that_is_no_regular_file_is_E852(tmp_path: Path, kind: str) -> None:
    if kind == "fifo":
        path = tmp_path / "t.jsonl"
        os.mkfifo(path)                   # nobody writes it: opening it would block
    elif kind == "dev-zero":
        path = Path("/dev/zero")          # read without bound, it never ends
        if not path.exists():
            pytest.skip("no /dev/zero here")
    else:
        path = tmp_path / "t.jsonl"
        path.mkdir()
    out = tmp_path / "out"
    replay = rssmc("simulate", FINISHES, "--replay", path, "-q", cwd=tmp_path)
    assert replay.returncode == 2 and coded(replay.stderr, "E852"), replay.stderr
    assert "not a regular file" in replay.stderr
    render = rssmc("render", FINISHES, "--no-svg", "--trace", path, "-o", out, cwd=tmp_path)
    assert render.returncode == 1 and coded(render.stderr, "E852"), render.stderr
    assert "not a regular file" in render.stderr
    assert not out.exists()


def _deep(depth: int) -> str:
    return "[" * depth + "]" * depth


@pytest.mark.parametrize("kind", ["deep-document", "deep-line", "deep-later-line", "latin1",
                                  "huge-integer", "long-line", "large-document", "empty",
                                  "blank"])
def test_a_malformed_trace_is_E852(tmp_path: Path, finished_trace: Path, kind: str,
                                   monkeypatch: pytest.MonkeyPatch) -> None:
    # a report --replay reads whole may be 256 MB: the test lowers that cap to 8 MB
    monkeypatch.setattr("rssm_dsl.interp.replay.MAX_REPORT_BYTES", 8 << 20)
    lines = finished_trace.read_bytes().split(b"\n")
    if kind == "deep-document":
        data = _deep(200_000).encode()
    elif kind == "deep-line":
        data = b'{"event": ' + _deep(200_000).encode() + b"}\n"
    elif kind == "deep-later-line":
        lines[5] = b'{"event":"fire","transition":' + _deep(100_000).encode() + b"}"
        data = b"\n".join(lines)
    elif kind == "latin1":
        data = "{\"event\": \"caf\xe9\"}\n".encode("latin-1")
    elif kind == "huge-integer":
        lines[3] = lines[3].replace(b'"step":', b'"step":' + b"9" * 5000 + b',"x":', 1)
        data = b"\n".join(lines)
    elif kind == "long-line":                 # a line of 9 MB: more than MAX_FILE_BYTES
        data = b"\n".join([lines[0], b'{"event":"fire","transition":"' + b"x" * (9 << 20)
                           + b'"}'])
    elif kind == "empty":                     # render drew a playback of 0 firings
        data = b""
    elif kind == "blank":
        data = b"\n  \n\t\n"
    else:                                     # a JSON document of 9 MB on many lines
        data = b"[\n" + b'"t",\n' * ((9 << 20) // 5) + b'"t"]\n'
    path = tmp_path / "t.jsonl"
    path.write_bytes(data)
    replay = invoke("simulate", FINISHES, "--replay", path, "-q")
    assert replay.exit_code == 2 and coded(replay.output, "E852"), replay.output
    out = tmp_path / "out"
    render = invoke("render", FINISHES, "--no-svg", "--trace", path, "-o", out)
    assert render.exit_code == 1 and coded(render.output, "E852"), render.output
    assert not out.exists()


# ---------------------------------------------------------------- 3. imports of other files

SECRET = "TOP SECRET: the content of a file that is no spec"


@pytest.mark.parametrize("name", ["notes.txt", "data", "page.rssm.html"])
def test_an_import_of_a_file_that_is_no_spec_is_E014_without_its_content(
        tmp_path: Path, name: str) -> None:
    (tmp_path / name).write_text(SECRET + "\nmore\n", encoding="utf-8")
    spec = tmp_path / "s.rssm"
    text = f'import "{name}"\n' + FINISHES.read_text(encoding="utf-8")
    spec.write_text(text, encoding="utf-8")
    result = invoke("check", spec, "--format", "json")
    assert result.exit_code == 1
    diags = json.loads(result.stdout)
    assert [d["code"] for d in diags] == ["E014"] and diags[0]["span"]["line"] == 1
    assert "SECRET" not in result.output
    # the editor compiles with the buffer's text (overrides): the same, nothing shown
    comp = compile_file(spec, {spec.resolve(): text}, build=False)
    assert [d.code for d in comp.diagnostics] == ["E014"]
    assert not any("SECRET" in src.text for src in comp.program.sources.values())


def test_an_import_of_etc_passwd_shows_nothing_of_it(tmp_path: Path) -> None:
    if not Path("/etc/passwd").is_file():
        pytest.skip("no /etc/passwd here")
    first = Path("/etc/passwd").read_text(encoding="utf-8", errors="replace").split("\n")[0]
    spec = tmp_path / "s.rssm"
    spec.write_text('import "/etc/passwd"\n' + FINISHES.read_text(encoding="utf-8"))
    result = invoke("check", spec)
    assert result.exit_code == 1 and coded(result.output, "E014")
    assert first not in result.output


# ---------------------------------------------------------------- 4. fmt, output folders

def test_fmt_of_a_fifo_says_it_is_not_a_regular_file(tmp_path: Path) -> None:
    fifo = tmp_path / "f.rssm"
    os.mkfifo(fifo)
    done = rssmc("fmt", fifo, cwd=tmp_path)         # a path that names no file: usage, 2
    assert done.returncode == 2 and coded(done.stderr, "E002"), done.stderr
    assert "not a regular file" in done.stderr and "no such file" not in done.stderr
    missing = rssmc("fmt", "--check", "missing.rssm", cwd=tmp_path)
    assert missing.returncode == 2 and coded(missing.stderr, "E001"), missing.stderr


@pytest.mark.parametrize("command", ["compile", "render"])
def test_an_empty_output_folder_is_a_coded_usage_error(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str) -> None:
    monkeypatch.chdir(tmp_path)
    before = sorted(os.listdir(tmp_path))
    result = invoke(command, FINISHES, "-o", "")
    assert result.exit_code == 2 and coded(result.output, "E880"), result.output
    (tmp_path / "file").write_text("x")
    result = invoke(command, FINISHES, "-o", "file")
    assert result.exit_code == 2 and coded(result.output, "E880"), result.output
    assert sorted(os.listdir(tmp_path)) == sorted([*before, "file"])
    assert (tmp_path / "file").read_text() == "x"


@pytest.mark.parametrize("command", ["compile", "render", "ros2"])
def test_an_output_folder_inside_a_file_is_E880_and_names_the_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str) -> None:
    """`-o afile/sub`: the folder cannot be made because `afile` is a file; the message says
    so (it said "File exists" and named no file)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_text("x")
    result = invoke(command, FINISHES, "-o", "afile/sub")
    assert result.exit_code == 2 and coded(result.output, "E880"), result.output
    assert "'afile'" in result.output, result.output
    assert sorted(os.listdir(tmp_path)) == ["afile"]
    assert (tmp_path / "afile").read_text() == "x"


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs /proc (Linux)")
@pytest.mark.parametrize("command", ["compile", "render", "ros2"])
def test_an_output_folder_the_file_system_refuses_is_E881_naming_it(command: str) -> None:
    """`-o /proc/out`: no folder can be made there; the message names /proc/out (it named
    the hidden staging folder that rssmc tried to make beside it)."""
    result = invoke(command, FINISHES, "-o", "/proc/rssmc-out")
    assert result.exit_code == 2 and coded(result.output, "E881"), result.output
    assert "'/proc/rssmc-out'" in result.output and ".rssmc-" not in result.output


# ---------------------------------------------------------------- 5. a finished run replays

def test_the_trace_of_a_finished_system_replays_to_its_end(finished_trace: Path) -> None:
    result = invoke("simulate", FINISHES, "--replay", finished_trace)
    assert result.exit_code == 0, result.output
    assert "replay: replayed" in result.output and "finished" in result.output
    result = invoke("simulate", FINISHES, "--replay", finished_trace, "-f", "json")
    assert result.exit_code == 0
    assert json.loads(result.stdout)["replay"]["reproduced"] is True


# ---------------------------------------------------------------- 6. fuzz

WRONG = [None, [], {}, "", "x", 0, -1, 3, True, 1.5, 1e308, -1e308, [1, 2], {"a": 1},
         "t[in]", "\u202e", 2 ** 70]


def _wrong_types(lines: list[bytes], rng: random.Random) -> list[bytes]:
    out = list(lines)
    for _ in range(rng.randint(1, 3)):
        k = rng.randrange(len(out))
        try:
            obj = json.loads(out[k])
        except ValueError:
            continue
        if not isinstance(obj, dict) or not obj:
            continue
        key = rng.choice(sorted(obj))
        obj[key] = rng.choice(WRONG)
        out[k] = json.dumps(obj).encode()
    return out


def _huge_numbers(lines: list[bytes], rng: random.Random) -> list[bytes]:
    out = list(lines)
    number = rng.choice([b"9" * 25, b"9" * 4400, b"-" + b"9" * 400, b"1e999", b"-1e999",
                         b"NaN", b"Infinity", b"1e-999", b"0.1e400"])
    for _ in range(rng.randint(1, 3)):
        k = rng.randrange(len(out))
        for field in (b'"step":', b'"time":', b'"format":'):
            at = out[k].find(field)
            if at >= 0:
                end = at + len(field)
                stop = end
                while stop < len(out[k]) and out[k][stop:stop + 1] in b"0123456789.-e":
                    stop += 1
                out[k] = out[k][:end] + number + out[k][stop:]
                break
    return out


def _document(lines: list[bytes], rng: random.Random) -> bytes:
    """The trace's transitions as one of the JSON documents a replay reads, spoiled a bit."""
    names: list[object] = []
    for raw in lines:
        try:
            obj = json.loads(raw)
        except ValueError:
            continue
        if isinstance(obj, dict) and obj.get("event") == "fire":
            names.append(obj.get("transition"))
    for _ in range(rng.randint(0, 3)):
        if names:
            names[rng.randrange(len(names))] = rng.choice(WRONG)
    steps = names[: rng.randint(0, len(names))]
    shape = rng.randrange(5)
    doc: object
    if shape == 0:
        doc = steps
    elif shape == 1:
        doc = {"kind": rng.choice(["deadlock", "unsafe", "progress", "property", 7]),
               "steps": steps, "cycle": rng.choice([steps[:3], "x", None]),
               "values": rng.choice([[], [{"step": 1e999}], "v", [{"step": 1, "subsystem": "a",
                                                               "variable": "b", "value": []}]])}
    elif shape == 2:
        doc = {"verdict": "violated", "deadlocks": [{"kind": "deadlock", "steps": steps}]}
    elif shape == 3:
        doc = {"user_properties": [{"name": rng.choice(["p", 3]), "holds": False,
                                    "kind": "always", "counterexample": {"steps": steps}}]}
    else:
        doc = {"steps": {"steps": {"steps": steps}}}
    return json.dumps(doc).encode()


def mutate(base: bytes, rng: random.Random) -> tuple[str, bytes]:
    lines = base.split(b"\n")
    kind = rng.choice(["truncate", "flip", "structural", "nest", "nest-line", "huge",
                       "types", "drop", "shuffle", "restart", "document"])
    if kind == "truncate":
        return kind, base[: rng.randrange(len(base))]
    if kind in ("flip", "structural"):
        data = bytearray(base)
        for _ in range(rng.randint(1, 20)):
            at = rng.randrange(len(data))
            data[at] = rng.randrange(256) if kind == "flip" else rng.choice(b'{}[]",:\n\x00\xff\\')
        return kind, bytes(data)
    if kind in ("nest", "nest-line"):
        depth = rng.choice([10, 500, 5000, 100_000])
        k = rng.randrange(len(lines))
        if kind == "nest":
            lines[k] = lines[k].replace(b'"transition":', b'"transition":' + b"[" * depth, 1)
            lines[k] = lines[k].replace(b',"role"', b"]" * depth + b',"role"', 1)
        else:
            lines[k] = b"[" * depth + lines[k] + b"]" * depth
        return kind, b"\n".join(lines)
    if kind == "huge":
        return kind, b"\n".join(_huge_numbers(lines, rng))
    if kind == "types":
        return kind, b"\n".join(_wrong_types(lines, rng))
    if kind == "drop":
        keep = [raw for raw in lines if rng.random() > 0.2]
        return kind, b"\n".join(keep)
    if kind == "shuffle":
        a = rng.randrange(len(lines))
        b = min(len(lines), a + rng.randint(2, 10))
        part = lines[a:b]
        rng.shuffle(part)
        return kind, b"\n".join(lines[:a] + part + lines[b:])
    if kind == "restart":                     # the header again, later
        k = rng.randrange(1, len(lines))
        return kind, b"\n".join([*lines[:k], lines[0], *lines[k:]])
    return kind, _document(lines, rng)


def test_fuzzed_traces_never_crash_replay_or_playback(tmp_path: Path,
                                                      finished_trace: Path) -> None:
    """Seeded: the same cases at every run. Every exit code is one of the documented ones,
    never 70; no traceback; a failed render writes nothing."""
    rng = random.Random(20261129)
    base = finished_trace.read_bytes()
    path = tmp_path / "fuzzed.jsonl"
    out = tmp_path / "out"
    seen: dict[str, set[int]] = {}
    for n in range(100):
        kind, data = mutate(base, rng)
        path.write_bytes(data)
        replay = invoke("simulate", FINISHES, "--replay", path, "-q")
        assert replay.exit_code in (0, 1, 2, 3), (n, kind, replay.output)
        render = invoke("render", FINISHES, "--no-svg", "--trace", path, "-o", out, "-q")
        assert render.exit_code in (0, 1, 2), (n, kind, render.output)
        if render.exit_code != 0:
            assert not out.exists(), (n, kind, render.output)
        elif out.exists():
            shutil.rmtree(out)
        seen.setdefault(kind, set()).update({replay.exit_code, render.exit_code})
    assert len(seen) >= 8, seen               # the mutations are varied
    assert any(1 in codes or 2 in codes for codes in seen.values())


# ---------------------------------------------------------------- files a command writes

def test_an_output_file_that_is_a_fifo_the_spec_or_a_loop_is_E880(tmp_path: Path) -> None:
    """--trace into a FIFO would hang for ever, onto the spec it would overwrite it; an
    output folder that is a link loop: each is E880 (exit 2), nothing written or hung."""
    spec = tmp_path / "s.rssm"
    text = FINISHES.read_text(encoding="utf-8")
    spec.write_text(text, encoding="utf-8")
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    for target in (fifo, spec, tmp_path):
        r = invoke("simulate", spec, "--until", "0.1", "--trace", target, "-q")
        assert r.exit_code == 2 and coded(r.output, "E880"), r.output
    assert spec.read_text(encoding="utf-8") == text
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    for command in ("compile", "render", "ros2"):
        r = invoke(command, spec, "-o", tmp_path / "a")
        assert r.exit_code == 2 and coded(r.output, "E880"), (command, r.output)


@pytest.mark.parametrize(("command", "taken"), [("compile", "iteration.hpn.json"),
                                                ("render", "index.html")])
def test_an_output_whose_place_is_a_folder_writes_nothing(tmp_path: Path, command: str,
                                                          taken: str) -> None:
    """A file the command would write is a folder in the target: it fails before it moves
    anything into place (before, the files sorted ahead of it were already there)."""
    out = tmp_path / "out"
    (out / taken).mkdir(parents=True)
    r = invoke(command, FINISHES, "-o", out)
    assert r.exit_code == 2 and "Traceback" not in r.output, r.output
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*")) == [taken]
