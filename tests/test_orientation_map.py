"""The error map over orientations: its figures (computed by the core, no viser), its SVG, and the
failing rings of a diagnosis, worst first."""

from __future__ import annotations

import re

import numpy as np
import pytest
from synthetic import lobing_campaign

from ph_explorer.app.dataset import LOO_FIGURE, LOO_RATIO_FIGURE, RONT_FIGURE, Dataset, dataset_for
from ph_explorer.diagnosis.results import RING_VERDICTS, Diagnosis, Ring
from ph_explorer.diagnosis.within_noise import NoiseTest
from ph_explorer.figures.charts import nice_ticks
from ph_explorer.figures.diagnosis_report import diagnosis_figures
from ph_explorer.figures.orientation_map import MapFigure, map_svg, ranked_rings
from ph_explorer.harmonics import ron_t
from ph_explorer.metrics import noise_floor, ring_mae
from ph_explorer.models.crossval import OutOfSampleSmoother, cross_val_predict, held_out_mae
from ph_explorer.models.trilinear import TrilinearModel

CHECK = ((43.0, 90.0), (22.0, -30.0), (52.0, 130.0))  # off the lattice


@pytest.fixture(scope="module")
def twin() -> Dataset:
    """A small twin campaign with three check rings, and an extra model fitted on its training rings."""
    campaign = lobing_campaign(seed=4, n_repetitions=5, extra_orientations=CHECK, check_orientations=CHECK)
    dataset = dataset_for(campaign, "small twin", None)
    return dataset.with_model("coarse", TrilinearModel().fit(campaign, dataset.train_mask))


def test_nice_ticks_are_round_and_inside_the_range() -> None:
    assert nice_ticks(0.043, 0.171) == [0.05, 0.1, 0.15]
    assert nice_ticks(0.8, 3.9) == [1.0, 2.0, 3.0]
    for low, high in [(0.0123, 0.0456), (1.0, 97.0), (-2.0, 2.0)]:
        ticks = nice_ticks(low, high)
        assert len(ticks) >= 3 and all(low <= t <= high for t in ticks), (low, high, ticks)


def test_the_map_figures_are_the_cores_out_of_sample_errors(twin: Dataset) -> None:
    c = twin.campaign
    loo = twin.figure(LOO_FIGURE)
    expected = ring_mae(cross_val_predict(TrilinearModel, c, twin.train_mask), c.deviations)["mean"]
    np.testing.assert_allclose(loo.values, expected)
    assert loo.unit == "um" and np.all(loo.values > 0)
    # Over each ring's own floor: its noise and that of the rings predicting it (never below the plain floor).
    floor = OutOfSampleSmoother(c.orientations, twin.train_mask).noise_floor(c.noise_sigma_um(), c.n_repetitions)["mean"]
    ratio = twin.figure(LOO_RATIO_FIGURE)
    np.testing.assert_allclose(ratio.values, expected / floor)
    assert ratio.unit == "x floor" and np.all(floor > noise_floor(c.noise_sigma_um(), c.n_repetitions)["mean"])
    np.testing.assert_allclose(twin.figure(RONT_FIGURE).values, ron_t(c.mean_curves()))
    # Another model: out of sample on the check rings only; its training rings carry no value.
    names = twin.figure_names()
    assert "coarse MAE, check rings" in names and "coarse MAE / noise floor, check rings" in names
    other = twin.figure("coarse MAE, check rings")
    check = c.holdout_mask()
    assert check.sum() == 3 and np.isnan(other.values[~check]).all() and np.isfinite(other.values[check]).all()
    assert np.mean(other.values[check]) == pytest.approx(held_out_mae(twin.models["coarse"], c, check)["mean"])
    # The worst rings of a figure, largest first, with their orientation.
    worst = twin.worst_orientations("coarse MAE, check rings", count=5)
    assert len(worst) == 3 and [v for _, _, v in worst] == sorted(other.values[check], reverse=True)


def test_the_map_svg_has_axes_ticks_rings_the_current_orientation_and_a_colour_bar(twin: Dataset) -> None:
    c = twin.campaign
    figure = twin.figure(LOO_FIGURE)
    svg = map_svg(figure, c.orientations, c.holdout_mask(), (15.0, -20.0), LOO_FIGURE)
    assert "A (deg)" in svg and "B (deg)" in svg
    for tick in (">-180<", ">-60<", ">0<", ">60<", ">180<", ">15<", ">45<", ">90<"):
        assert tick in svg, tick
    # Every ring a marker: check rings as diamonds (paths with a title), training rings as circles.
    assert svg.count("(check ring)</title></path>") == 3
    assert len(re.findall(r'<circle cx="[^"]+" cy="[^"]+" r="4.6"', svg)) == c.n_orientations - 3
    assert 'r="9" fill="none" stroke="#111"' in svg  # the current orientation
    # The colour bar: round ticks between min and max (more than the two ends), and the unit.
    low, high = np.min(figure.values), np.max(figure.values)
    labels = [float(t) for t in re.findall(r'text-anchor="middle">([-0-9.e]+)</text>', svg.split("linearGradient")[-1])]
    assert len(labels) >= 3 and all(low <= t <= high for t in labels), labels
    assert ">um</text>" in svg
    # Every marker's title gives the ring and its value with its unit.
    a, b = c.orientations[0]
    assert f"A{a:g} B{b:g}: {figure.values[0]:.3g} um" in svg


