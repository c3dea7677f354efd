"""The hybrid's data part: the trilinear interpolation and the mean curve of the training rings
(models.trilinear.MeanCurveModel), and the Gaussian process; a hybrid with each as its data part.
How the data-efficiency benchmark weighs them (benchmarks/stacking.py, experiment code) is checked
beside it, outside this suite (benchmarks/experiment_checks.py)."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import lobing_campaign, scenario_with

from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.geometry import point_angles_deg
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.models.hybrid import HybridModel
from ph_explorer.models.trilinear import MeanCurveModel
from ph_explorer.twin import simulate

B_AXIS = DEFAULT_CATALOG["b_axis_cyclic"]


def test_the_mean_curve_is_the_same_at_every_orientation_and_round_trips(tmp_path) -> None:
    campaign = lobing_campaign(seed=1)
    train = ~campaign.holdout_mask()
    model = MeanCurveModel().fit(campaign, train)
    expected = campaign.deviations[train].mean(axis=(0, 1))
    predicted = model.predict([[0.0, 0.0], [43.0, 91.0], [90.0, -170.0]])
    assert np.allclose(predicted, expected[None, :], atol=1e-12)
    # The spread of single touches about their own ring's mean, pooled: the touch noise (0.175 um).
    assert model.repetition_sigma([[10.0, 20.0]]).mean() == pytest.approx(0.175, rel=0.05)
    # Another number of points: the curve interpolated round the ring, then circle-fitted.
    coarse = model.predict([[10.0, 20.0]], n_points=32)[0]
    assert np.allclose(coarse, remove_size_and_centre(np.interp(point_angles_deg(32), point_angles_deg(64), expected, period=360.0)))
    again = MeanCurveModel.load(model.save(tmp_path).parent)
    assert np.array_equal(again.predict([[5.0, 5.0]]), model.predict([[5.0, 5.0]]))


def test_its_out_of_sample_weights_are_the_mean_of_the_other_training_rings() -> None:
    orientations = np.array([[0.0, 0.0], [15.0, 20.0], [30.0, 40.0], [45.0, 60.0], [60.0, 80.0]])
    train = np.array([True, True, True, True, False])
    weights = OutOfSampleSmoother(orientations, train, MeanCurveModel).weights
    expected = (
        np.array([[0, 1, 1, 1, 0], [1, 0, 1, 1, 0], [1, 1, 0, 1, 0], [1, 1, 1, 0, 0], [1, 1, 1, 1, 0]]) / np.array([3, 3, 3, 3, 4])[:, None]
    )
    assert np.allclose(weights, expected)


def test_a_hybrid_with_each_data_part_predicts_the_same_once_saved_and_loaded(tmp_path) -> None:
    """A head whose only orientation-dependent error is a B 2/rev error, on a dozen of its training
    rings: the hybrid with the trilinear tables, the mean curve or the GP as its data part keeps its
    data part's kind and its predictions through its folder."""
    campaign = simulate(scenario_with(B_AXIS(amplitude_arcsec=1.8, phase_deg=40.0, cycles_per_rev=2)), 3)
    subset = campaign.subset(np.flatnonzero(~campaign.holdout_mask())[::10])
    at = np.array([[43.0, 90.0], [7.5, -170.0]])
    for part in ("trilinear", "mean_curve", "gp"):
        model = HybridModel([B_AXIS(cycles_per_rev=2)], part).fit(subset)
        model.save(tmp_path / part)
        again = HybridModel.load(tmp_path / part)
        assert again.data_part.name == part
        assert np.allclose(again.predict(at), model.predict(at), atol=1e-12)
        assert np.allclose(again.repetition_sigma(at), model.repetition_sigma(at), atol=1e-12)


def test_a_hybrid_without_terms_is_its_data_part_even_given_as_a_model() -> None:
    campaign = lobing_campaign(seed=1)
    train = ~campaign.holdout_mask()
    given = MeanCurveModel()
    hybrid = HybridModel([], given).fit(campaign, train)
    assert hybrid.data_part is given and isinstance(HybridModel([], MeanCurveModel).data_part, MeanCurveModel)  # or a factory
    touches = campaign_touches(campaign.subset([0, 50, 126]))
    alone = MeanCurveModel().fit(campaign, train)
    assert np.allclose(hybrid.predict_touches(touches), alone.predict_touches(touches), atol=1e-12)
