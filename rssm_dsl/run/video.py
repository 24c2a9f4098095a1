"""A short video of a run, rendered offscreen after it: the recorded joint angles are replayed
through MuJoCo's kinematics and drawn with ``mujoco.Renderer`` (the desired circle in grey, the
path drawn so far in the colour of the control subsystem's behaviour), then encoded as MP4
(H.264) with PyAV.

Offscreen rendering needs an OpenGL backend. MuJoCo chooses it when it is imported, from
``MUJOCO_GL``: :func:`choose_backend` sets ``egl`` when there is no display (call it before
anything imports mujoco); EGL needs the system's ``libEGL`` and a Mesa driver. Without PyAV the
frames are written as PNG files instead. Either problem is a W873 warning that says what
to install, never a crash.
"""

from __future__ import annotations

import itertools
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rssm_core.records import dataclass
from rssm_dsl.extras import install_command

if TYPE_CHECKING:
    from rssm_dsl.run.experiment import Experiment

INSTALL_GL = ("install an OpenGL backend for offscreen rendering: on Debian/Ubuntu "
              "`apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri` (MUJOCO_GL=egl), or "
              "`apt-get install libosmesa6` and set MUJOCO_GL=osmesa")
INSTALL_AV = f"install PyAV to encode MP4: {install_command('video')}"
RGB = {0: (0.12, 0.47, 0.71), 1: (0.84, 0.15, 0.16), 2: (0.17, 0.63, 0.17)}


def has_display() -> bool:
    if sys.platform.startswith("linux"):
        return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))
    return True


def choose_backend() -> str | None:
    """Set MUJOCO_GL for offscreen rendering when the user has not; returns the backend."""
    if "MUJOCO_GL" not in os.environ and not has_display():
        os.environ["MUJOCO_GL"] = "egl"
    return os.environ.get("MUJOCO_GL")


@dataclass(frozen=True)
class VideoResult:
    path: Path | None            # the MP4 written, or the folder of PNG frames
    frames: int
    problem: str | None          # why there is no MP4 (W873), with what to install


def _frame_indices(t: np.ndarray[Any, Any], fps: float) -> list[int]:
    if len(t) == 0:
        return []
    times = np.arange(t[0], t[-1] + 1e-9, 1.0 / fps)
    return [int(k) for k in np.minimum(np.searchsorted(t, times), len(t) - 1)]


def _add_line(scene: Any, a: np.ndarray[Any, Any], b: np.ndarray[Any, Any], width: float,
              rgba: tuple[float, float, float, float]) -> None:
    """A line segment decoration (cheap to draw, unlike spheres, in software rendering)."""
    import mujoco  # type: ignore[import-untyped]

    if scene.ngeom >= scene.maxgeom:
        return
    geom = scene.geoms[scene.ngeom]
    mujoco.mjv_initGeom(geom, mujoco.mjtGeom.mjGEOM_LINE, np.zeros(3), np.zeros(3),
                        np.eye(3).ravel(), np.array(rgba, dtype=np.float32))
    mujoco.mjv_connector(geom, mujoco.mjtGeom.mjGEOM_LINE, width,
                         np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
    scene.ngeom += 1


def render_frames(exp: Experiment, fps: float, width: int, height: int
                  ) -> tuple[list[np.ndarray[Any, Any]], str | None]:
    """The frames (RGB uint8), or the reason they cannot be rendered."""
    s = exp.samples
    if s.q is None or exp.model is None:
        return [], "the run did not record the joint angles"
    try:
        import mujoco

        model = exp.model
        data = mujoco.MjData(model)
        renderer = mujoco.Renderer(model, height, width)
    except Exception as e:  # any GL failure is reported, not raised
        backend = os.environ.get("MUJOCO_GL", "glfw")
        return [], (f"MuJoCo cannot render offscreen with MUJOCO_GL={backend}: "
                    f"{type(e).__name__}: {e}; {INSTALL_GL}")
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = (0.33, 0.0, 0.45)        # between the base and the circle
    camera.distance = 1.3
    camera.azimuth = 215.0
    camera.elevation = -38.0
    n = len(s.t)
    ring = s.desired[:: max(1, n // 96)]
    behaviours = {b: i for i, b in enumerate(dict.fromkeys(s.behaviour))}
    every = max(1, round(0.01 / float(np.median(np.diff(s.t))))) if n > 1 else 1
    frames: list[np.ndarray[Any, Any]] = []
    try:
        for k in _frame_indices(s.t, fps):
            data.qpos[:] = s.q[k]
            mujoco.mj_forward(model, data)
            renderer.update_scene(data, camera)
            scene = renderer.scene
            scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = 0   # 2-3x faster in software GL
            scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = 0
            for a, b in itertools.pairwise(ring):
                _add_line(scene, a, b, 2.0, (0.7, 0.7, 0.7, 1.0))
            for j in range(every, k + 1, every):
                r, g, b_ = RGB[behaviours[s.behaviour[j]] % len(RGB)]
                _add_line(scene, s.actual[j - every], s.actual[j], 4.0, (r, g, b_, 1.0))
            frames.append(renderer.render().copy())
    finally:
        renderer.close()
    return frames, None


def _encode(frames: list[np.ndarray[Any, Any]], fps: float, path: Path) -> None:
    import av  # type: ignore[import-untyped,import-not-found,unused-ignore]

    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp_name = tempfile.mkstemp(suffix=path.suffix or ".mp4", prefix=".rssmc-",
                                    dir=path.parent)
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        height, width = frames[0].shape[:2]
        with av.open(str(tmp), mode="w", format="mp4") as container:
            codec = "libx264" if "libx264" in av.codecs_available else "mpeg4"
            stream: Any = container.add_stream(codec, rate=round(fps))
            stream.width, stream.height = width, height
            stream.pix_fmt = "yuv420p"
            for img in frames:
                for packet in stream.encode(av.VideoFrame.from_ndarray(img, format="rgb24")):
                    container.mux(packet)
            for packet in stream.encode():
                container.mux(packet)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)          # mkstemp makes it private
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _write_pngs(frames: list[np.ndarray[Any, Any]], folder: Path) -> None:
    from matplotlib.image import imsave

    folder.mkdir(parents=True, exist_ok=True)
    digits = max(4, int(math.log10(max(1, len(frames)))) + 1)
    for k, img in enumerate(frames):
        imsave(folder / f"frame{k:0{digits}d}.png", img)


def write_video(exp: Experiment, path: Path, fps: float = 30.0, width: int = 640,
                height: int = 480) -> VideoResult:
    """Render the run and write ``path`` (MP4); see the module docstring for the fallbacks."""
    frames, problem = render_frames(exp, fps, width, height)
    if problem is not None:
        return VideoResult(None, 0, problem)
    try:
        import av  # type: ignore[import-untyped,import-not-found,unused-ignore]  # noqa: F401
    except ImportError:
        folder = path.with_name(path.stem + "-frames")
        _write_pngs(frames, folder)
        return VideoResult(folder, len(frames),
                           f"PyAV is not installed: wrote {len(frames)} PNG frames to {folder} "
                           f"instead of {path}; {INSTALL_AV}")
    _encode(frames, fps, path)
    return VideoResult(path, len(frames), None)
