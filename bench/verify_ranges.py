"""Time to verdict of a property as a tracked range grows: one controller with two ranged
counters (`waited: 0..N`, `busy: 0..10`) written by one `update memory`, a receptor, a device
of random readings, and `always a.c.waited <= N`; `rssmc verify --no-simulation` in its own
process, compilation included, for each N, and the growth from the smallest N to the
largest, measured in the same invocation. The states stay few (hundreds); what grows is the
value-tracked net of the property's slice (a variant of each transition function per value
pair). Before the conflict masks were built from the consumers' masks
(rssm_dsl/verify/netbits.py), N = 20 took 2.9 s, N = 30 14.6 s and N = 50 266 s.

    python bench/verify_ranges.py [--sizes 10 20 30 50]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SPEC = """device receptor Eye @ 10 Hz {{
  output blocked: bool nonblocking
  binding "rssm_stdlib.devices.random_values:RandomDevice"
}}

system cliff {{
  agent a {{
    control @ 10 Hz {{
      input seen: bool from r.eye
      memory waited: 0..{n} = 0
      memory busy: 0..10 = 0

      behaviour wait {{
        update memory {{
          waited := waited + 1
          busy := 0
        }}
        terminal arrived when seen
        terminal timed_out when waited >= {n}
      }}
      behaviour other {{
        update memory {{
          waited := 0
          busy := busy + 1
        }}
        terminal back when busy >= 10
      }}
      initial wait
      switch wait -> other otherwise
      switch other -> wait when back
    }}
    receptor eye @ 10 Hz {{
      input beam: bool from R.eye
      output seen: bool to c
      behaviour relay {{
        update seen {{ seen := beam }}
        terminal never when false
      }}
      initial relay
    }}
    real receptor eye: Eye
  }}
  property bounded: always a.c.waited <= {n}
}}
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 30, 50])
    args = ap.parse_args()
    times: dict[int, float] = {}
    with tempfile.TemporaryDirectory() as d:
        for n in args.sizes:
            spec = Path(d) / f"cliff{n}.rssm"
            spec.write_text(SPEC.format(n=n))
            t = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "rssm_dsl", "verify", str(spec),
                                "--no-simulation"], capture_output=True, text=True,
                               timeout=3600, check=False)
            times[n] = time.perf_counter() - t
            head = r.stdout.splitlines()[0] if r.stdout else r.stderr.strip()[:200]
            found = re.search(r"the properties: (\d+) states at most", r.stdout)
            states = found.group(1) if found else "?"
            print(f"N = {n:3}: {times[n]:6.2f} s, exit {r.returncode}, {head}; "
                  f"the property's exploration: {states} states")
    lo, hi = min(times), max(times)
    print(f"growth from N = {lo} to N = {hi}: {times[hi] / times[lo]:.1f}x "
          f"(the range grows {hi / lo:.1f}x)")


if __name__ == "__main__":
    main()
