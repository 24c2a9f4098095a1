"""`rssmc render` end to end: files, exit codes, diagnostics."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import ROOT
from tests.render.support import LWR4, lwr4_net, random_run, write_trace


def _rssmc(*args: str, path: str | None = None) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    if path is not None:
        env["PATH"] = path
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *args], capture_output=True,
                          text=True, cwd=ROOT, env=env, timeout=300, check=False)


@pytest.mark.external
@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz dot not installed")
def test_render_writes_a_figure_per_page_and_the_index(tmp_path: Path) -> None:
    out = tmp_path / "out"
    done = _rssmc("render", str(LWR4), "-o", str(out))
    assert done.returncode == 0, done.stderr
    svgs = sorted(p.name for p in out.glob("*.svg"))
    assert len(svgs) == 30 and "fig-PB_1_lwr_move.svg" in svgs and "fig-H.svg" in svgs
    assert (out / "index.html").is_file()
    assert not (out / "lwr4_circle.html").exists()  # --html not given
    assert "wrote 30 figures, index.html to" in done.stderr


@pytest.mark.external
@pytest.mark.skipif(shutil.which("dot") is None, reason="Graphviz dot not installed")
def test_render_with_a_trace_writes_the_explorer(tmp_path: Path) -> None:
    trace = write_trace(tmp_path / "t.jsonl", random_run(lwr4_net(), 40, seed=9))
    done = _rssmc("render", str(LWR4), "-o", str(tmp_path / "out"), "--trace", str(trace))
    assert done.returncode == 0, done.stderr
    html = (tmp_path / "out" / "lwr4_circle.html").read_text()
    assert '"kind":"trace"' in html
    assert "playback: 40 firings" in done.stderr


def test_without_graphviz_it_says_so_and_writes_the_explorer(tmp_path: Path) -> None:
    empty = tmp_path / "bin"
    empty.mkdir()
    out = tmp_path / "out"
    done = _rssmc("render", str(LWR4), "-o", str(out), path=str(empty))
    assert done.returncode == 0, done.stderr
    assert "warning[W850]" in done.stderr and "Graphviz `dot` is not installed" in done.stderr
    assert not list(out.glob("*.svg"))
    assert (out / "lwr4_circle.html").is_file()
    assert "No figures were drawn" in (out / "index.html").read_text()


def test_a_bad_trace_is_a_coded_error_and_nothing_is_written(tmp_path: Path) -> None:
    trace = tmp_path / "t.jsonl"
    trace.write_text('{"event": "fire", "transition": "t[out]"}\n')
    out = tmp_path / "out"
    done = _rssmc("render", str(LWR4), "-o", str(out), "--trace", str(trace), "--format", "json")
    assert done.returncode == 1
    diags = json.loads(done.stdout)
    assert [(d["code"], d["span"]["file"], d["span"]["line"]) for d in diags] == [
        ("E854", str(trace), 1)]
    assert not out.exists()


def test_a_spec_with_errors_renders_nothing(tmp_path: Path) -> None:
    spec = tmp_path / "bad.rssm"
    spec.write_text("system s { agent a { control c { behaviour b { } } } ")
    done = _rssmc("render", str(spec), "-o", str(tmp_path / "out"), "--no-svg")
    assert done.returncode == 1
    assert "error[E" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "out").exists()
