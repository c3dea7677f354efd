"""How long the explorer takes to show the verdict after Diagnose is clicked (issue 28, item 5).

What a user does: `ph-explorer serve` on the shipped default data (the paper campaign, the network
as the baseline) in its own process, a fresh server each time; Debian's chromium (headless,
Playwright) opens the page at 1440x900; once the page has settled (SETTLE_S after the Diagnose
button is shown, so that the page's own loading is over), the Physics tab, then Diagnose; the
seconds from the click until "Verdict:" is visible on the page. Browser and server share the
machine's cores, as on a teacher's laptop.
"""

from __future__ import annotations

import os
import re
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-gpu"]
WIDTH, HEIGHT = 1440, 900
SETTLE_S = 5.0
TARGET_S = 3.0
REPOSITORY = Path(__file__).resolve().parent.parent


def one_click() -> float:
    """A fresh server, a fresh page: seconds from the click on Diagnose until the verdict shows."""
    from playwright.sync_api import sync_playwright

    server = subprocess.Popen(
        [sys.executable, "-m", "ph_explorer", "serve", "--port", "0"],
        cwd=REPOSITORY,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert server.stdout is not None
        url = None
        for line in server.stdout:
            found = re.search(r"serving at (\S+)", line)
            if found:
                url = found.group(1)
                break
        if url is None:
            raise RuntimeError("the server stopped before it served")
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            page.goto(url)
            page.get_by_role("tab", name="Physics").wait_for(timeout=120_000)
            page.get_by_role("tab", name="Physics").click()
            diagnose = page.get_by_role("button", name="Diagnose", exact=True)
            diagnose.wait_for(timeout=120_000)
            time.sleep(SETTLE_S)
            started = time.perf_counter()
            diagnose.click()
            page.get_by_text("Verdict:", exact=False).first.wait_for(state="visible", timeout=120_000)
            seconds = time.perf_counter() - started
            browser.close()
        return seconds
    finally:
        os.killpg(server.pid, signal.SIGINT)
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()


def run(repeats: int = 3) -> dict[str, Any]:
    """The click's seconds over `repeats` fresh servers: each, their median and max, the target."""
    seconds = [round(one_click(), 2) for _ in range(repeats)]
    return {
        "what": "seconds from the click on Diagnose until the verdict shows; a fresh `ph-explorer serve` on the shipped "
        f"data each time, Debian's chromium (headless) at {WIDTH}x{HEIGHT}, the page settled {SETTLE_S:g} s first",
        "seconds": seconds,
        "median_s": statistics.median(seconds),
        "max_s": max(seconds),
        "target_s": TARGET_S,
        "holds": max(seconds) <= TARGET_S,
    }


if __name__ == "__main__":
    print(run(int(sys.argv[1]) if len(sys.argv) > 1 else 3))
