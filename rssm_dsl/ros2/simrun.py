"""The LWR4+ experiment (``rssmc run``'s, rssm_dsl/run/) on ROS 2: every node of a built
workspace of the specification started from its ``system.launch.py`` on simulated time (the
MuJoCo device node is the clock, runtime/simclock.py) or on the wall clock, the topics
recorded by
rssm_dsl/ros2/record.py until the control subsystem switched behaviours ``switches`` times,
and the tracking figures computed from the recording (rssm_dsl/ros2/tracking.py).

Used by tests/ros2/test_lwr4.py and bench/ros2_lwr4.py.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from rssm_core.records import dataclass
from rssm_dsl.ros2 import toolchain, tracking
from rssm_dsl.ros2.generator import Workspace
from rssm_dsl.run.metrics import Metrics
from rssm_dsl.run.rig import Rig
from rssm_dsl.semantics.model import System


@dataclass(frozen=True)
class Topics:
    setpoint: str            # TOPIC=pkg/msg/Name of the set points the effector tracks
    state: str               # of the device's state (the end-effector position)
    status: str              # the control subsystem's diagnostics topic
    device_node: str         # the device node's fully qualified name
    control_node: str        # the control subsystem's
    interfaces: str


@dataclass(frozen=True)
class RosRun:
    recording: tracking.Recording
    metrics: Metrics
    wall: float              # s from the launch to the last switch recorded
    real_time_factor: float | None       # None: on the wall clock
    ok: bool                 # the control subsystem switched as often as asked
    log_dir: Path


def node_name(owner: str) -> str:
    """The node of a subsystem or device id: a1.c -> /a1/c, a1.e.lwr -> /a1/e_lwr."""
    agent, _, rest = owner.partition(".")
    return f"/{agent}/{rest.replace('.', '_')}"


def topics(ws: Workspace, system: System, rig: Rig) -> Topics:
    """The topics of the experiment's rig in the generated workspace."""
    state_ch = next(ch.id for ch in system.channels
                    if ch.producer.owner == rig.device and ch.consumer.owner == rig.effector)
    views = {c.channel: c for a in ws.view.agents for d in a.devices for c in d.channels_out}
    views |= {c.channel: c for a in ws.view.agents for n in a.nodes for c in n.outputs}
    sp, st = views[rig.setpoint_channel], views[state_ch]
    return Topics(f"{sp.topic}={sp.ros_type}", f"{st.topic}={st.ros_type}",
                  f"{node_name(rig.control)}/rssm/diagnostics", node_name(rig.device),
                  node_name(rig.control), ws.view.interfaces.package)


def run(built_env: dict[str, str], launch_file: Path, names: Topics, out: Path,
        real_time_factor: float | None, switches: int = 2, timeout: float = 300.0) -> RosRun:
    """Launch the system with use_sim_time at ``real_time_factor`` (None: on the wall clock),
    record until ``switches`` switches of the control subsystem (or ``timeout`` s), stop every
    node. ``built_env``: the workspace's environment with a DDS domain of its own and rssmc
    importable (toolchain.with_rssmc)."""
    out.mkdir(parents=True, exist_ok=True)
    recording = out / "recording.jsonl"
    logs = out / "logs"
    logs.mkdir(exist_ok=True)
    venv_python = str(Path(built_env["VIRTUAL_ENV"]) / "bin" / "python")
    rec_cmd = [venv_python, "-m", "rssm_dsl.ros2.record", "--interfaces", names.interfaces,
               "--setpoint", names.setpoint, "--state", names.state, "--status", names.status,
               "--switches", str(switches), "--timeout", str(timeout), "--out", str(recording)]
    # the device (the clock) and the control subsystem wait for the recorder's subscriptions
    # before their first iteration: nothing of the run goes unrecorded
    launch_cmd = [sys.executable, "-m", "rssm_dsl.ros2.launch_runner", "--log-dir", str(logs),
                  "--grace", "10",
                  "-p", f"{names.device_node}:rssm.observers:=1",
                  "-p", f"{names.control_node}:rssm.observers:=1", str(launch_file)]
    if real_time_factor is not None:
        launch_cmd[-1:-1] = ["-p", f"{names.device_node}:rssm.real_time_factor:="
                             f"{real_time_factor}"]
        launch_cmd.append("use_sim_time:=true")
    t0 = time.monotonic()
    with open(logs / "recorder.log", "wb") as rec_log:
        recorder = subprocess.Popen(rec_cmd, env=built_env, stdout=rec_log,
                                    stderr=subprocess.STDOUT, start_new_session=True)
    launcher: subprocess.Popen[bytes] | None = None
    try:
        _wait_ready(recorder, logs / "recorder.log")
        with open(logs / "launch.log", "wb") as launch_log:
            launcher = subprocess.Popen(launch_cmd, env=built_env, stdout=launch_log,
                                        stderr=subprocess.STDOUT, start_new_session=True)
        code = recorder.wait(timeout=timeout + 30)
        wall = time.monotonic() - t0
    finally:
        for p in (launcher, recorder):
            if p is not None:
                _stop(p)
    rec = tracking.load(recording)
    return RosRun(rec, tracking.metrics(rec), wall, real_time_factor,
                  code == 0 and len(rec.switches) >= switches, logs)


def _wait_ready(proc: subprocess.Popen[bytes], log: Path, timeout: float = 60.0) -> None:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if log.exists() and b"ready" in log.read_bytes():
            return
        if proc.poll() is not None:
            raise toolchain.ToolchainError(f"the recorder failed: {log.read_text()[-2000:]}")
        time.sleep(0.1)
    raise toolchain.ToolchainError(f"the recorder did not start in {timeout:g} s")


def _stop(proc: subprocess.Popen[bytes], grace: float = 15.0) -> None:
    """SIGINT to the process (the launch runner stops its nodes), SIGKILL to its process
    group after ``grace`` s."""
    if proc.poll() is None:
        try:
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=grace)
        except (ProcessLookupError, subprocess.TimeoutExpired):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
