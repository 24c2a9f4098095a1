"""The explorer stays bounded as the run gets longer: simulate an example for increasing
durations (`rssmc simulate --trace --series`), render the explorer with both (`rssmc render
--no-svg --trace --series`), and open it in real headless Chromium (Selenium, cut off from the
network, as tests/render/browser.py does). Per duration: the firings and the size of the trace,
the size of the HTML file and the steps it embeds (a window of at most --max-steps), the time
until the explorer says it is ready (its own performance.now() when it sets data-ready, the
median of a few loads), and the time of a seek far away (the step box, to its ends, middle
and quarters); each against the shortest run.

    python bench/explorer_load.py [--spec examples/lwr4_circle.rssm] [--durations 2 20 60]

Needs Debian's chromium and chromium-driver (apt-get install chromium chromium-driver).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from tests.render.browser import CHROMEDRIVER, CHROMIUM, chromium, open_explorer  # noqa: E402

LOADS = 5


@dataclass
class Row:
    seconds: float
    firings: int
    trace_bytes: int
    series_bytes: int
    simulate_s: float
    render_s: float
    html_bytes: int
    embedded: int
    load_ms: float
    seek_ms: float


def _rssmc(*args: str) -> tuple[subprocess.CompletedProcess[str], float]:
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "rssm_dsl", *args], capture_output=True,
                          text=True, cwd=ROOT, check=False)
    return done, time.perf_counter() - start


def _produce(spec: Path, seconds: float, tmp: Path) -> tuple[Path, Path, float]:
    trace, series = tmp / f"run{seconds:g}.jsonl", tmp / f"run{seconds:g}.npz"
    done, took = _rssmc("simulate", str(spec), "--until", str(seconds), "--no-live", "-q",
                        "--trace", str(trace), "--series", str(series))
    if done.returncode != 0:
        raise SystemExit(f"simulate {seconds:g} s exited {done.returncode}: {done.stderr[-600:]}")
    return trace, series, took


def _render(spec: Path, trace: Path, series: Path, out: Path) -> tuple[Path, float]:
    done, took = _rssmc("render", str(spec), "--no-svg", "-q", "-o", str(out), "--trace",
                        str(trace), "--series", str(series))
    if done.returncode != 0:
        raise SystemExit(f"render exited {done.returncode}: {done.stderr[-600:]}")
    (html,) = [p for p in out.glob("*.html") if p.name != "index.html"]
    return html, took


def _embedded(html: Path) -> tuple[int, int]:
    """(firings in the trace, steps embedded) as the page says."""
    text = html.read_text(encoding="utf-8")
    block = text.split('id="rssm-data">', 1)[1].split("</script>", 1)[0]
    play = json.loads(block)["playback"]
    return int(play["total"]), len(play["fired"])


_SEEK = """
const box = document.getElementById('stepbox'), lo = +box.min, hi = +box.max, took = [];
for (const f of [1, 0.5, 0.25, 0.75, 0, 1]) {
  box.value = String(Math.round(lo + f * (hi - lo)));
  const start = performance.now();
  box.dispatchEvent(new Event('change'));
  took.push(performance.now() - start);
}
return took;
"""


def _browse(driver: Any, html: Path) -> tuple[float, float]:
    """Median load time to ready (ms) and median time of a seek far away (ms)."""
    loads: list[float] = []
    seeks: list[float] = []
    for _ in range(LOADS):
        loads.append(open_explorer(driver, html, timeout=300))
        seeks += [float(t) for t in driver.execute_script(_SEEK)]
    return statistics.median(loads), statistics.median(seeks)


def measure(spec: Path, durations: list[float]) -> list[Row]:
    rows = []
    with tempfile.TemporaryDirectory(prefix="rssmc-explorer-load-") as name, chromium() as driver:
        tmp = Path(name)
        for seconds in durations:
            trace, series, sim_s = _produce(spec, seconds, tmp)
            html, render_s = _render(spec, trace, series, tmp / f"out{seconds:g}")
            total, embedded = _embedded(html)
            load_ms, seek_ms = _browse(driver, html)
            rows.append(Row(seconds, total, trace.stat().st_size, series.stat().st_size, sim_s,
                            render_s, html.stat().st_size, embedded, load_ms, seek_ms))
            print(f"  {seconds:g} s done", file=sys.stderr, flush=True)
            trace.unlink()
    return rows


def table(spec: Path, rows: list[Row]) -> str:
    head = (f"{'run':>6} {'firings':>10} {'trace MB':>9} {'series kB':>10} {'render s':>9} "
            f"{'HTML kB':>8} {'embedded':>9} {'load ms':>8} {'seek ms':>8} "
            f"{'HTML x':>7} {'load x':>7} {'trace x':>8}")
    lines = [f"explorer of {spec.relative_to(ROOT) if spec.is_relative_to(ROOT) else spec} "
             f"(trace + series), headless Chromium, median of {LOADS} loads", head]
    first = rows[0]
    for r in rows:
        lines.append(
            f"{r.seconds:>5g}s {r.firings:>10,} {r.trace_bytes / 1e6:>9.1f} "
            f"{r.series_bytes / 1e3:>10.1f} {r.render_s:>9.1f} {r.html_bytes / 1e3:>8.0f} "
            f"{r.embedded:>9,} {r.load_ms:>8.0f} {r.seek_ms:>8.1f} "
            f"{r.html_bytes / first.html_bytes:>6.2f}x {r.load_ms / first.load_ms:>6.2f}x "
            f"{r.trace_bytes / first.trace_bytes:>7.1f}x")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--spec", type=Path, default=ROOT / "examples" / "lwr4_circle.rssm")
    ap.add_argument("--durations", type=float, nargs="+", default=[2.0, 20.0, 60.0])
    args = ap.parse_args()
    if CHROMIUM is None or CHROMEDRIVER is None:
        raise SystemExit("needs headless Chromium: apt-get install chromium chromium-driver")
    spec = args.spec.resolve()
    print(table(spec, measure(spec, sorted(args.durations))))


if __name__ == "__main__":
    main()
