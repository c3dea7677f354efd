"""Screenshots of the explorer for the README (run: python docs/make_screenshots.py [OUT_DIR]).

The server runs in this process on a free port; Debian's chromium (driven by Playwright) is the
browser. 1) the default start (shipped paper campaign, model/paper); 2) the teaching loop on the
head_3 scenario: Diagnose, tick the top candidate, Refit, through that browser's Session.
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
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.goto(app.url)
            session = app.session(timeout=60)
            page.get_by_text("Tables 1-3").first.wait_for(timeout=60_000)
            time.sleep(3.0)
            dismiss_notices(page)
            time.sleep(1.0)
            page.screenshot(path=str(out / "screenshot_default.png"))
            session.data_panel.scenario.value = "head_3"
            session.wait(timeout=300)
            session.submit(session.loop.diagnose)  # what the Diagnose button runs
            session.wait(timeout=600)
            best = session.loop.diagnosis.candidates[0].effect
            session.physics.effects[best].value = True
            session.submit(session.loop.refit)  # what the Refit button runs
            session.wait(timeout=600)
            session.go_to(43.0, 90.0)
            page.get_by_text("Curves", exact=True).first.click()  # fold the curve switches away
            page.get_by_role("tab", name="Physics").click()
            page.get_by_text("Last step:").first.scroll_into_view_if_needed()
            time.sleep(3.0)
            dismiss_notices(page)
            time.sleep(1.0)
            page.screenshot(path=str(out / "screenshot_loop.png"))
            browser.close()
    finally:
        app.stop()


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("/tmp/ph_shots"))
