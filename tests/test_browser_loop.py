"""Issue 15, first Done-when line: the whole teaching loop in a real headless Chromium at 1440x900,
driven by labels as a teacher would, nothing scrolled.

On the default data (the shipped paper campaign and assets/models/paper), the teacher loads the hidden-effect
scenario head_3 from the Data tab's Scenario, diagnoses it, reads on the map where it fails (the
failing rings, worst first, with their error and floor), goes to the worst ring with one click,
ticks the effect the diagnosis found, refits, reads the error fall and reveals the hidden effect.
At each step: the flat polar plot and the error map are drawn (element screenshots with several
distinct colours and enough non-blank pixels, not only DOM nodes), the controls and results that
step needs lie inside the 1440x900 viewport (Playwright's bounding boxes), nothing on the page was
scrolled, and a screenshot goes to loop_<n>_<step>.png in PH_EXPLORER_LOOP_SHOTS (docs: the site's).
The diagnosis's failing rings come from its per-ring test, so the map names them after Diagnose.

Then (issue 31): the exported report is the session (the refitted effect by name, every step);
at 1440x900 and 1280x720 with Curves open, no two texts of a chart or of the 3D scene overlap at
any View, the ring sits mid-canvas between the panels, and Refit's and Reveal's results are
brought into view (the panel scrolls, never the page); an uploaded campaign leaves nothing of the
old in view (the scenario box, the report's line).
"""

from __future__ import annotations

import io
import os
import re
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from fake_browser import wait_for

CHROMIUM = "/usr/bin/chromium"
ARGS = ["--no-sandbox", "--enable-unsafe-swiftshader", "--disable-background-networking", "--disable-gpu"]

pytestmark = [pytest.mark.browser, pytest.mark.slow]

if not Path(CHROMIUM).exists() and not os.environ.get("CI"):
    pytest.skip("Debian's chromium is not installed (/usr/bin/chromium); apt-get install chromium", allow_module_level=True)

WIDTH, HEIGHT = 1440, 900
SCENARIO = "head_3"  # a teaching scenario with a hidden effect (its name says nothing of it)
# A drawn chart: this many pixels off the white background, in at least this many colours (each
# covering at least COLOUR_PIXELS pixels, so that anti-aliasing does not count as a colour).
MIN_INKED = {"polar plot": 4000, "error map": 8000, "signature plot": 1500}
MIN_COLOURS = {"polar plot": 3, "error map": 4, "signature plot": 3}
COLOUR_PIXELS = 25
NUMBER = r"(\d+\.\d+)"


