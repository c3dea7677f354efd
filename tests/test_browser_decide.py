"""Issue 29's explorer line: when the rings cannot decide, the rings that would, measured by the twin,
in a real headless Chromium at 1440x900, driven by labels, nothing scrolled.

The teacher loads head_6 (a hidden effect that another mechanism mimics on the paper's rings),
diagnoses it (the claim cannot be told from its partner; the default six rings would not decide
it, and the verdict says how many would), asks for the rings that would decide at that budget
(listed, and crossed on the error map), has the twin measure them (they join the campaign as
check rings, on the map), and diagnoses again: the verdict says what the merged rings tell. A screenshot
of each step goes to decide_<n>_<step>.png in PH_EXPLORER_LOOP_SHOTS (docs: the site's).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from fake_browser import wait_for
from test_browser_loop import CHROMIUM, chart_drawn, diagnosed, in_view, scenario_loaded, step_shot, walk_in_chromium

from ph_explorer.io.rings import read_rings

pytestmark = [pytest.mark.browser, pytest.mark.slow]

if not Path(CHROMIUM).exists() and not os.environ.get("CI"):
    pytest.skip("Debian's chromium is not installed (/usr/bin/chromium); apt-get install chromium", allow_module_level=True)

SCENARIO = "head_6"


def decide(page, session, shots: Path) -> None:
    scenario_loaded(page, session, SCENARIO)
    measured = session.dataset.campaign.n_orientations

    # 1. Diagnose: the claim cannot be told from its partner on these rings.
    before = diagnosed(page, session)
    assert "cannot tell them apart" in before, before
    in_view(page.get_by_text("cannot tell them apart", exact=False).first, "the untold pair")
    step_shot(page, shots, "decide_1_diagnosed")

    # 2. Rings that would decide: the default six do not (what the model leaves at the check rings
    # scatters the rings' gains); the verdict says how many would, and the box holds that budget.
    expected = session.loop.decision.expected
    (needed,) = [q["rings_needed"] for q in expected.values() if q.get("rings_needed")] or [expected]
    assert f"{needed} rings would (a budget of {needed})" in before and int(session.physics.budget.value) == needed
    # The rings, listed with their reasons and the CMM time, crossed on the map.
    button = page.get_by_role("button", name="Rings that would decide")
    in_view(button, "Rings that would decide")
    button.click()
    assert wait_for(lambda: session.loop.proposed is not None and len(session.loop.proposed) > 0, timeout=300)
    session.wait(timeout=120)
    proposed = [(float(a), float(b)) for a, b in session.loop.proposed]
    assert 3 <= len(proposed) <= needed
    in_view(page.get_by_text("rings that decide, in this order", exact=False).first, "the rings listed")
    in_view(page.get_by_text("minutes of CMM time", exact=False).first, "the CMM time")
    error_map = page.locator('svg[aria-label^="error map"]').first
    assert wait_for(lambda: error_map.inner_html().count("proposed, not measured yet") == len(proposed), timeout=30)
    chart_drawn(page, "error map")
    step_shot(page, shots, "decide_2_rings")
    # The same rings as a file for a CMM program (what design --decide --out writes).
    with page.expect_download() as download:
        page.get_by_role("button", name="Download rings.csv").click()
    path = download.value.path()
    assert np.allclose(read_rings(path), proposed)

    # 3. Measure them: the twin measures them after the campaign; they are on the map as check rings.
    measure = page.get_by_role("button", name="Measure them")
    in_view(measure, "Measure them")
    measure.click()
    assert wait_for(lambda: session.dataset.campaign.n_orientations == measured + len(proposed), timeout=600)
    session.wait(timeout=300)
    assert wait_for(lambda: "proposed, not measured yet" not in error_map.inner_html(), timeout=30)
    for a, b in proposed:
        assert wait_for(lambda a=a, b=b: f"A{a:g} B{b:g}:" in error_map.inner_html(), timeout=30), (a, b)
    assert f"{len(proposed)} rings measured by the twin" in session.data_panel.source.content
    chart_drawn(page, "error map")
    step_shot(page, shots, "decide_3_measured")

    # 4. Diagnose again on the merged rings: the pair's test over rings is run again, and the verdict
    # says what the rings now tell (told apart, or the pair still named, with what would decide it).
    page.get_by_role("button", name="Diagnose", exact=True).click()
    assert wait_for(lambda: session.loop.diagnosis is not None and "Verdict" in session.physics.verdict.content, timeout=900)
    session.wait(timeout=300)
    after = session.physics.verdict.content
    told = "the rings tell them apart" if "the rings tell them apart" in after else "these rings cannot tell"
    assert after != before and told in after and "a_axis_cyclic" in after, after
    in_view(page.get_by_text(told, exact=False).first, "what the rings now tell")
    step_shot(page, shots, "decide_4_decided")


def test_the_rings_that_would_decide_measured_by_the_twin_decide_at_1440x900() -> None:
    shots = walk_in_chromium(decide, "decide_")
    assert len(list(shots.glob("decide_*.png"))) == 4
