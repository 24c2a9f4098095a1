"""``rssmc run --viewer``: MuJoCo's passive viewer on the simulated LWR4+, paced at real time.

The viewer is a device observer: on its first call it opens ``mujoco.viewer.launch_passive`` on
the device's own model and data, then every 1/60 s of simulated time it shows the new state
and sleeps until the wall clock has caught up with the simulated clock, so the arm moves at
its real speed. Closing the window ends the run (as the last switch would). Where no window
can open (no display, or the viewer fails to start) :attr:`Viewer.problem` says why (W872)
and the run goes on headless.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from typing import Any

from rssm_dsl.interp.errors import StopSimulation
from rssm_dsl.run.video import has_display

FRAME = 1.0 / 60.0


def display_problem() -> str | None:
    """Why no viewer window can open here, or None when one may. GLFW is tried first: the
    viewer would end the whole process if it could not initialise it."""
    if not has_display():
        return ("there is no display (DISPLAY and WAYLAND_DISPLAY are unset): the run goes on "
                "headless; use --video FILE.mp4 to see it")
    try:
        import glfw  # type: ignore[import-untyped,unused-ignore]
    except ImportError:
        return "the glfw package (installed with mujoco) is missing: the run goes on headless"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok = bool(glfw.init())
    if not ok:
        where = os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") or "?"
        return (f"GLFW cannot open a window on the display {where}: the run goes on headless; "
                "use --video FILE.mp4 to see it")
    glfw.terminate()
    return None


class Viewer:
    def __init__(self) -> None:
        self.problem: str | None = None
        self.stop_message: str | None = None    # set when closing the window ended the run
        self._handle: Any = None
        self._failed = False
        self._t0 = 0.0          # wall clock at the first frame
        self._sim0 = 0.0
        self._next = 0.0

    def _open(self, device: Any) -> None:
        try:
            import mujoco.viewer  # type: ignore[import-untyped]

            self._handle = mujoco.viewer.launch_passive(device.arm.model, device.arm.data)
        except Exception as e:  # any failure to open is reported, not raised
            self._failed = True
            hint = " (on macOS, run rssmc with mjpython)" if sys.platform == "darwin" else ""
            self.problem = (f"MuJoCo's viewer did not open: {type(e).__name__}: {e}{hint}; "
                            "the run goes on headless")
            return
        self._t0 = time.perf_counter()
        self._sim0 = float(device.arm.data.time)

    def __call__(self, device: Any) -> None:
        if self._failed:
            return
        if self._handle is None:
            self._open(device)
            if self._handle is None:
                return
        sim = float(device.arm.data.time)
        if sim < self._next:
            return
        self._next = sim + FRAME
        if not self._handle.is_running():
            self.stop_message = f"the viewer window was closed at t = {sim:.3f} s"
            raise StopSimulation("stopped", self.stop_message)
        self._handle.sync()
        ahead = (sim - self._sim0) - (time.perf_counter() - self._t0)
        if ahead > 0:
            time.sleep(ahead)

    def close(self) -> None:
        if self._handle is not None:
            self._handle.close()
            self._handle = None
