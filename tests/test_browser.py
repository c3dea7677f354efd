"""End to end in a real headless Chromium (Debian's /usr/bin/chromium driven by Playwright).

The page loads, the A slider is moved with the keyboard like a user would, and the server-side
handles of that browser's session show the head turned and the curves changed; a lab's campaign,
uploaded, shows no teaching-only control. One server (a synthetic teaching scenario) and one
chromium serve the module's tests, each test in its own page (its own session). Screenshots go
to the test's tmp folder (and $PH_EXPLORER_SCREENSHOTS when set) so a human can look at them.
"""

from __future__ import annotations

import io
import os
import re
import time
from pathlib import Path

import numpy as np
import pytest
from fake_browser import wait_for
from test_browser_loop import scene_canvas, settled
from viser.transforms import SO3

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-gpu"]

pytestmark = [pytest.mark.browser, pytest.mark.slow]

if not Path(CHROMIUM).exists() and not os.environ.get("CI"):
    pytest.skip("Debian's chromium is not installed (/usr/bin/chromium); apt-get install chromium", allow_module_level=True)


def _rotation(wxyz: np.ndarray) -> np.ndarray:
    """The rotation matrix of a viser frame's (w, x, y, z) quaternion."""
    return SO3(np.asarray(wxyz, dtype=float)).as_matrix()


def dark_pixels(png: bytes) -> int:
    """How many pixels of a screenshot are near-black (the measured mean's curve, the chart's text)."""
    from PIL import Image  # pillow comes with matplotlib, a test dependency

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)
    return int((rgb.max(axis=-1) < 70).sum())


def coloured_pixels(png: bytes) -> int:
    """How many pixels of a screenshot are strongly coloured (the map's viridis markers and colour bar)."""
    from PIL import Image

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)
    return int((rgb.max(axis=-1) - rgb.min(axis=-1) > 60).sum())


# What a teaching scenario's sidecar records of what it hides (app/physics.py's teaching_scenario).
HIDDEN = {"name": "synthetic lobing", "hidden": ["lobing"], "effects": [{"id": "lobing", "hidden": True}]}


@pytest.fixture(scope="module")
def served():
    """One explorer serving a synthetic teaching scenario, and one chromium, for the module's tests."""
    assert Path(CHROMIUM).exists(), "CI must have Debian's chromium at /usr/bin/chromium"
    from playwright.sync_api import sync_playwright
    from synthetic import lobing_campaign

    from ph_explorer.app.dataset import dataset_for
    from ph_explorer.app.server import ExplorerApp

    campaign = lobing_campaign(seed=5, extra_orientations=((43.0, 90.0), (15.0, -20.0)))
    campaign.scenario = dict(HIDDEN)
    app = ExplorerApp(dataset_for(campaign, "synthetic browser-test campaign", None), port=0)
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            yield app, browser
            browser.close()
    finally:
        app.stop()


def open_page(served, errors: list[str]):
    """A new page at 1440x900 on the served explorer, and its session once it has drawn."""
    app, browser = served
    known = set(app.sessions)
    page = browser.new_page(viewport={"width": 1440, "height": 900})
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(app.url)
    assert wait_for(lambda: set(app.sessions) - known, timeout=60), "no session for the page"
    session = app.session(min(set(app.sessions) - known))
    assert wait_for(lambda: session.render_count >= 1)
    return page, session


