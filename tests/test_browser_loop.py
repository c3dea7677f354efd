"""Issue 15 item 4: the teaching loop above the fold on a 1440x900 screen, in a real headless Chromium.

A teacher loads a hidden-effect campaign (the Data tab's Scenario), diagnoses it, ticks the effect
the diagnosis found, refits, reads the error fall and reveals the hidden effect, all found by their
labels; at each step the controls and results it needs must be inside the 1440x900 viewport without
scrolling (Playwright's bounding boxes: visible, bottom <= 900). Screenshots: docs/loop_*.png.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import pytest

from fake_browser import wait_for

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-gpu"]

pytestmark = [pytest.mark.browser, pytest.mark.slow]

if not Path(CHROMIUM).exists() and not os.environ.get("CI"):
    pytest.skip("Debian's chromium is not installed (/usr/bin/chromium); apt-get install chromium", allow_module_level=True)

WIDTH, HEIGHT = 1440, 900
DOCS = Path(__file__).resolve().parents[1] / "docs"


def above_the_fold(locator, what: str) -> dict:
    """The element is shown and wholly inside the viewport, as the page stands (nothing scrolled)."""
    locator.wait_for(state="visible", timeout=30_000)
    box = locator.bounding_box()
    assert box is not None, what
    print(f"{what}: top {box['y']:.0f}, bottom {box['y'] + box['height']:.0f}")
    if os.environ.get("PH_EXPLORER_LOOP_MEASURE"):
        return box
    assert box["y"] >= 0 and box["y"] + box["height"] <= HEIGHT, (what, box)
    assert box["x"] >= 0 and box["x"] + box["width"] <= WIDTH, (what, box)
    return box


def no_scroll(page) -> None:
    """Nothing on the page, nor in the side panel, was scrolled to get there."""
    scrolled = page.evaluate(
        "() => [window.scrollY, ...Array.from(document.querySelectorAll('*')).map(e => e.scrollTop)].filter(v => v > 0).length"
    )
    assert scrolled == 0 or os.environ.get("PH_EXPLORER_LOOP_MEASURE"), "something was scrolled"


def test_the_teaching_loop_fits_above_the_fold_at_1440x900(tmp_path: Path) -> None:
    from playwright.sync_api import sync_playwright

    from ph_explorer.app.dataset import dataset_for
    from ph_explorer.app.server import ExplorerApp
    from synthetic import lobing_campaign

    app = ExplorerApp(dataset_for(lobing_campaign(seed=5), "synthetic browser-test campaign", None), port=0)
    shots = Path(os.environ.get("PH_EXPLORER_LOOP_SHOTS", DOCS))
    shots.mkdir(parents=True, exist_ok=True)
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            page.goto(app.url)
            session = app.session(timeout=60)
            assert wait_for(lambda: session.render_count >= 1)

            # 1. Load a hidden-effect campaign: Data tab, Scenario.
            page.get_by_role("tab", name="Data").click()
            above_the_fold(page.get_by_label("Scenario"), "Scenario")
            page.get_by_label("Scenario").click()
            page.get_by_role("option", name="head_3").click()
            assert wait_for(lambda: "head_3" in session.data_panel.source.content, timeout=600)
            session.wait(timeout=300)
            time.sleep(1.0)
            page.screenshot(path=str(shots / "loop_1_loaded.png"))

            # 2. Diagnose (Physics tab): the button and its verdict above the fold.
            page.get_by_role("tab", name="Physics").click()
            diagnose = page.get_by_role("button", name="Diagnose", exact=True)
            above_the_fold(diagnose, "Diagnose")
            diagnose.click()
            assert wait_for(lambda: session.loop.diagnosis is not None and "Verdict" in session.physics.verdict.content, timeout=900)
            found = [c.effect for c in session.loop.diagnosis.found]
            assert found, "the diagnosis found no effect"
            verdict = page.get_by_text("Verdict:", exact=False).first
            time.sleep(1.5)
            above_the_fold(verdict, "verdict")
            no_scroll(page)
            page.screenshot(path=str(shots / "loop_2_diagnosed.png"))

            # 3. Tick the found effect, by its label, and Refit.
            box = page.get_by_label(found[0], exact=True)
            above_the_fold(box, f"checkbox {found[0]}")
            box.check()
            assert wait_for(lambda: session.physics.effects[found[0]].value, timeout=60)
            refit = page.get_by_role("button", name="Refit the hybrid")
            above_the_fold(refit, "Refit")
            steps = len(session.loop.steps)
            refit.click()
            assert wait_for(lambda: len(session.loop.steps) > steps and "hybrid" in session.dataset.models, timeout=900)
            first, last = session.loop.steps[0], session.loop.steps[-1]
            assert last.mae_um["mean"] < first.mae_um["mean"]

            # 4. The error fell: the history chart and the line that says how far, above the fold.
            time.sleep(2.0)
            above_the_fold(page.get_by_text("Check-ring MAE (um) per step", exact=False).first, "history chart title")
            above_the_fold(page.locator(".uplot", has_text="Check-ring MAE (um) per step").first, "history chart")
            above_the_fold(page.get_by_text("Check-ring MAE:", exact=False).first, "the error fall")
            no_scroll(page)
            page.screenshot(path=str(shots / "loop_3_refitted.png"))

            # 5. Reveal: the button and the truth beside what was found.
            reveal = page.get_by_role("button", name="Reveal the hidden effect")
            above_the_fold(reveal, "Reveal")
            reveal.click()
            assert wait_for(lambda: "truth:" in session.physics.revealed.content, timeout=60)
            time.sleep(1.0)
            above_the_fold(page.get_by_text("Hidden in this scenario", exact=False).first, "Reveal's result")
            above_the_fold(page.get_by_text("truth:", exact=False).first, "the truth")
            above_the_fold(page.get_by_text("last refit:", exact=False).first, "the last refit")
            no_scroll(page)
            page.screenshot(path=str(shots / "loop_4_revealed.png"))

            # The Map tab: the map whole and where it fails.
            page.get_by_role("tab", name="Map").click()
            error_map = page.locator('svg[aria-label^="error map"]').first
            above_the_fold(error_map, "error map")
            above_the_fold(page.get_by_role("button", name=session.map_panel.failing_buttons[0].label), "where it fails: the worst ring")
            no_scroll(page)
            page.screenshot(path=str(shots / "loop_5_map.png"))
            browser.close()
    finally:
        app.stop()
