"""Joint tracking of the Franka Panda examples, measured.

Runs a specification (examples/panda_joints.rssm by default) deterministically on simulated
time (the interpreter executing its net: c at 100 Hz computing minimum-jerk joint set points,
e.arm at 1 kHz running a joint PD with Pinocchio's gravity compensation, the Panda simulated
by MuJoCo from example-robot-data's URDF) and prints each arm's joint tracking error against
the set points its control subsystem sent, held to first order (rssm_dsl/run/joints.py), and
the speed (µs per 1 kHz device step of one arm, real-time factor). ``--spec
examples/panda_handover.rssm --switches 5`` measures the two arms of the handover over one
cycle. Needs ``pip install 'rssmc[robots]'``.

    python bench/panda.py [--spec FILE] [--until 5] [--switches 0] [--repeat 1] [--json out.json]
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
from rssm_dsl.run.joints import JointTracking, run_arms_tracking  # noqa: E402

SPEC = ROOT / "examples" / "panda_joints.rssm"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spec", type=Path, default=SPEC, help="the specification")
    parser.add_argument("--until", type=float, default=5.0, help="simulated seconds")
    parser.add_argument("--switches", type=int, default=0,
                        help="stop after this many switches of the first arm's control "
                        "subsystem (0: at --until)")
    parser.add_argument("--repeat", type=int, default=1, help="runs (speed: the median)")
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args(argv)
    if not _has_robot_data():
        print("skipped: example-robot-data is not installed: pip install 'rssmc[robots]'")
        return 0
    comp = compile_file(args.spec)
    if not comp.ok or comp.system is None:
        for d in comp.diagnostics:
            print(d.message, file=sys.stderr)
        return 1
    runs: list[tuple[JointTracking, ...]] = [
        run_arms_tracking(comp, args.until, switches=args.switches)
        for _ in range(max(1, args.repeat))]
    arms = runs[0]
    r = arms[0]
    us = statistics.median(x[0].us_per_step for x in runs)
    rtf = statistics.median(x[0].simulated / x[0].wall for x in runs)
    several = len(arms) > 1
    if several:
        print(f"{comp.system.name}: {len(arms)} arms simulated by MuJoCo")
    for a in arms:
        print(f"{'  arm        ' if several else comp.system.name + ': '}{a.rig.control} -> "
              f"{a.rig.effector} -> {a.rig.device} "
              f"{'(' + a.robot + ')' if several else '(Panda simulated by MuJoCo)'}")
    print(f"  simulated  {r.simulated:.3f} s: {r.device_steps} device steps"
          f"{' per arm' if several else ''}, {r.firings:,} firings ({r.reason})")
    print(f"  speed      {us / len(arms):.1f} us per device step, {rtf:.1f}x real time "
          f"(median of {len(runs)})")
    for a in arms:
        who = f"{a.rig.device} " if several else ""
        print(f"  tracking   {who}joint RMS {a.rms * 1e3:.3f} mrad, max "
              f"{a.max_abs * 1e3:.3f} mrad, {len(a.t)} samples")
        print(f"  per joint  {who}RMS " + " ".join(f"{x * 1e3:.3f}" for x in a.rms_per_joint)
              + " mrad")
    if args.json is not None:
        args.json.write_text(json.dumps({
            "simulated_s": r.simulated, "device_steps": r.device_steps,
            "us_per_device_step": us / len(arms), "real_time_factor": rtf,
            "arms": [{"device": a.rig.device, "rms_rad": a.rms, "max_abs_rad": a.max_abs,
                      "rms_per_joint_rad": [float(x) for x in a.rms_per_joint]}
                     for a in arms]}, indent=2) + "\n")
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
