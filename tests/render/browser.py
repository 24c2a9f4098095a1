"""Headless Chromium (Debian's chromium + chromium-driver) driven by Selenium, cut off from
the network: a proxy that points nowhere, no host name resolves, and every request the page
makes is recorded from the DevTools performance log so a test can prove there were none."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")

needs_chromium = pytest.mark.skipif(
    CHROMIUM is None or CHROMEDRIVER is None,
    reason="headless Chromium not installed (Debian: apt-get install chromium chromium-driver)")

FLAGS = ["--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--no-first-run", "--no-default-browser-check", "--disable-extensions",
         "--window-size=1600,1000", "--proxy-server=http://127.0.0.1:9",
         "--host-resolver-rules=MAP * ~NOTFOUND"]


@contextmanager
def chromium() -> Iterator[Any]:
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    assert CHROMIUM is not None and CHROMEDRIVER is not None
    profile = tempfile.mkdtemp(prefix="rssmc-chromium-")
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for flag in [*FLAGS, f"--user-data-dir={profile}"]:
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def requests(driver: Any) -> list[tuple[str, str]]:
    """(URL, URL of the document that asked for it) of every request since the last call,
    the browser's own chrome:// pages included."""
    out = []
    for entry in driver.get_log("performance"):
        msg = json.loads(entry["message"])["message"]
        if msg.get("method") == "Network.requestWillBeSent":
            params = msg["params"]
            out.append((params["request"]["url"], params.get("documentURL", "")))
    return out


NETWORK_SCHEMES = ("http:", "https:", "ws:", "wss:", "ftp:")


def rssmc(*args: str) -> subprocess.CompletedProcess[str]:
    """Run rssmc from the repository's root."""
    return subprocess.run([sys.executable, "-m", "rssm_dsl", *args], capture_output=True,
                          text=True, cwd=ROOT, timeout=600, check=False)


def render_explorer_file(spec: Path, out: Path, *extra: str) -> Path:
    """`rssmc render SPEC -o OUT --no-svg --html EXTRA...`; the explorer written."""
    done = rssmc("render", str(spec), "-o", str(out), "--no-svg", "--html", *extra)
    assert done.returncode == 0, done.stderr
    (html,) = [p for p in out.glob("*.html") if p.name != "index.html"]
    return html


def open_explorer(driver: Any, html: Path, timeout: float = 60) -> float:
    """Open the explorer and wait until it says it is ready; the milliseconds it took from
    the start of the navigation (its own performance.now() when ready)."""
    from selenium.webdriver.support.ui import WebDriverWait

    driver.get(html.as_uri())
    WebDriverWait(driver, timeout).until(
        lambda d: d.execute_script("return document.body.getAttribute('data-ready')") == "true")
    return float(driver.execute_script("return document.body.getAttribute('data-ready-ms')"))


def severe_console_errors(driver: Any) -> list[Any]:
    return [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