def test_a_slider_move_redraws_the_marker_only_and_the_kept_map_is_the_fresh_one(twin: Dataset) -> None:
    """map_svg keeps the static part per (figure, rings) objects: a move changes the marker only, and
    the kept SVG equals one drawn from fresh copies of the same figure and rings."""
    c = twin.campaign
    figure, orientations, check = twin.figure(LOO_FIGURE), c.orientations.copy(), c.holdout_mask()
    here, there = (map_svg(figure, orientations, check, current, LOO_FIGURE) for current in ((15.0, -20.0), (45.0, 60.0)))

    def strip(svg):
        return re.sub(r'<line x1[^>]*stroke-dasharray[^>]*/><line[^>]*/><circle[^>]*r="9"[^>]*/><circle[^>]*r="9"[^>]*/>', "", svg)

    assert here != there and strip(here) == strip(there)
    fresh = MapFigure(figure.values.copy(), figure.unit, figure.note, figure.categories)
    assert map_svg(fresh, orientations.copy(), check.copy(), (45.0, 60.0), LOO_FIGURE) == there


def test_a_verdict_map_has_a_legend_of_its_categories_not_a_colour_bar(twin: Dataset) -> None:
    c = twin.campaign
    verdict = MapFigure((np.arange(c.n_orientations) % 7 == 0).astype(float), "", "test", RING_VERDICTS)
    svg = map_svg(verdict, c.orientations, c.holdout_mask(), None)
    assert "linearGradient" not in svg
    assert RING_VERDICTS[0] in svg and RING_VERDICTS[1] in svg
    assert svg.count("#d62728") == int((np.arange(c.n_orientations) % 7 == 0).sum()) + 1  # the markers + the legend's swatch
    assert [ring[:2] for ring in ranked_rings(verdict, c.orientations)][:1] == [tuple(c.orientations[0])]


def diagnosis_of(mae: list[float], floor: list[float], failing: list[bool], held_out: list[bool]) -> Diagnosis:
    """A Diagnosis holding only what the per-ring figures read."""
    n = len(mae)
    p_ring = np.where(failing, 1e-4, 0.5)
    rings = tuple(
        Ring(30.0, i * 20.0 - 160.0, held_out[i], {"mean": mae[i], "single": mae[i]}, {"mean": floor[i], "single": floor[i]}, failing[i])
        for i in range(n)
    )
    return Diagnosis(
        verdict="unexplained",
        noise_floor_um={},
        baseline_model="trilinear",
        baseline_mae_um={},
        candidates=(),
        found=(),
        suggested=(),
        not_needed=(),
        signature=(),
        # Failing rings by their mean (the smaller p-value), as the per-ring figures read them.
        within_noise={"baseline": NoiseTest(p_ring, int(sum(failing)), 2.0, 1.0, 0.01, True, 2.0, p_ring / 2, np.ones(n)), "after": None},
        steps=(),
        rings=rings,
    )


def test_failing_rings_are_worst_first_by_their_error_over_their_floor() -> None:
    # Ring 0 has the largest error but a large floor; ring 3 is far above its floor but within noise by the test.
    result = diagnosis_of(
        mae=[0.30, 0.12, 0.20, 0.50, 0.05],
        floor=[0.15, 0.03, 0.05, 0.05, 0.04],
        failing=[True, True, True, False, True],
        held_out=[False, True, False, False, False],
    )
    rings = result.failing_rings()
    assert [(r.b_deg, round(r.ratio, 2)) for r in rings] == [(-140.0, 4.0), (-120.0, 4.0), (-160.0, 2.0), (-80.0, 1.25)]
    assert rings[0].held_out and rings[0].mae_um["mean"] == 0.12 and rings[0].floor_um["mean"] == 0.03
    assert not any(r.by_scatter for r in rings) and rings[0].exceeds_by == "repetition mean"
    figures = diagnosis_figures(result)
    verdict = figures["diagnosis: ring verdict (within-noise test)"]
    np.testing.assert_array_equal(verdict.values, [1, 1, 1, 0, 1])
    assert verdict.text(1.0) == "exceeds its noise"
    np.testing.assert_allclose(figures["diagnosis: out-of-sample MAE / its floor"].values, [2.0, 4.0, 4.0, 10.0, 1.25])
