"""Drawing the figures of a large system: every page laid out by Graphviz `dot`, one process
per page, one at a time against one per core (rssm_dsl/render/svg.py, ``draw_figures``), in
the same invocation; the size of the explorer (`rssmc render --html`).

    python bench/render_pages.py [--agents 100] [--jobs N]
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from rssm_dsl.hpn.flatten import flatten  # noqa: E402
from rssm_dsl.pipeline import compile_file  # noqa: E402
from rssm_dsl.render.html import render_explorer  # noqa: E402
from rssm_dsl.render.names import figure_files  # noqa: E402
from rssm_dsl.render.svg import draw_figures  # noqa: E402
from rssm_dsl.synth import lean_ring_system  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--agents", type=int, default=100)
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args()
    dot = shutil.which("dot")
    if dot is None:
        sys.exit("needs Graphviz dot (apt-get install graphviz)")
    with tempfile.TemporaryDirectory() as d:
        spec = Path(d) / "ring.rssm"
        spec.write_text(lean_ring_system(args.agents))
        comp = compile_file(spec)
        assert comp.ok and comp.hpn is not None, comp.diagnostics
        hpn = comp.hpn
        names = figure_files(hpn)
        print(f"lean ring of {args.agents} agents: {len(names)} pages")
        timings = {}
        for jobs in (1, args.jobs):
            t = time.perf_counter()
            svgs, problems = draw_figures(hpn, names, dot, jobs=jobs)
            timings[jobs] = time.perf_counter() - t
            size = sum(len(s) for s in svgs.values())
            print(f"  jobs={jobs}: {timings[jobs]:.1f} s, {size / 1e6:.1f} MB of SVG, "
                  f"{len(problems)} pages with the quick layout or not drawn")
        print(f"  speed-up with {args.jobs} jobs: {timings[1] / timings[args.jobs]:.2f}x")
        html = render_explorer(hpn, flatten(hpn), comp.program, str(spec), names, None, None)
        print(f"  explorer (--html): {len(html.encode()) / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
