"""Time to verdict of the properties stated in a spec: the handover of
examples/verify/ with two state invariants over its arm and base added (one holds, one is
violated), and lockstep with its own two properties; `rssmc verify` as a user runs it, in
its own process, compilation included.

    python bench/verify_properties.py
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
HANDOVER_PROPERTIES = """
  property no_stale_clamp: always not (base.c in unload and base.c.clamped)
  property no_release_while_docking: always not (arm.c in release and base.c in dock)
}
"""


def run(spec: Path) -> tuple[dict[str, object], float]:
    start = time.monotonic()
    out = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec), "--format",
                          "json"], capture_output=True, text=True, cwd=ROOT, check=False)
    return json.loads(out.stdout), time.monotonic() - start


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        handover = Path(tmp) / "handover_with_properties.rssm"
        text = (ROOT / "examples" / "verify" / "handover.rssm").read_text(encoding="utf-8")
        handover.write_text(text.rstrip().removesuffix("}") + HANDOVER_PROPERTIES,
                            encoding="utf-8")
        print(f"{'spec':<28} {'verdict':<10} {'time s':>7}  properties")
        for spec in (handover, ROOT / "examples" / "verify" / "lockstep.rssm"):
            report, seconds = run(spec)
            props = report.get("user_properties", [])
            assert isinstance(props, list)
            words = ", ".join(f"{p['name']}: {p['why']}" for p in props)
            print(f"{spec.stem:<28} {report['verdict']!s:<10} {seconds:>7.1f}  {words}")


if __name__ == "__main__":
    main()