def test_page_loads_and_the_a_slider_turns_the_head(served, tmp_path: Path) -> None:
    from ph_explorer.geometry import head_rotation

    shots = Path(os.environ.get("PH_EXPLORER_SCREENSHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    errors: list[str] = []
    t0 = time.monotonic()
    page, session = open_page(served, errors)
    page.get_by_text("Tables 1-3").first.wait_for(timeout=30_000)
    time.sleep(2.0)  # let the canvas draw
    page.screenshot(path=str(shots / "explorer_initial.png"))
    print(f"page ready and drawn after {time.monotonic() - t0:.1f} s")

    a_before = session.orientation[0]
    wxyz_before = np.array(session.head.a_frame.wxyz)
    curve_before = np.asarray(session.ring.curves["trilinear"].points).copy()
    renders = session.render_count

    # Every control is reachable by its label or its name, as a screen reader finds it (the
    # Curves folder, collapsed at start so that the tabs sit high, opened by its title first:
    # a folder is a button named by its title, expanded or not, and opens with the keyboard).
    nameless = "() => [...document.querySelectorAll('button, [role=button]')].filter(b => !(b.innerText.trim() || b.getAttribute('aria-label'))).length"
    assert wait_for(lambda: page.evaluate(nameless) == 0, timeout=30), "a button without a name"
    for name in ("Orientation", "Curves", "Effects in the hybrid (all)", "More: candidates, tests, history", "Settings"):
        assert page.get_by_role("button", name=name, exact=True).count() == 1, name
    curves = page.get_by_role("button", name="Curves", exact=True)
    assert curves.get_attribute("aria-expanded") == "false"
    curves.focus()
    page.keyboard.press("Enter")
    page.get_by_label("Magnification").wait_for(timeout=30_000)
    assert wait_for(lambda: curves.get_attribute("aria-expanded") == "true")
    # The software-WebGL notice (no GPU here) closes by its name.
    notices = page.locator(".mantine-Notification-root")
    if notices.count():
        page.get_by_role("button", name="Close notice").first.click()
        assert wait_for(lambda: notices.count() == 0, timeout=10)
    for label in ("A (deg)", "B (deg)", "Magnification", "Worst", "Measured mean", "Monte Carlo band"):
        assert page.get_by_label(label).count() == 1, label
    for name in ("A (deg)", "B (deg)", "Magnification"):
        assert page.get_by_role("slider", name=name).count() == 1, name
    for name in ("A15 B-20", "ring + head", "along the axis", "whole field"):
        assert page.get_by_role("button", name=name).count() == 1, name

    # Move the A slider like a user: focus it by its label, press the arrow key three times (1 deg each).
    thumb = page.get_by_label("A (deg)")
    thumb.focus()
    for _ in range(3):
        page.keyboard.press("ArrowRight")
    assert wait_for(lambda: session.orientation[0] == a_before + 3.0, timeout=90), session.orientation
    print(f"slider moved after {time.monotonic() - t0:.1f} s")
    assert wait_for(lambda: session.view.a_deg == a_before + 3.0)
    assert session.render_count > renders

    a, b = session.orientation
    np.testing.assert_allclose(_rotation(session.head.b_frame.wxyz) @ _rotation(session.head.a_frame.wxyz), head_rotation(a, b), atol=1e-9)
    assert not np.allclose(session.head.a_frame.wxyz, wxyz_before)
    assert not np.allclose(np.asarray(session.ring.curves["trilinear"].points), curve_before, atol=1e-4)
    # The browser shows the new value in the slider's number box.
    assert page.get_by_label("A (deg)").get_attribute("aria-valuenow") == f"{a:g}"
    time.sleep(1.5)
    page.screenshot(path=str(shots / "explorer_after_a_slider.png"))

    # The flat polar chart is drawn (pixels of the measured mean's near-black curve, not only DOM).
    chart = page.locator('svg[role="img"]').first
    chart.scroll_into_view_if_needed()
    assert dark_pixels(chart.screenshot(path=str(shots / "explorer_polar_chart.png"))) > 300
    # Along the axis: the ring and its curves, not the inside of the head.
    page.get_by_role("button", name="along the axis").click()
    assert wait_for(lambda: not session.head.root.visible)
    # The scene redrawn along the axis: the dark head gone from the canvas, the ring and the
    # model's curve (orange; A18 is not measured, so no black mean) drawn, not a grey screen.
    canvas = scene_canvas(page)
    seen: list[tuple[int, int]] = []

    def along_the_axis() -> bool:
        png = page.screenshot(clip=canvas)
        seen.append((dark_pixels(png), coloured_pixels(png)))
        return seen[-1][0] < 2000 and seen[-1][1] > 1000

    assert wait_for(along_the_axis, timeout=30), seen[-3:]
    print(f"along the axis: canvas {canvas}, (dark, coloured) pixels {seen[0]} -> {seen[-1]} in {len(seen)} shots")
    page.screenshot(path=str(shots / "explorer_along_the_axis.png"), clip={"x": 0, "y": 0, "width": 1000, "height": 900})
    # The error map (Map tab) is drawn: its coloured markers and colour bar, not only DOM nodes.
    page.get_by_role("tab", name="Map").click()
    error_map = page.locator('svg[aria-label^="error map"]').first
    error_map.wait_for(timeout=30_000)
    error_map.scroll_into_view_if_needed()
    time.sleep(1.0)
    png = error_map.screenshot(path=str(shots / "explorer_error_map.png"))
    assert coloured_pixels(png) > 3000 and dark_pixels(png) > 300  # markers and bar; axis labels and ticks
    # A ring chosen under the map: the sliders go there.
    option = session.map_panel.ring.options[2]
    page.get_by_label("Go to ring").click()
    page.get_by_role("option", name=option).click()
    target = tuple(float(t[1:]) for t in option.split()[:2])
    assert wait_for(lambda: session.orientation == target, timeout=60), (session.orientation, target)
    page.screenshot(path=str(shots / "explorer_map_went_to_ring.png"))
    assert not [e for e in errors if "value property" in e or "TypeError" in e], errors
    page.close()
    assert (shots / "explorer_after_a_slider.png").stat().st_size > 10_000


def uploaded(page, session, path: Path) -> None:
    """The campaign CSV uploaded as a user does: the Data tab's upload button, the file chooser."""
    with page.expect_file_chooser() as chooser:
        page.get_by_role("button", name="Upload a campaign CSV").click()
    chooser.value.set_files(str(path))
    assert wait_for(lambda: path.name in session.data_panel.source.content, timeout=300), session.data_panel.message.content
    session.wait(timeout=120)


def diagnosed(page, session):
    """Diagnose clicked on the Physics tab; the diagnosis once its verdict shows and the page stands still."""
    page.get_by_role("tab", name="Physics").click()
    page.get_by_role("button", name="Diagnose", exact=True).click()
    assert wait_for(lambda: session.loop.diagnosis is not None and "Verdict" in session.physics.verdict.content, timeout=600)
    session.wait(timeout=300)
    settled(page)
    return session.loop.diagnosis


# The teaching-only controls (issue 57, item 8): the Physics tab's Reveal and the Data tab's report option.
TEACHING_ONLY = {"Physics": ("button", "Reveal the hidden effect"), "Data": ("checkbox", "Name hidden effects in the report")}


def test_a_lab_campaign_uploaded_shows_no_teaching_only_control_and_its_verdict_first(served, tmp_path: Path) -> None:
    """Issue 57, item 8: the served teaching scenario (its campaign records a hidden effect) shows
    its teaching-only controls; a lab's campaign uploaded from the Data tab (a CSV, nothing in it
    says it is a scenario) shows none: no control nor text of the Physics and Data tabs offers to
    reveal or name a hidden effect."""
    from synthetic import lobing_campaign

    from ph_explorer.io import write_campaign

    shots = Path(os.environ.get("PH_EXPLORER_SCREENSHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    errors: list[str] = []
    page, session = open_page(served, errors)
    page.add_style_tag(content=".mantine-Notification-root, .mantine-Notifications-root { display: none !important; }")
    for tab, (role, name) in TEACHING_ONLY.items():
        page.get_by_role("tab", name=tab).click()
        page.get_by_role(role, name=name).wait_for(state="visible", timeout=30_000)

    # The lab's CSV, uploaded as a user does: Data tab, its upload button, the file chooser.
    lab = write_campaign(lobing_campaign(seed=6, n_repetitions=3), tmp_path / "lab.csv")
    uploaded(page, session, lab)
    page.get_by_text("uploaded lab.csv", exact=False).first.wait_for(timeout=30_000)
    teaching = re.compile(r"reveal|hidden effect", re.IGNORECASE)
    for tab, (role, name) in TEACHING_ONLY.items():
        page.get_by_role("tab", name=tab).click()
        settled(page)
        assert not page.get_by_role(role, name=name).is_visible(), (tab, name)
        texts = page.get_by_text(teaching)
        shown = [texts.nth(i).inner_text() for i in range(texts.count()) if texts.nth(i).is_visible()]
        assert shown == [], (tab, shown)
        page.screenshot(path=str(shots / f"explorer_lab_{tab.lower()}.png"))
    # Diagnosed: the verdict leads the Physics tab; between Diagnose and Refit nothing speaks of a
    # candidate that is neither claimed nor suggested; still no teaching-only control.
    result = diagnosed(page, session)
    top = page.get_by_role("button", name="Diagnose", exact=True).bounding_box()
    bottom = page.get_by_role("button", name="Refit the hybrid").bounding_box()
    paragraphs = page.evaluate(
        "([low, high, left]) => [...document.querySelectorAll('p')].map(p => [p.getBoundingClientRect(), p.innerText])"
        ".filter(([r, t]) => r.x > left && r.y > low && r.y < high && r.height > 0 && t.trim()).map(([r, t]) => t)",
        [top["y"] + top["height"], bottom["y"], top["x"] - 10],
    )
    assert paragraphs and paragraphs[0].startswith(f"Verdict: {result.verdict}"), paragraphs
    spoken = {c.effect for c in (*result.found, *result.suggested)} | {p.effect for c in result.found for p in c.confounded_with}
    unspoken = [c.effect for c in result.candidates if c.effect not in spoken]
    assert not [(effect, text) for text in paragraphs for effect in unspoken if re.search(rf"\b{effect}\b", text)], paragraphs
    assert not page.get_by_role("button", name="Reveal the hidden effect").is_visible()
    page.screenshot(path=str(shots / "explorer_lab_diagnosed.png"))
    assert not [e for e in errors if "TypeError" in e], errors
    page.close()


def test_a_badly_measured_ring_is_named_under_the_verdict_in_the_explorer(served, tmp_path: Path) -> None:
    """Issue 55, item 5: a lab campaign whose ring A45 B40 was measured with a chipped contact (a
    0.8 um 3-lobe form in every repetition), uploaded and diagnosed: the verdict paragraph, in view
    at 1440x900, says to remeasure that ring and leaves it out; the verdict is the head's."""
    from dataclasses import replace

    from ph_explorer.io import write_campaign
    from ph_explorer.twin.random_heads import random_campaign

    shots = Path(os.environ.get("PH_EXPLORER_SCREENSHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    head = random_campaign(7, "paper")
    ring = int(np.flatnonzero((head.orientations == [45.0, 40.0]).all(axis=1))[0])
    deviations = head.deviations.copy()
    deviations[ring] += 0.8 * np.cos(3 * np.radians(np.arange(head.n_points) * 360.0 / head.n_points) + 0.4)
    lab = write_campaign(replace(head, deviations=deviations, scenario={}), tmp_path / "chipped.csv")
    errors: list[str] = []
    page, session = open_page(served, errors)
    page.add_style_tag(content=".mantine-Notification-root, .mantine-Notifications-root { display: none !important; }")
    page.get_by_role("tab", name="Data").click()
    uploaded(page, session, lab)
    result = diagnosed(page, session)
    assert [(r.a_deg, r.b_deg) for r in result.suspect_rings] == [(45.0, 40.0)] and result.verdict == "none"
    named = page.get_by_text("Remeasure A45 B40", exact=False).first
    named.wait_for(state="visible", timeout=30_000)
    box = named.bounding_box()
    assert box is not None and 0 <= box["y"] and box["y"] + box["height"] <= 900, box
    page.screenshot(path=str(shots / "explorer_suspect_ring.png"))
    assert not [e for e in errors if "TypeError" in e], errors
    page.close()
