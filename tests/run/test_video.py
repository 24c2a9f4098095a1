"""`rssmc run --video`: offscreen rendering (EGL here, no display) encoded as MP4, and the PNG
frames written instead when PyAV is missing; `--viewer` on a virtual display (Xvfb)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import av  # type: ignore[import-untyped,import-not-found,unused-ignore]
import pytest

from tests.run.conftest import LWR4, rssmc

SHORT = ("--until", "0.5", "--switches", "0")


def test_video_is_rendered_offscreen(tmp_path: Path) -> None:
    video = tmp_path / "clip" / "run.mp4"
    r = rssmc("run", LWR4, "-o", tmp_path / "out", "--video", video, *SHORT,
              env={"DISPLAY": "", "WAYLAND_DISPLAY": ""})
    assert r.returncode == 0, r.stderr
    assert "W873" not in r.stderr and "frames to" in r.stdout
    assert video.read_bytes()[4:8] == b"ftyp"
    with av.open(str(video)) as container:
        frames = [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]
    written = int(r.stdout.split(" frames to ")[0].rsplit(" ", 1)[1])
    assert len(frames) == written == 15              # 0.5 s at 30 frames/s
    assert frames[0].shape == (480, 640, 3)
    assert frames[0].mean() > 5.0                    # the arm is drawn, not a black frame
    assert not (frames[0] == frames[-1]).all()       # and it moves


def test_without_pyav_the_frames_are_png(tmp_path: Path) -> None:
    video = tmp_path / "run.mp4"
    code = ("import sys; sys.modules['av'] = None; from rssm_dsl.cli import entry; "
            "sys.argv[0] = 'rssmc'; entry()")
    r = rssmc("run", LWR4, "-o", tmp_path / "out", "--video", video, "--until", "0.2",
              "--switches", "0", python=("-c", code), env={"DISPLAY": "", "WAYLAND_DISPLAY": ""})
    assert r.returncode == 0, r.stderr
    assert "W873" in r.stderr and "PyAV is not installed" in r.stderr
    frames = sorted((tmp_path / "run-frames").iterdir())
    assert len(frames) == 6 and frames[0].name == "frame0000.png"
    assert frames[0].read_bytes().startswith(b"\x89PNG")
    assert not video.exists()


@pytest.mark.skipif(shutil.which("xvfb-run") is None, reason="needs xvfb-run (.ci/run installs it)")
def test_viewer_on_a_virtual_display_shows_the_same_run(tmp_path: Path) -> None:
    args = ("--until", "0.3", "--switches", "0", "-q")
    r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1024x768x24", sys.executable, "-m",
                        "rssm_dsl", "run", str(LWR4), "-o", str(tmp_path / "shown"),
                        "--viewer", *args], capture_output=True, text=True, timeout=300,
                       env={**os.environ, "WAYLAND_DISPLAY": ""})
    assert r.returncode == 0, r.stderr
    assert "W872" not in r.stderr
    r = rssmc("run", LWR4, "-o", tmp_path / "headless", *args)
    assert r.returncode == 0, r.stderr
    # the viewer only looks: the run is the same
    assert (tmp_path / "shown" / "trajectory.csv").read_bytes() == \
        (tmp_path / "headless" / "trajectory.csv").read_bytes()