def colour_census(png: bytes) -> tuple[int, int]:
    """(pixels off the white background, distinct colours among them) of a screenshot; colours are
    counted on a 32-level grid per channel and only when they cover COLOUR_PIXELS pixels."""
    from PIL import Image  # pillow comes with matplotlib, a test dependency

    rgb = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=int)
    inked = rgb.min(axis=-1) < 235
    codes = (rgb[inked] // 32) @ np.array([64, 8, 1])
    counts = np.bincount(codes, minlength=512)
    return int(inked.sum()), int((counts >= COLOUR_PIXELS).sum())


# The page has settled when no element, attribute or text of it has changed for QUIET_MS (the
# server's updates drawn), then two frames painted; at most MOST_MS.
QUIET_MS, MOST_MS = 500, 5000
SETTLED = """([quiet, most]) => new Promise(resolve => {
  let ended = false, timer = null;
  const end = () => { if (ended) return; ended = true; observer.disconnect();
    requestAnimationFrame(() => requestAnimationFrame(() => resolve(true))); };
  const observer = new MutationObserver(() => { clearTimeout(timer); timer = setTimeout(end, quiet); });
  observer.observe(document.body, {subtree: true, childList: true, attributes: true, characterData: true});
  timer = setTimeout(end, quiet);
  setTimeout(end, most);
})"""


def settled(page) -> None:
    """Wait until the page has drawn the server's last updates (SETTLED), not a fixed time."""
    page.evaluate(SETTLED, [QUIET_MS, MOST_MS])


def steady_box(locator, what: str, timeout: float = 10.0) -> dict:
    """The element's box once it stops moving (a panel the app scrolls glides there)."""
    deadline, box = time.monotonic() + timeout, None
    while time.monotonic() < deadline:
        now = locator.bounding_box()
        if now is not None and box is not None and all(abs(now[k] - box[k]) < 0.5 for k in ("x", "y", "width", "height")):
            return now
        box = now
        time.sleep(0.05)
    assert box is not None, what
    return box


def within_height(box: dict, page) -> bool:
    """The box lies between the viewport's top and bottom (1440x900, or the page's), to within a
    pixel: a panel scrolls by whole pixels and its lines sit at fractions of one, so an element it
    scrolls into view at the bottom can overhang by less than a pixel (666.3 + 234 px of 900)."""
    height = (page.viewport_size or {"height": HEIGHT})["height"]
    return box["y"] > -1.0 and box["y"] + box["height"] < height + 1.0


def within_width(box: dict, page) -> bool:
    """The box lies between the viewport's left and right edges (1440x900, or the page's)."""
    width = (page.viewport_size or {"width": WIDTH})["width"]
    return box["x"] >= 0 and box["x"] + box["width"] <= width


def in_view(locator, what: str, timeout: float = 10.0) -> dict:
    """The element is shown and wholly inside the viewport (1440x900, or the page's), once it stands
    still there: the app scrolls a step's results into view when the panel has redrawn them, which
    can come after the text has stood still where the redraw put it."""
    locator.wait_for(state="visible", timeout=30_000)
    deadline = time.monotonic() + timeout
    box = steady_box(locator, what)
    while time.monotonic() < deadline and not (within_height(box, locator.page) and within_width(box, locator.page)):
        time.sleep(0.2)
        box = steady_box(locator, what)
    print(f"{what}: x {box['x']:.0f}-{box['x'] + box['width']:.0f}, y {box['y']:.0f}-{box['y'] + box['height']:.0f}")
    if not os.environ.get("PH_EXPLORER_LOOP_MEASURE"):
        assert within_height(box, locator.page), (what, box)
        assert within_width(box, locator.page), (what, box)
    return box


def kept_in_view_until_the_reader_scrolls(page, session, fall, what: str) -> None:
    """A step's text, once brought into view, is kept there while the panel redraws above it (the
    words may stand already where an earlier step wrote them), until the reader scrolls: the next
    redraw then leaves the panel where the reader put it. fall: the locator of the error fall's line."""
    panel = session.physics
    said = panel.refit_status.content
    pushed = lambda lines: said + "\n\n" + "\n\n".join(f"a redraw's line {k}" for k in range(lines))  # noqa: E731
    try:
        panel.keep_in_view("Check-ring MAE:")
        in_view(fall, f"{what}: asked again")
        # A step's redraws follow its request at once (the window is counted from then, not from
        # the check above, which a loaded machine makes slow): asked, then pushed down, out of view.
        panel.keep_in_view("Check-ring MAE:")
        panel.refit_status.content = pushed(30)
        in_view(fall, f"{what}: kept in view while the panel redraws", timeout=3.0)
        box = fall.bounding_box()
        page.mouse.move(box["x"] + 5, box["y"] + box["height"] / 2)
        page.mouse.wheel(0, -600)
        time.sleep(0.5)
        panel.refit_status.content = pushed(45)
        time.sleep(1.0)
        box = steady_box(fall, what)
        print(f"{what}, the reader scrolled up and the panel redrew: y {box['y']:.0f}-{box['y'] + box['height']:.0f}")
        assert not within_height(box, page), (what, "brought back into view after the reader scrolled", box)
    finally:
        panel.refit_status.content = said


def no_scroll(page) -> None:
    """The page itself was not scrolled, nor the figures panel: every control the walk clicks was in
    view when clicked (in_view). The controls panel may have been scrolled by the app, which brings
    a step's results into view beside the button that made them (issue 31, item 4)."""
    scrolled = page.evaluate(
        "() => [window.scrollY, ...Array.from(document.querySelectorAll('svg[aria-label^=\"polar plot\"]')).map(svg => {"
        " let e = svg; let top = 0; while (e) { top += e.scrollTop || 0; e = e.parentElement; } return top; })].filter(v => v > 0).length"
    )
    assert scrolled == 0 or os.environ.get("PH_EXPLORER_LOOP_MEASURE"), "the page or the figures panel was scrolled"


def chart_drawn(page, what: str, title: str | None = None) -> None:
    """The SVG chart (aria-label 'what ...') is in view and drawn: real pixels in several colours."""
    chart = page.locator(f'svg[aria-label^="{what}"]').first
    in_view(chart, what)
    if title is not None:
        assert title in (chart.get_attribute("aria-label") or ""), (what, title, chart.get_attribute("aria-label"))
    inked, colours = colour_census(chart.screenshot())
    print(f"{what}: {inked} inked pixels, {colours} colours")
    assert inked >= MIN_INKED[what] and colours >= MIN_COLOURS[what], (what, inked, colours)


def figures_drawn(page, title: str | None = None) -> None:
    """The flat polar plot (of this orientation) and the error map: both in view and drawn."""
    chart_drawn(page, "polar plot", title)
    chart_drawn(page, "error map")
    assert svg_text_overlaps(page) == []  # no chart's texts drawn over each other


def overlapping(boxes: list[tuple[str, float, float, float, float]], slack: float = 1.0) -> list[tuple[str, str]]:
    """Pairs of (text, x, y, width, height) boxes that overlap by more than `slack` px both ways."""
    pairs = []
    for i, (t1, x1, y1, w1, h1) in enumerate(boxes):
        for t2, x2, y2, w2, h2 in boxes[i + 1 :]:
            if min(x1 + w1, x2 + w2) - max(x1, x2) > slack and min(y1 + h1, y2 + h2) - max(y1, y2) > slack:
                pairs.append((t1, t2))
    return pairs


SVG_TEXT_BOXES = """() => [...document.querySelectorAll('svg[role="img"]')].filter(svg => svg.getBoundingClientRect().width > 0).map(svg =>
  [svg.getAttribute('aria-label'), [...svg.querySelectorAll('text')].filter(t => t.textContent.trim()).map(t => {
    const r = t.getBoundingClientRect(); return [t.textContent.trim(), r.x, r.y, r.width, r.height]; })])"""


def svg_text_overlaps(page) -> list:
    """Every shown SVG chart's text boxes (the browser's own layout) that overlap another of its own."""
    return [(label, pairs) for label, boxes in page.evaluate(SVG_TEXT_BOXES) if (pairs := overlapping([tuple(b) for b in boxes]))]


def scene_canvas(page) -> dict:
    """The 3D canvas's box on the page: the scene between the docked panels."""
    return page.evaluate(
        "() => { const r = document.querySelector('canvas').getBoundingClientRect(); return {x: r.x, y: r.y, width: r.width, height: r.height}; }"
    )


def on_canvas(session, point_world, canvas: dict) -> tuple[float, float, float]:
    """(x, y) in page px and the depth (mm) of a world point through this browser's camera (viser's
    camera frame is OpenCV's: x right, y down, z forward; fov is vertical)."""
    from viser.transforms import SO3

    camera = session.client.camera
    local = SO3(np.asarray(camera.wxyz, dtype=float)).inverse().apply(np.asarray(point_world, dtype=float) - np.asarray(camera.position))
    focal = 0.5 * canvas["height"] / np.tan(0.5 * camera.fov)
    return (
        canvas["x"] + 0.5 * canvas["width"] + focal * local[0] / local[2],
        canvas["y"] + 0.5 * canvas["height"] + focal * local[1] / local[2],
        local[2],
    )


# viser writes a screen label's em at 12 CSS px x font_screen_scale, on a background quad: its box
# is taken a little larger than its glyphs (0.62 em a character, 1.5 em high, 0.6 em of padding).
LABEL_EM_PX = 12.0


def scene_label_boxes(session, canvas: dict) -> list[tuple[str, float, float, float, float]]:
    """The 3D chart's labels that are shown, as boxes on the page (see LABEL_EM_PX)."""
    from viser.transforms import SO3

    ring = session.ring
    frame = SO3(np.asarray(ring.frame.wxyz, dtype=float))
    boxes = []
    for handle, anchor, scale in [*((h, "center-center", 0.7) for h in ring.labels), (ring.arrow_label, "center-center", 0.8)]:
        if not handle.visible or not handle.text:
            continue
        x, y, depth = on_canvas(session, frame.apply(np.asarray(handle.position)) + np.asarray(ring.frame.position), canvas)
        assert depth > 0, handle.text
        em = LABEL_EM_PX * scale
        width, height = (0.62 * len(handle.text) + 0.6) * em, 1.5 * em
        vertical, horizontal = anchor.split("-")
        left = {"left": x, "center": x - width / 2, "right": x - width}[horizontal]
        top = {"top": y, "center": y - height / 2, "bottom": y - height}[vertical]
        boxes.append((handle.text, left, top, width, height))
    return boxes


def scenario_loaded(page, session, name: str) -> None:
    """Data -> Scenario -> name, as a user picks it (notifications hidden: they would cover the
    panel in screenshots); returns once the scenario's campaign is shown."""
    page.add_style_tag(content=".mantine-Notification-root, .mantine-Notifications-root { display: none !important; }")
    page.get_by_role("tab", name="Data").click()
    page.get_by_label("Scenario").click()
    page.get_by_role("option", name=name).click()
    assert wait_for(lambda: name in session.data_panel.source.content, timeout=600)
    session.wait(timeout=300)


def diagnosed(page, session) -> str:
    """Physics -> Diagnose, as a user clicks them; the verdict's text once it is shown."""
    page.get_by_role("tab", name="Physics").click()
    page.get_by_role("button", name="Diagnose", exact=True).click()
    assert wait_for(lambda: session.loop.diagnosis is not None and "Verdict" in session.physics.verdict.content, timeout=900)
    session.wait(timeout=300)
    return session.physics.verdict.content


def step_shot(page, shots: Path, name: str) -> None:
    no_scroll(page)
    settled(page)
    page.screenshot(path=str(shots / f"{name}.png"))


def fall_figures(text: str) -> tuple[float, float, float]:
    """(before, after, after over its floor) from the one-line error fall shown on the Physics tab."""
    found = re.search(rf"Check-ring MAE: {NUMBER} -> {NUMBER} um, {NUMBER}x its floor", text)
    assert found, text
    before, after, ratio = (float(g) for g in found.groups())
    return before, after, ratio


def failing_figures(label: str) -> tuple[float, float, float, float, float]:
    """(A, B, MAE, floor, ratio) from a failing ring's button: 'A83 B110: 0.170 um, floor 0.048 um (3.5x, check ring)'."""
    found = re.match(rf"A(-?[\d.]+) B(-?[\d.]+): {NUMBER} um, floor {NUMBER} um \({NUMBER}x", label)
    assert found, label
    return tuple(float(g) for g in found.groups())  # type: ignore[return-value]


def teach(page, session, shots: Path) -> None:
    """The loop, step by step, as a teacher goes through it (see the module docstring)."""
    # The software-WebGL notice is about this machine (no GPU), not the app.
    page.add_style_tag(content=".mantine-Notification-root, .mantine-Notifications-root { display: none !important; }")
    figures_drawn(page, "A15 B-20")

    # 1. Load the hidden-effect scenario: Data tab, Scenario, by their labels; its progress ends.
    page.get_by_role("tab", name="Data").click()
    in_view(page.get_by_label("Scenario"), "Scenario")
    page.get_by_label("Scenario").click()
    page.get_by_role("option", name=SCENARIO).click()
    assert wait_for(lambda: SCENARIO in session.data_panel.source.content, timeout=600)
    session.wait(timeout=300)
    page.get_by_text(f"scenario {SCENARIO}", exact=False).first.wait_for(timeout=30_000)
    bars = page.get_by_role("progressbar")  # the load's progress, under the orientation: gone when done
    assert wait_for(lambda: not any(bars.nth(i).is_visible() for i in range(bars.count())), timeout=60)
    in_view(page.get_by_text(f"scenario {SCENARIO}", exact=False).first, "the data loaded")
    figures_drawn(page)
    step_shot(page, shots, "loop_1_loaded")

    # 2. Diagnose (Physics tab): the verdict, the found effect's checkbox, and the diagnosis's
    # results: the signature plot and the fit with its uncertainty and identifiability.
    page.get_by_role("tab", name="Physics").click()
    diagnose = page.get_by_role("button", name="Diagnose", exact=True)
    in_view(diagnose, "Diagnose")
    diagnose.click()
    assert wait_for(lambda: session.loop.diagnosis is not None and "Verdict" in session.physics.verdict.content, timeout=900)
    session.wait(timeout=300)
    result = session.loop.diagnosis
    found = [c.effect for c in result.found]
    assert found, "the diagnosis found no effect"
    in_view(page.get_by_text("Verdict:", exact=False).first, "verdict")
    in_view(page.get_by_label(found[0], exact=True), f"checkbox {found[0]}")
    chart_drawn(page, "signature plot", found[0])
    fit = page.get_by_text("fitted ± U (k = 2)", exact=False).first
    in_view(fit, "the fit's table")
    best = result.found[0]
    for name, value in best.params.items():
        if best.params_u.get(name):  # a fitted parameter, shown with its uncertainty
            assert f"{value:.3g}" in session.physics.fit.content, (name, value)
    told = all(o.told_apart for o in best.confounded_with)
    ident = "identifiable" if not best.confounded_with else ("told apart by the rings" if told else "confounded")
    in_view(page.get_by_text(ident, exact=False).first, "identifiability")
    figures_drawn(page)
    step_shot(page, shots, "loop_2_diagnosed")

    # 3. Where it fails, on the Map tab: the map shows each ring's error over its floor, and the
    # failing rings are listed worst first, each with its error and floor, every button in view.
    page.get_by_role("tab", name="Map", exact=True).click()
    page.get_by_label("Map of").click()
    page.get_by_role("option", name="diagnosis: out-of-sample MAE / its floor").click()
    assert wait_for(lambda: "out-of-sample MAE / its floor" in session.map_panel.plot.content, timeout=60)
    failing = result.failing_rings()
    in_view(page.get_by_text(f"{len(failing)} rings exceed their noise", exact=True), "where it fails")
    buttons = [button.label for button in session.map_panel.failing_buttons]
    assert len(buttons) == min(len(failing), 10)
    assert buttons, "no failing ring listed"
    figures = [failing_figures(label) for label in buttons]
    ratios = [f[4] for f in figures]
    assert ratios == sorted(ratios, reverse=True), ratios  # worst first
    # Each listed ring exceeds: by its mean (MAE over its floor), or by its repetitions' scatter, said so.
    assert all(mae > floor or "by its repetitions' scatter" in label for label, (_, _, mae, floor, _) in zip(buttons, figures))
    for label in buttons:
        in_view(page.get_by_role("button", name=label), f"failing ring {label}")
    settled(page)
    figures_drawn(page)
    error_map = page.locator('svg[aria-label^="error map"]').first
    assert "out-of-sample MAE / its floor" in (error_map.get_attribute("aria-label") or "")
    step_shot(page, shots, "loop_3_where_it_fails")

    # 4. One click on the worst ring: both sliders move there, the polar plot shows that ring.
    a_target, b_target = figures[0][0], figures[0][1]
    renders = session.render_count
    page.get_by_role("button", name=buttons[0]).click()
    assert wait_for(lambda: session.orientation == (a_target, b_target), timeout=60), (session.orientation, a_target, b_target)
    assert wait_for(lambda: session.render_count > renders, timeout=60)
    for label, value in (("A (deg)", a_target), ("B (deg)", b_target)):
        slider = page.get_by_role("slider", name=label)
        in_view(slider, label)
        assert wait_for(lambda: slider.get_attribute("aria-valuenow") == f"{value:g}", timeout=30), (
            label,
            slider.get_attribute("aria-valuenow"),
        )
    settled(page)
    figures_drawn(page, f"A{a_target:g} B{b_target:g}")
    step_shot(page, shots, "loop_4_at_the_worst_ring")

    # 5. Tick the found effect by its label, Refit: the error shown falls.
    page.get_by_role("tab", name="Physics").click()
    box = page.get_by_label(found[0], exact=True)
    in_view(box, f"checkbox {found[0]}")
    box.check()
    assert wait_for(lambda: session.physics.effects[found[0]].value, timeout=60)
    refit = page.get_by_role("button", name="Refit the hybrid")
    in_view(refit, "Refit")
    steps = len(session.loop.steps)
    refit.click()
    assert wait_for(lambda: len(session.loop.steps) > steps and "hybrid" in session.dataset.models, timeout=900)
    session.wait(timeout=300)
    fall = page.get_by_text("Check-ring MAE:", exact=False).first
    in_view(fall, "the error fall")
    before, after, ratio = fall_figures(fall.inner_text())
    print(f"the error fell: {before:.3f} -> {after:.3f} um, {ratio:.2f}x its floor")
    assert after < before
    first, last = session.loop.steps[0], session.loop.steps[-1]
    assert (before, after) == (round(first.mae_um["mean"], 3), round(last.mae_um["mean"], 3))
    in_view(page.locator('svg[aria-label="history of the check-ring error"]').first, "history chart")
    # The polar plot at the failing ring now draws the hybrid beside the measured mean.
    assert "hybrid" in session.polar.plot.content
    figures_drawn(page, f"A{a_target:g} B{b_target:g}")
    step_shot(page, shots, "loop_5_refitted")

    # 6. Reveal: the truth beside what was found, the fall and the history still in view.
    reveal = page.get_by_role("button", name="Reveal the hidden effect")
    in_view(reveal, "Reveal")
    reveal.click()
    assert wait_for(lambda: "truth:" in session.physics.revealed.content, timeout=60)
    settled(page)
    in_view(page.get_by_text("Hidden:", exact=False).first, "Reveal's result")
    in_view(page.get_by_text("truth:", exact=False).first, "the truth")
    in_view(page.get_by_text("diagnosis (significant", exact=False).first, "what was found")
    in_view(page.get_by_text("last refit:", exact=False).first, "the last refit")
    in_view(fall, "the error fall")
    in_view(page.locator('svg[aria-label="history of the check-ring error"]').first, "history chart")
    hidden = [e["id"] for e in session.dataset.campaign.scenario["effects"] if e.get("hidden")]
    assert any(f"`{effect_id}`" in session.physics.revealed.content for effect_id in hidden)
    figures_drawn(page)
    step_shot(page, shots, "loop_6_revealed")

    # 7. The report is the session: the refitted effect by name (revealed now), every step.
    page.get_by_role("tab", name="Data").click()
    with page.expect_download(timeout=120_000) as download:
        page.get_by_role("button", name="Export report").click()
    report = Path(download.value.path()).read_text(encoding="utf-8")
    from ph_explorer.effects import DEFAULT_CATALOG

    assert f"{DEFAULT_CATALOG[found[0]].name} ({found[0]})" in report and "the model is the baseline" not in report
    history = report[report.index('id="history"') :]
    assert len(re.findall(r"<tr><td>\d+</td>", history)) >= 2, "the report's history has fewer than 2 steps"
    assert wait_for(lambda: "Report sent" in session.report_panel.status.content, timeout=60)

    # 8. Readable at both window sizes, with Curves open: no two texts of a chart or of the 3D
    # scene overlap at any View; the ring in the middle of the scene between the panels; and a
    # step's results are brought into view beside the button that made them.
    for width, height in ((WIDTH, HEIGHT), (1280, 720)):
        page.set_viewport_size({"width": width, "height": height})
        settled(page)
        curves = page.get_by_role("button", name="Curves", exact=True)
        if curves.get_attribute("aria-expanded") != "true":
            curves.click()
        readable_scene(page, session)
        page.get_by_role("tab", name="Charts").click()  # the deviation and harmonic charts, same axes
        page.locator('svg[aria-label^="chart Harmonics"]').first.wait_for(timeout=30_000)
        assert svg_text_overlaps(page) == []
        page.get_by_role("tab", name="Physics").click()
        steps = len(session.loop.steps)
        page.get_by_role("button", name="Refit the hybrid").click()
        assert wait_for(lambda: len(session.loop.steps) > steps, timeout=600)
        session.wait(timeout=300)
        settled(page)
        fall = page.get_by_text("Check-ring MAE:", exact=False).first
        in_view(fall, f"the error fall at {width}x{height}, Curves open")
        if width == WIDTH:
            kept_in_view_until_the_reader_scrolls(page, session, fall, f"the error fall at {width}x{height}")
        page.get_by_role("button", name="Reveal the hidden effect").click()
        settled(page)
        in_view(page.get_by_text("Hidden:", exact=False).first, f"Reveal's result at {width}x{height}, Curves open")
        in_view(page.get_by_text("last refit:", exact=False).first, f"the last refit at {width}x{height}, Curves open")
        assert page.evaluate("() => window.scrollY") == 0  # the panel scrolls, never the page
        assert svg_text_overlaps(page) == []
    step_shot(page, shots, "loop_7_small_window")

    # 9. New data: nothing of the old stays in view (the scenario box, the report's line, the history).
    page.set_viewport_size({"width": WIDTH, "height": HEIGHT})
    page.get_by_role("tab", name="Data").click()
    with page.expect_file_chooser() as chooser:
        page.get_by_role("button", name="Upload a campaign CSV").click()
    chooser.value.set_files(str(Path(__file__).resolve().parents[1] / "assets" / "data" / "paper.csv"))
    assert wait_for(lambda: "paper.csv" in session.data_panel.source.content, timeout=600)
    session.wait(timeout=300)
    assert session.data_panel.chosen() is None and session.report_panel.status.content == ""
    assert session.loop.steps == [] and not session.physics.revealed.content
    page.get_by_text("paper.csv", exact=False).first.wait_for(timeout=30_000)
    assert page.get_by_text("Report sent", exact=False).count() == 0


def readable_scene(page, session) -> None:
    """At each View: no two 3D labels overlap (their boxes on the canvas, from the server's label
    positions through the browser's camera), nor two texts of a chart; along the axis puts the
    ring's centre in the middle of the canvas between the docked panels, and ring + head shows the
    whole head (its outline inside the canvas) with the ring."""
    for view in ("whole field", "along the axis", "ring + head"):  # ring + head last: the screenshot's view
        # A View click is lost now and then under load (twice in ~10 runs, CI and local: the View
        # stayed, no error logged); the server's side of a click is test_app's. Clicked again, twice at most.
        for _ in range(3):
            page.get_by_role("button", name=view, exact=True).click()
            if wait_for(lambda: session.camera.view == view, timeout=10):
                break
            # The button's value on the server says whether the click's message arrived at all.
            print(f"View {view!r} at {page.viewport_size}: lost (the button's value: {session.controls.view_ring.value!r}), clicked again")
        assert session.camera.view == view, (view, session.camera.view, session.controls.view_ring.value, page.viewport_size)
        time.sleep(1.0)
        canvas = scene_canvas(page)
        boxes = scene_label_boxes(session, canvas)
        assert overlapping(boxes) == [], (view, boxes)
        assert all(canvas["x"] <= x and x + w <= canvas["x"] + canvas["width"] for _, x, _, w, _ in boxes), (view, canvas, boxes)
        if view == "along the axis":
            x, y, _ = on_canvas(session, np.asarray(session.ring.frame.position), canvas)
            assert abs(x - (canvas["x"] + canvas["width"] / 2)) < 0.1 * canvas["width"], (view, x, canvas)
            assert abs(y - (canvas["y"] + canvas["height"] / 2)) < 0.1 * canvas["height"], (view, y, canvas)
        if view == "ring + head":
            from ph_explorer.app.scene import head_points

            geometry = session.dataset.campaign.geometry
            a, b = session.orientation
            outline = [on_canvas(session, p, canvas) for p in head_points(a, b, geometry.pivot_to_ball_mm, geometry.ball_diameter_mm)]
            inside = [
                canvas["x"] <= x <= canvas["x"] + canvas["width"] and canvas["y"] <= y <= canvas["y"] + canvas["height"]
                for x, y, _ in outline
            ]
            assert all(inside), (view, page.viewport_size, sum(not i for i in inside), "points of the head outside the canvas")
    assert svg_text_overlaps(page) == []


def walk_in_chromium(walk, prefix: str) -> Path:
    """Serve the default data, open it in chromium at 1440x900 and run walk(page, session, shots);
    the page as it stood goes to PH_EXPLORER_LOOP_FAILED (default /tmp) when it fails. The walk's
    screenshots, `prefix`*.png, replace the older ones in PH_EXPLORER_LOOP_SHOTS (docs to retake the
    site's; else a temporary folder, so the tests leave a clone as it was) once the whole walk has
    passed; a failed walk leaves them as they were."""
    from playwright.sync_api import sync_playwright

    from ph_explorer.app.server import build_server

    app = build_server(port=0)  # the default data: the shipped paper campaign and assets/models/paper
    folder = os.environ.get("PH_EXPLORER_LOOP_SHOTS")
    shots = Path(folder) if folder else Path(tempfile.mkdtemp(prefix="ph_explorer_shots_"))
    shots.mkdir(parents=True, exist_ok=True)
    taken = Path(tempfile.mkdtemp(prefix=f"ph_explorer_{prefix}"))
    try:
        with sync_playwright() as pw:
            browser = pw.chromium.launch(executable_path=CHROMIUM, args=ARGS)
            page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
            errors: list[str] = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.goto(app.url)
            session = app.session(timeout=60)
            assert wait_for(lambda: session.render_count >= 1)
            try:
                walk(page, session, taken)
            except Exception:  # the page as it stood, for whoever reads the failure
                page.screenshot(path=str(Path(os.environ.get("PH_EXPLORER_LOOP_FAILED", "/tmp")) / f"ph_explorer_{prefix}failed.png"))
                raise
            assert not [e for e in errors if "TypeError" in e], errors
            browser.close()
    finally:
        app.stop()
    for stale in shots.glob(f"{prefix}*.png"):  # the screenshots of this walk only, never an older layout's
        stale.unlink()
    for shot in taken.glob(f"{prefix}*.png"):
        shutil.move(shot, shots / shot.name)
    shutil.rmtree(taken)
    return shots


def test_the_whole_teaching_loop_by_labels_at_1440x900() -> None:
    shots = walk_in_chromium(teach, "loop_")
    assert len(list(shots.glob("loop_*.png"))) == 7
