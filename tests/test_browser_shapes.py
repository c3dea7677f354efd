"""Issue 56's explorer line: a shape no catalog holds, found, drawn, added and the error falling, in a
real headless Chromium at 1440x900, driven by labels.

The user uploads a campaign of a head whose B axis has a 48-tooth gear's error (beyond the
catalog's scan of 1-40 cycles/rev), diagnoses it (`uncatalogued`: the B axis's angular positioning
as a function of the B joint angle, its curve drawn with its band under the verdict), ticks the
shape in "Effects found", refits, and reads the check-ring error fall; the hybrid joins Tables
1-3. A screenshot of each step goes to shapes_<n>_<step>.png in PH_EXPLORER_LOOP_SHOTS (docs: the site's).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import pytest
from fake_browser import wait_for
from test_browser_loop import CHROMIUM, colour_census, diagnosed, in_view, settled, step_shot, walk_in_chromium
from test_shapes import SEED, FineGearB

from ph_explorer.io.writer import write_campaign
from ph_explorer.twin.random_heads import random_campaign

pytestmark = [pytest.mark.browser, pytest.mark.slow]

if not Path(CHROMIUM).exists() and not os.environ.get("CI"):
    pytest.skip("Debian's chromium is not installed (/usr/bin/chromium); apt-get install chromium", allow_module_level=True)


def add_a_shape(page, session, shots: Path) -> None:
    page.add_style_tag(content=".mantine-Notification-root, .mantine-Notifications-root { display: none !important; }")
    data = write_campaign(random_campaign(SEED, "paper", [FineGearB()]), Path(tempfile.mkdtemp()) / "fine_gear.csv")
    page.get_by_role("tab", name="Data").click()
    with page.expect_file_chooser() as chooser:
        page.get_by_role("button", name="Upload a campaign CSV").click()
    chooser.value.set_files(str(data))
    assert wait_for(lambda: "fine_gear.csv" in session.data_panel.source.content, timeout=600)
    session.wait(timeout=300)
    # Its sidecar (the file's 12 check rings, as the command line reads them), as docs/walkthrough_shape.md says.
    with page.expect_file_chooser() as chooser:
        page.get_by_role("button", name="Upload its sidecar TOML").click()
    chooser.value.set_files(str(data.with_suffix(".toml")))
    assert wait_for(lambda: "with its sidecar **fine_gear.toml**" in session.data_panel.message.content, timeout=600)
    session.wait(timeout=300)
    assert int(session.dataset.campaign.holdout_mask().sum()) == 12

    # 1. Diagnose: no catalog effect explains it, a shape does; its curve is drawn under the verdict.
    verdict = diagnosed(page, session)
    assert "Verdict: uncatalogued - angular positioning of the B axis" in verdict, verdict
    in_view(page.get_by_text("Verdict: uncatalogued", exact=False).first, "the verdict")
    chart = page.locator('svg[aria-label^="chart Shape (claimed): angular positioning of the B axis"]').first
    chart.scroll_into_view_if_needed()  # the panel scrolls to it (under the verdict's lines), never the page
    in_view(chart, "the shape's curve")
    assert page.evaluate("() => window.scrollY") == 0
    inked, colours = colour_census(chart.screenshot())
    assert inked >= 1500 and colours >= 3, (inked, colours)  # drawn: its curve and its band, not an empty frame
    step_shot(page, shots, "shapes_1_found")
    # What is left, binned in the head's variables: its caption sends the user to the shape found,
    # not to writing a Python effect.
    caption = page.get_by_text("is claimed as a shape, shape_b_angular", exact=False).first
    chart.hover()
    page.mouse.wheel(0, 300)  # the reader scrolls the panel on (the app then stops keeping the verdict in view)
    caption.scroll_into_view_if_needed()
    in_view(caption, "what is left's caption")
    assert "then Refit the hybrid" in session.physics.evidence_text.content

    # 2. Tick the shape, refit: the check rings' error falls, and the hybrid joins Tables 1-3.
    tables_before = session.tables.markdown.content
    box = page.get_by_role("checkbox", name="shape_b_angular")
    box.scroll_into_view_if_needed()
    in_view(box, "the shape's checkbox")
    # Its label, the shape's id, on one line: not broken mid-word by viser's narrow label column.
    label = page.locator("label", has_text="shape_b_angular").first
    assert label.bounding_box()["height"] < 1.5 * float(label.evaluate("e => parseFloat(getComputedStyle(e).lineHeight)"))
    box.check()
    page.get_by_role("button", name="Refit the hybrid").click()
    assert wait_for(lambda: len(session.loop.steps) >= 2 and "Refitted" in session.physics.refit_status.content, timeout=600)
    session.wait(timeout=300)
    settled(page)
    last, first = session.loop.steps[-1], session.loop.steps[0]
    assert last.added == ("shape_b_angular",) and last.mae_um["mean"] < 0.8 * first.mae_um["mean"]
    assert wait_for(lambda: session.tables.markdown.content != tables_before and "hybrid" in session.tables.markdown.content, timeout=60)
    in_view(page.get_by_text("Check-ring MAE:", exact=False).first, "the error fall")
    step_shot(page, shots, "shapes_2_added")


def test_a_shape_is_found_drawn_added_and_the_error_falls_at_1440x900() -> None:
    shots = walk_in_chromium(add_a_shape, "shapes_")
    assert len(list(shots.glob("shapes_*.png"))) == 2
