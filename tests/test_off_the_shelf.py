"""The off-the-shelf peers (models.off_the_shelf): scipy's thin-plate RBF and scikit-learn's GP on the
mean curves' coefficients of harmonics 2..20, as models, on the Map beside the project's."""

from __future__ import annotations

import numpy as np
import pytest
from synthetic import lobing_campaign

from ph_explorer.app.dataset import Dataset, dataset_for
from ph_explorer.campaign import Campaign
from ph_explorer.models.crossval import held_out_ring_mae
from ph_explorer.models.off_the_shelf import PEER_MODELS, CoefficientGPPeer, RBFPeer


@pytest.fixture(scope="module")
def linear_field():
    """Mean curves whose 3/rev and 20/rev parts are linear in (A rad, cos B, sin B), plus harmonics
    the peers do not fit (1 and 21), on a 7 x 12 lattice and three check rings between its nodes."""
    a, b = np.meshgrid([0.0, 15, 30, 45, 60, 75, 90], np.arange(-180.0, 180.0, 30.0), indexing="ij")
    orientations = np.vstack([np.column_stack([a.ravel(), b.ravel()]), [[22.5, 15.0], [52.5, -75.0], [67.5, 105.0]]])
    theta = np.radians(np.arange(64) * 360.0 / 64)
    x = np.column_stack([np.radians(orientations[:, 0]), np.cos(np.radians(orientations[:, 1])), np.sin(np.radians(orientations[:, 1]))])
    wanted = (0.2 + x @ [0.1, -0.05, 0.03])[:, None] * np.cos(3 * theta) + (x @ [0.02, 0.01, -0.04])[:, None] * np.sin(20 * theta)
    extra = 0.05 * np.cos(theta) + 0.03 * np.cos(21 * theta)
    deviations = np.repeat((wanted + extra)[:, None, :], 2, axis=1)
    return Campaign(orientations, deviations, check_orientations=orientations[-3:]), wanted


def test_the_peers_fit_harmonics_2_to_20_and_reproduce_a_field_linear_in_their_features(linear_field) -> None:
    """The thin-plate RBF is exact on a linear field and the GP close; harmonics 0, 1 and 21 are not
    fitted (what the circle fit removes, what lies beyond)."""
    campaign, wanted = linear_field
    train, at = ~campaign.holdout_mask(), campaign.orientations[-3:]
    assert train.sum() == 84
    np.testing.assert_allclose(RBFPeer().fit(campaign, train).predict(at), wanted[-3:], atol=1e-8)
    gp = CoefficientGPPeer().fit(campaign, train)
    assert np.abs(gp.predict(at) - wanted[-3:]).max() < 0.01 * np.abs(wanted).max()
    variance = gp.curve_variance(at)
    assert variance.shape == (3, 64) and (variance > 0).all()
    assert gp.predict(at, n_points=32).shape == (3, 32)


@pytest.mark.parametrize("name", list(PEER_MODELS))
def test_a_peer_round_trips_without_learning_again(linear_field, name, tmp_path) -> None:
    campaign, _ = linear_field
    train, at = ~campaign.holdout_mask(), np.array([[43.0, 90.0], [7.5, -170.0]])
    model = PEER_MODELS[name]().fit(campaign, train)
    path = model.save(tmp_path)
    assert path.name == f"{name}.npz"
    again = PEER_MODELS[name].load(tmp_path)
    np.testing.assert_allclose(again.predict(at), model.predict(at), atol=1e-10)
    assert again.repetition_sigma(at).shape == (2, 64)


def test_the_map_scores_each_peer_on_the_check_rings_only() -> None:
    campaign = lobing_campaign(seed=3, extra_orientations=((43.0, 90.0), (15.0, -20.0)), check_orientations=((43.0, 90.0), (15.0, -20.0)))
    dataset = dataset_for(campaign, "synthetic", None)
    for name in PEER_MODELS:
        assert f"{name} MAE / noise floor, check rings" in dataset.figure_names()
    figure = dataset.figure("rbf MAE / noise floor, check rings")
    held = dataset.held_out_mask
    assert held.sum() >= 2 and np.isnan(figure.values[~held]).all()
    expected = held_out_ring_mae(RBFPeer().fit(campaign, ~held), campaign, held)["mean"] / dataset.noise_floor_um["mean"]
    np.testing.assert_allclose(figure.values[held], expected)
    assert figure.unit == "x floor" and "peer" in figure.note
    # A campaign with no check ring has nothing to score a peer on: the Map does not offer them.
    every = Dataset(campaign, dataset.models, "every ring trained on", train_mask=np.ones(campaign.n_orientations, dtype=bool))
    assert not any(n.startswith("rbf") for n in every.figure_names())
