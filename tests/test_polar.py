"""Polar charts as roundness instruments draw them: the profile never reaches the centre, and the
scale circles' labels say the deviations their radii stand for (ph_explorer.figures.polar)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from ph_explorer import paths, twin
from ph_explorer.figures.polar import (
    INNER_CLEARANCE,
    PolarSeries,
    campaign_bounds,
    offered_magnifications,
    polar_scale,
    polar_svg,
    scale_label,
)
from ph_explorer.io import read_campaign


def shipped_campaigns() -> dict[str, object]:
    """The shipped data (assets/data) and every `simulate --list` scenario, simulated with its seed."""
    campaigns = {path.name: read_campaign(path) for path in sorted((paths.assets_dir() / "data").glob("*.csv"))}
    for name in [s.name for s in twin.list_scenarios()]:
        scenario = twin.load_scenario(name)
        campaigns[f"scenario {name}"] = twin.simulate(scenario, scenario.seed)
    return campaigns


@pytest.fixture(scope="module")
def campaigns() -> dict[str, object]:
    return shipped_campaigns()


def test_every_shipped_campaign_stays_off_the_centre_at_every_magnification(campaigns) -> None:
    assert len(campaigns) >= 2 and offered_magnifications().size > 5
    for name, campaign in campaigns.items():
        bore = 0.5 * campaign.geometry.bore_diameter_mm
        # Each repetition (the "each repetition" curves) and the means: every deviation of the campaign.
        for m in offered_magnifications():
            scale = polar_scale(m, [campaign.deviations], bore)
            radius = scale.radius_mm(campaign.deviations)
            assert radius.min() >= INNER_CLEARANCE * scale.base_mm > 0.0, (name, m)
            assert scale.base_mm >= bore  # never smaller than the ring it is drawn on
            circles = np.array([r for _, r in scale.labelled_circles()])
            assert circles.min() > 0.0 and np.all(np.diff(circles) > 0.0)
            assert circles.max() >= radius.max() - 1e-9  # the scale reaches past the profile's peaks


def test_a_stray_touch_rescales_its_own_ring_not_the_campaign() -> None:
    """One touch of 5 um among 0.3 um of noise (debris): every other ring keeps the chart of the
    campaign without it; its own ring, drawn with its touches, keeps them off the centre."""
    rng = np.random.default_rng(4)
    clean = rng.normal(0.0, 0.3, (126, 10, 64))
    stray = clean.copy()
    stray[7, 9, 20], stray[7, 9, 40] = 5.2, -3.1
    for m in offered_magnifications():
        quiet = [campaign_bounds(stray), stray[3], stray[3].mean(axis=0)]
        assert polar_scale(m, quiet, 10.0) == polar_scale(m, [campaign_bounds(clean), clean[3], clean[3].mean(axis=0)], 10.0)
        own = polar_scale(m, [campaign_bounds(stray), stray[7], stray[7].mean(axis=0)], 10.0)
        assert own.radius_mm(stray[7]).min() >= INNER_CLEARANCE * own.base_mm and own.outer_mm >= own.radius_mm(5.2) - 1e-9
    assert campaign_bounds(np.full((2, 3), np.nan)) == (0.0, 0.0)


def test_the_labels_say_the_deviation_of_their_circle() -> None:
    deviations = np.array([-0.97, 1.12])
    for m in offered_magnifications():
        scale = polar_scale(m, [deviations], 10.0)
        assert 0.0 in scale.circles_um
        for text, radius in scale.labelled_circles():
            value = float(text.removesuffix(" um"))
            assert np.isclose(radius, scale.base_mm + m * 1e-3 * value)
            assert value == pytest.approx(round(value / scale.step_um) * scale.step_um)


def test_a_deep_profile_grows_the_base_radius_instead_of_crossing_the_centre() -> None:
    scale = polar_scale(20000.0, [np.array([-2.0, 0.5])], 10.0)  # -2 um x 20000 = 40 mm below the base
    assert scale.base_mm >= 40.0 / (1.0 - INNER_CLEARANCE)
    assert scale.radius_mm(-2.0) >= INNER_CLEARANCE * scale.base_mm
    shallow = polar_scale(1000.0, [np.array([-0.5, 0.5])], 10.0)
    assert shallow.base_mm == 10.0  # room enough: the chart sits on the ring


def test_the_flat_chart_prints_its_scale_circles_magnification_points_and_legend() -> None:
    theta = np.radians(360.0 * np.arange(64) / 64)
    curve = 0.4 * np.cos(3 * theta)
    scale = polar_scale(10000.0, [curve], 10.0)
    svg = polar_svg(scale, [PolarSeries("measured mean", curve, "#1e1e1e")], "A15 B-20")
    circles = [float(r) for r in re.findall(r'<circle cx="0" cy="0" r="([0-9.]+)"', svg)]
    labels = re.findall(r'fill="#555">([^<]+)</text>', svg)
    assert len(circles) == len(labels) == len(scale.circles_um)
    for radius, label in zip(circles, labels):
        value = float(label.split(" um")[0])
        assert radius == pytest.approx(scale.base_mm + 10.0 * value, abs=1e-3)
    assert scale_label(0.0) + " (LS circle)" in labels
    # The labels over the profiles, which cross them at the LS circle: drawn after the curve.
    assert svg.index('stroke="#1e1e1e"') < svg.index('fill="#555">')
    assert "x10000" in svg and "measured mean" in svg and "θ" in svg
    for k in (0, 16, 32, 48):
        assert re.search(rf'dominant-baseline="middle">{k}</text>', svg)
    # The curve's path: point k at radius base + m dev_k, theta counter-clockwise (SVG y down).
    path = re.search(r'<path d="M([^"]+) Z" fill="none" stroke="#1e1e1e"', svg).group(1)
    points = np.array([[float(v) for v in p.split(",")] for p in path.split(" L")])
    np.testing.assert_allclose(np.hypot(points[:, 0], points[:, 1]), scale.radius_mm(curve), atol=2e-3)
    assert points[16, 1] < 0.0  # point 16 (theta 90 deg) is drawn above the centre
