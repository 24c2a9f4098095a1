"""Joint tracking of the Franka Panda example (examples/panda_joints.rssm), measured.

Runs the specification deterministically on simulated time (the interpreter executing its
net: c at 100 Hz computing minimum-jerk joint set points, e.arm at 1 kHz running a joint PD
with Pinocchio's gravity compensation, the Panda simulated by MuJoCo from example-robot-data's
URDF) and prints the joint tracking error against the set points c sent, held to first order
(rssm_dsl/run/joints.py), and the speed (µs per 1 kHz device step, real-time factor).
Needs ``pip install 'rssmc[robots]'``.

    python bench/panda.py [--until 5] [--repeat 1] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from rssm_dsl.pipeline import compile_file  # noqa: E402
from rssm_dsl.run.joints import JointTracking, run_joint_tracking  # noqa: E402

SPEC = ROOT / "examples" / "panda_joints.rssm"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--until", type=float, default=5.0, help="simulated seconds")
    parser.add_argument("--repeat", type=int, default=1, help="runs (speed: the median)")
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args(argv)
    if not _has_robot_data():
        print("skipped: example-robot-data is not installed: pip install 'rssmc[robots]'")
        return 0
    comp = compile_file(SPEC)
    if not comp.ok:
        for d in comp.diagnostics:
            print(d.message, file=sys.stderr)
        return 1
    runs: list[JointTracking] = [run_joint_tracking(comp, args.until)
                                 for _ in range(max(1, args.repeat))]
    r = runs[0]
    us = statistics.median(x.us_per_step for x in runs)
    rtf = statistics.median(x.simulated / x.wall for x in runs)
    per_joint = r.rms_per_joint
    print(f"panda_joints: {r.rig.control} -> {r.rig.effector} -> {r.rig.device} "
          "(Panda simulated by MuJoCo)")
    print(f"  simulated  {r.simulated:.3f} s: {r.device_steps} device steps, "
          f"{r.firings:,} firings ({r.reason})")
    print(f"  speed      {us:.1f} us per device step, {rtf:.1f}x real time "
          f"(median of {len(runs)})")
    print(f"  tracking   joint RMS {r.rms * 1e3:.3f} mrad, max {r.max_abs * 1e3:.3f} mrad, "
          f"{len(r.t)} samples")
    print("  per joint  RMS " + " ".join(f"{x * 1e3:.3f}" for x in per_joint) + " mrad")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "simulated_s": r.simulated, "device_steps": r.device_steps,
            "us_per_device_step": us, "real_time_factor": rtf,
            "rms_rad": r.rms, "max_abs_rad": r.max_abs,
            "rms_per_joint_rad": [float(x) for x in per_joint]}, indent=2) + "\n")
    return 0 if r.ok else 1


def _has_robot_data() -> bool:
    import importlib.metadata

    try:
        importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return False
    return True


if __name__ == "__main__":
    sys.exit(main())
