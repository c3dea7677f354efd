"""Screenshots of the explorer for the README (run: python docs/make_screenshots.py [OUT_DIR]).

The server runs in this process on a free port; Debian's chromium (driven by Playwright) is the
browser, at 1440x900 (the screen the teaching loop is laid out for). 1) the default start (shipped
paper campaign, assets/models/paper); 2) the teaching loop on the head_3 scenario: Diagnose, tick the
effect found, Refit, go to the ring that failed worst; the Physics tab with the error fall, the
figures panel with that ring's polar plot and the map of each ring's error over its floor.
tests/test_browser_loop.py takes the same loop step by step by labels (docs/loop_*.png).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

from ph_explorer.app.server import build_server

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--disable-background-networking"]


def dismiss_notices(page) -> None:
    """Hide the 'software WebGL' notice (swiftshader has no GPU): it is about this machine, not the app."""
    page.add_style_tag(content=".mantine-Notification-root, .mantine-Notifications-root { display: none !important; }")


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    app = build_server(port=0)
    print(f"ready in {app.startup_s:.2f} s at {app.url}")
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": 1440, "height": 900})
            page.goto(app.url)
            session = app.session(timeout=60)
            page.locator('svg[aria-label^="error map"]').first.wait_for(timeout=60_000)
            time.sleep(3.0)
            dismiss_notices(page)
            time.sleep(1.0)
            page.screenshot(path=str(out / "screenshot_default.png"))
            session.data_panel.scenario.value = session.data_panel.label_of("head_3")  # as a browser chooses it
            session.wait(timeout=300)
            session.submit(session.loop.diagnose)  # what the Diagnose button runs
            session.wait(timeout=600)
            found = session.loop.diagnosis.found[0].effect
            session.physics.effects[found].value = True
            session.submit(session.loop.refit)  # what the Refit button runs
            session.wait(timeout=600)
            session.map_panel.figure.value = "diagnosis: out-of-sample MAE / its floor"
            session.wait(timeout=120)
            worst = session.loop.diagnosis.failing_rings()[0]
            session.go_to(worst.a_deg, worst.b_deg)  # what its button under "Where it fails" does
            page.get_by_role("tab", name="Physics").click()
            time.sleep(3.0)
            dismiss_notices(page)
            time.sleep(1.0)
            page.screenshot(path=str(out / "screenshot_loop.png"))
            browser.close()
    finally:
        app.stop()


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("/tmp/ph_shots"))
