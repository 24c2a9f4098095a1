"""The concurrent mode: operations in worker threads, wall-clock pacing, same semantics."""

from __future__ import annotations

import itertools
import shutil
import threading
from pathlib import Path

from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.interp import RunConfig, SimOptions, Simulator
from rssm_dsl.verify.netbits import NetBits, to_mask
from tests.interp.conftest import EXAMPLES, SPECS, compiled, runtime


def test_concurrent_run_fires_only_enabled_transitions(tmp_path: Path) -> None:
    for name in ("camera_tracker.rssm", "camera.csv"):
        shutil.copy(EXAMPLES / name, tmp_path / name)
    comp = compiled(tmp_path / "camera_tracker.rssm")
    assert comp.hpn is not None
    nb = NetBits.of(flatten(comp.hpn))
    rt = runtime(comp, RunConfig(base_dir=tmp_path, wall_clock=True))
    # (the stall watch off: on a loaded machine a second of wall clock may see no iteration)
    sim = Simulator(rt, SimOptions(mode="concurrent", until=1.0, record_markings=True,
                                   workers=3, stall_periods=0))
    result = sim.run()
    assert result.reason == "until", result.message
    ms = [to_mask(m) for m in sim.markings]
    assert len(ms) >= 2, "nothing fired"
    for a, b in itertools.pairwise(ms):
        t = next((t for t in range(nb.ntrans) if a & nb.pre[t] == nb.pre[t]
                  and nb.fire(a, t) == b), None)
        assert t is not None, "a step that is not a firing of the net"
    c = rt.subsystems["a1.c"]
    # paced at 30 Hz for 1 s of wall clock: never ahead of the clock (a loaded machine lags,
    # perhaps to no iteration at all)
    assert c.i <= 31


def test_operations_run_in_worker_threads(tmp_path: Path) -> None:
    (tmp_path / "where.py").write_text(
        "import threading\nNAMES = set()\n"
        "def where(x):\n    NAMES.add(threading.current_thread().name)\n    return x + 1.0\n")
    (tmp_path / "w.rssm").write_text("""
extern where(x: float) -> float = "where:where"
system w {
  agent a1 {
    control c @ 200 Hz {
      memory x: float = 0.0
      behaviour b {
        update memory { x := where(x) }
        terminal never when false
      }
      initial b
    }
  }
}
""")
    comp = compiled(tmp_path / "w.rssm")
    rt = runtime(comp, RunConfig(base_dir=tmp_path, wall_clock=True))
    result = Simulator(rt, SimOptions(mode="concurrent", until=0.2)).run()
    import where  # type: ignore[import-not-found]  # loaded from the spec's folder

    assert result.reason == "until"
    assert where.NAMES and all(n.startswith("rssm-op") for n in where.NAMES)
    assert threading.current_thread().name not in where.NAMES
    assert rt.subsystems["a1.c"].vars["x"] >= 5


def test_concurrent_deadlock_and_error_path(tmp_path: Path) -> None:
    comp = compiled(SPECS / "handshake_deadlock.rssm")
    rt = runtime(comp, RunConfig(base_dir=SPECS, wall_clock=True))
    result = Simulator(rt, SimOptions(mode="concurrent", until=5.0)).run()
    assert result.reason == "deadlock" and result.wall < 5.0
    d = tmp_path / "proj"
    shutil.copytree(SPECS, d)
    comp = compiled(d / "faulty.rssm")
    rt = runtime(comp, RunConfig(base_dir=d, wall_clock=True))
    result = Simulator(rt, SimOptions(mode="concurrent", until=10.0)).run()
    c = rt.subsystems["a1.c"]
    assert result.reason == "finished", result.message
    assert c.handled_errors == 1 and c.vars["recovered"] == 1
