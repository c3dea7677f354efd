"""The models' interface, the trilinear + Monte Carlo model and (below) the Fourier network."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st
from synthetic import lobing_campaign, systematic_curves

from ph_explorer.harmonics import fourier_basis
from ph_explorer.models.crossval import (
    _WEIGHTS,
    OutOfSampleSmoother,
    _out_of_sample,
    out_of_sample_weights,
    unit_campaign,
    weights_operator,
)
from ph_explorer.models.trilinear import TrilinearModel, _node_sums, periodic_weights


@pytest.fixture(scope="module")
def campaign():
    return lobing_campaign(seed=1)


def low_harmonics(curves: np.ndarray) -> np.ndarray:
    """Amplitudes of harmonics 0 and 1 of curves (..., n_pt)."""
    n = curves.shape[-1]
    return np.abs(curves @ fourier_basis(n, 1)) / n


# -- trilinear ---------------------------------------------------------------------------------
def test_periodic_weights_wrap_between_last_and_first_node():
    nodes = np.arange(-160.0, 181.0, 20.0)  # ..., 160, 180
    i0, i1, w = periodic_weights(np.array([170.0, -170.0, 190.0, -160.0]), np.sort(((nodes + 180) % 360) - 180))
    sorted_nodes = np.sort(((nodes + 180) % 360) - 180)  # -180, -160, ..., 160
    assert sorted_nodes[i0[0]] == 160 and sorted_nodes[i1[0]] == -180 and w[0] == pytest.approx(0.5)
    assert sorted_nodes[i0[1]] == -180 and sorted_nodes[i1[1]] == -160 and w[1] == pytest.approx(0.5)
    assert sorted_nodes[i0[2]] == -180 and w[2] == pytest.approx(0.5)  # 190 = -170
    assert sorted_nodes[i0[3]] == -160 and w[3] == pytest.approx(0.0)


def test_trilinear_reproduces_measured_nodes_and_is_periodic_in_b(campaign):
    model = TrilinearModel().fit(campaign)
    grid = ~campaign.off_grid_mask()
    predicted = model.predict(campaign.orientations[grid])
    np.testing.assert_allclose(predicted, campaign.mean_curves()[grid], atol=1e-12)
    np.testing.assert_allclose(model.predict([[30, 170]]), model.predict([[30, -190]]), atol=1e-12)
    np.testing.assert_allclose(model.predict([[30, 180]]), model.predict([[30, -180]]), atol=1e-12)


def test_trilinear_fills_a_held_out_node_from_its_b_neighbours(campaign):
    held = campaign.index_of(15, -20)
    train = np.ones(campaign.n_orientations, bool)
    train[held] = False
    model = TrilinearModel().fit(campaign, train)
    assert not model.measured[np.searchsorted(model.a_axis, 15), np.searchsorted(model.b_axis, -20)]
    neighbours = (campaign.mean_curves()[campaign.index_of(15, -40)] + campaign.mean_curves()[campaign.index_of(15, 0)]) / 2
    np.testing.assert_allclose(model.predict([[15, -20]])[0], neighbours, atol=1e-12)


def test_trilinear_fills_a_whole_missing_a_row_along_a(campaign):
    train = campaign.orientations[:, 0] != 45
    model = TrilinearModel().fit(campaign, train)
    assert model.a_axis.tolist() == [0, 15, 30, 60, 75, 90]  # A 45 never seen: not a node
    expected = (model.predict([[30, 40]]) + model.predict([[60, 40]])) / 2
    np.testing.assert_allclose(model.predict([[45, 40]]), expected, atol=1e-12)


def test_one_a0_ring_is_the_whole_a0_row_where_the_lattice_would_leave_it_out(campaign):
    """Every A0 = 0 ring is the same ring whatever B0: one ring (at a B0 no other row holds) is the
    A0 row at every B, and A0 7.5 lies half-way to the A 15 row instead of holding A 15's curves.
    A full A0 row stays node by node, as the paper's lattice."""
    rows = np.isin(campaign.orientations[:, 0], [15.0, 30.0]) & ~campaign.off_grid_mask()
    train = rows | (np.arange(campaign.n_orientations) == campaign.index_of(0, -160))
    sparse = TrilinearModel().fit(campaign, train)
    assert sparse.a_axis.tolist() == [0, 15, 30] and sparse.measured[0].all()
    a0 = campaign.mean_curves()[campaign.index_of(0, -160)]
    for b in (-160.0, 33.0, 170.0):
        np.testing.assert_allclose(sparse.interpolate([[0.0, b]])[0], a0, atol=1e-12)
        half = (sparse.interpolate([[0.0, b]]) + sparse.interpolate([[15.0, b]])) / 2
        np.testing.assert_allclose(sparse.interpolate([[7.5, b]]), half, atol=1e-12)
    full = TrilinearModel().fit(campaign, train | (campaign.orientations[:, 0] == 0))
    at0 = campaign.orientations[:, 0] == 0
    np.testing.assert_allclose(full.interpolate(campaign.orientations[at0]), campaign.mean_curves()[at0], atol=1e-12)
    without = TrilinearModel().fit(campaign, rows)  # no A0 ring: the lowest row held below it
    np.testing.assert_allclose(without.interpolate([[5.0, 40.0]]), without.interpolate([[15.0, 40.0]]), atol=1e-12)


def test_trilinear_interpolates_off_grid_close_to_the_truth(campaign):
    model = TrilinearModel().fit(campaign, ~campaign.off_grid_mask())
    truth = systematic_curves([[43, 91]])
    error = np.abs(model.predict([[43, 91]]) - truth).mean()
    # Node means carry sigma/sqrt(10) noise; the interpolation error of this smooth field is small.
    assert error < 0.08
    assert error < np.abs(truth).mean() / 3


def test_trilinear_predictions_are_post_fit_curves_at_any_number_of_points(campaign):
    model = TrilinearModel().fit(campaign)
    curves64 = model.predict([[43, 91], [10, 5]])
    curves128 = model.predict([[43, 91], [10, 5]], n_points=128)
    assert curves128.shape == (2, 128)
    assert low_harmonics(curves128).max() < 1e-12 and low_harmonics(curves64).max() < 1e-12
    # Linear interpolation in theta: at the table's own angles the 128-point curve is the 64-point
    # one up to the re-fit of harmonics 0 and 1.
    np.testing.assert_allclose(curves128[:, ::2], curves64, atol=0.02)


def test_trilinear_monte_carlo_has_the_measured_mean_and_spread(campaign):
    model = TrilinearModel().fit(campaign)
    rng = np.random.default_rng(5)
    simulated = model.simulate([[43, 91], [60, -100]], n_repetitions=4000, rng=rng)
    assert simulated.shape == (2, 4000, 64)
    np.testing.assert_allclose(simulated.mean(axis=1), model.predict([[43, 91], [60, -100]]), atol=0.02)
    spread = simulated.std(axis=1, ddof=1)
    sigma = model.repetition_sigma([[43, 91], [60, -100]])
    # The post-fit spread is reproduced on average (the circle fit of each draw is compensated).
    assert spread.mean() == pytest.approx(sigma.mean(), rel=0.02)
    assert 0.15 < sigma.mean() < 0.19  # the campaign's 0.175 um touch noise, after the circle fit
    assert low_harmonics(simulated).max() < 1e-12


def test_a_node_measured_twice_pools_both_rings_as_np_add_at_would():
    """The tables' node sums (sorted, then each node's repeats added in order) equal np.add.at's
    bit for bit, with nodes measured once, twice and three times."""
    rng = np.random.default_rng(4)
    node = np.array([5, 0, 5, 3, 5, 0, 7])
    values = rng.normal(size=(node.size, 6))
    expected = np.zeros((2 * 4, 6))
    np.add.at(expected, node, values)
    assert np.array_equal(_node_sums(node, values, (2, 4)), expected.reshape(2, 4, 6))


def test_the_smoother_applies_a_sparse_w_as_the_dense_one(campaign):
    """An interpolator's out-of-sample W is applied as a sparse matrix: the same predictions."""
    smoother = OutOfSampleSmoother(campaign.orientations, np.ones(campaign.n_orientations, dtype=bool))
    values = np.random.default_rng(1).normal(size=(campaign.n_orientations, 3, 5))
    assert not isinstance(weights_operator(smoother.weights), np.ndarray)  # a few neighbours a ring
    assert np.allclose(smoother.predict(values), np.tensordot(smoother.weights, values, axes=(1, 0)), rtol=0, atol=1e-12)
    dense = np.full((4, 4), 0.25)  # the mean curve's W: every ring from all: applied dense
    assert isinstance(weights_operator(dense), np.ndarray)


@settings(max_examples=150, deadline=None)
@given(
    a_rows=st.lists(st.sampled_from([0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0]), min_size=1, max_size=4, unique=True),
    b_columns=st.lists(st.sampled_from([-180.0, -160.0, -90.0, -20.0, 0.0, 12.5, 40.0, 170.0, 180.0]), min_size=1, max_size=6, unique=True),
    drop=st.floats(0.0, 0.6),
    extra=st.lists(st.tuples(st.floats(0.0, 90.0), st.floats(-180.0, 180.0)), max_size=4),
    twice=st.integers(0, 3),
    seed=st.integers(0, 2**16),
)
def test_the_trilinear_weights_from_one_fit_are_those_of_a_refit_per_ring(a_rows, b_columns, drop, extra, twice, seed):
    """out_of_sample_weights of the trilinear model (one fit; a refit only for the rings it cannot
    read off it) equals a refit without each ring (_out_of_sample), bit for bit: lattices with holes,
    emptied rows, rings off the grid or measured twice, B at -180 and 180, a few rings held out."""
    rng = np.random.default_rng(seed)
    grid = np.array([(a, b) for a in a_rows for b in b_columns])
    grid = grid[rng.random(len(grid)) >= drop] if len(grid) > 1 else grid
    orientations = np.concatenate([grid, np.array(extra).reshape(-1, 2), grid[: min(twice, len(grid))]])
    train = rng.random(len(orientations)) > 0.15
    assume(len(orientations) >= 3 and train.any())  # a unit campaign's "points" are its rings: a circle needs 3

    def outcome(weights_of):
        try:
            return weights_of()
        except ValueError as error:  # no ring on the lattice: the same refusal both ways
            return str(error)

    generic = outcome(lambda: _out_of_sample(TrilinearModel, unit_campaign(orientations), train, lambda model, at: model.interpolate(at)))
    _WEIGHTS.clear()
    weights = outcome(lambda: out_of_sample_weights(orientations, train))
    if isinstance(generic, str) or isinstance(weights, str):
        assert type(weights) is type(generic) and weights == generic
    else:
        assert np.array_equal(weights, generic) and np.array_equal(np.signbit(weights), np.signbit(generic))


def test_the_row_view_predicts_each_inner_row_from_the_rows_beside_it():
    """leave_out="row": a training ring of an inner A row is predicted from the other rows only, an
    end row's and a held-out ring as in the ring view; a pattern of A0 alone, which each lattice
    ring's B neighbours carry exactly, is left at the inner rows' rings and nowhere else."""
    grid = np.array([(a, b) for a in (0.0, 15.0, 30.0, 45.0, 60.0) for b in np.arange(-180.0, 180.0, 30.0)])
    orientations = np.concatenate([grid, [[22.0, 41.0], [50.0, -73.0]]])
    train = np.arange(len(orientations)) < len(grid)
    ring, row = OutOfSampleSmoother(orientations, train), OutOfSampleSmoother(orientations, train, leave_out="row")
    a = orientations[:, 0]
    inner = train & (a > 0.0) & (a < 60.0)
    same_row = np.isclose(a[:, None], a[None, :])
    assert not (row.weights[inner] * same_row[inner]).any() and np.allclose(row.weights.sum(axis=1), 1.0)
    assert np.array_equal(row.weights[~inner], ring.weights[~inner])
    pattern = np.sin(np.radians(7.3 * a))[:, None] * np.ones((1, 4))  # (n_o, points): A0 alone
    assert np.abs(ring.residual(pattern[:, None])[train]).max() < 1e-12
    left = np.abs(row.residual(pattern[:, None])).max(axis=(1, 2))
    assert (left[inner] > 1e-3).all() and left[train & ~inner].max() < 1e-12


def test_trilinear_save_load_round_trip(campaign, tmp_path):
    held = ~campaign.off_grid_mask()
    model = TrilinearModel().fit(campaign, held)
    path = model.save(tmp_path)
    assert path.name == "trilinear.npz"
    loaded = TrilinearModel.load(tmp_path)
    query = [[43, 91], [0, 0], [90, 179], [22, -33]]
    np.testing.assert_array_equal(loaded.predict(query), model.predict(query))
    np.testing.assert_array_equal(loaded.repetition_sigma(query), model.repetition_sigma(query))


def test_predict_touches_broadcasts_over_repetitions(campaign):
    from ph_explorer.kinematics import campaign_touches

    model = TrilinearModel().fit(campaign)
    touches = campaign_touches(campaign.subset(np.arange(5)))
    out = model.predict_touches(touches)
    assert out.shape == (5, campaign.n_repetitions, 64)
    np.testing.assert_allclose(out[:, 3], model.predict(campaign.orientations[:5]))


# -- network -----------------------------------------------------------------------------------
from ph_explorer.models.network import FourierNetwork  # noqa: E402

QUICK = dict(max_epochs=40, early_stopping_patience=40)


@pytest.fixture(scope="module")
def quick_network(campaign):
    train = ~campaign.off_grid_mask()
    seen = []
    model = FourierNetwork(progress=lambda *args: seen.append(args), **QUICK).fit(campaign, train)
    return model, train, seen


def test_network_output_is_a_fourier_curve_of_k_harmonics(quick_network):
    model, _, _ = quick_network
    assert model.config.k_max == 8
    coef = model.coefficients([[43, 91], [0, 0]])
    assert coef.shape == (2, 17)
    curve = model.predict([[43, 91], [0, 0]], n_points=256)
    spectrum = np.abs(np.fft.rfft(curve, axis=1))
    assert spectrum[:, 9:].max() < 1e-9 * spectrum.max()  # nothing above K = 8
    assert spectrum[:, :2].max() < 1e-9 * spectrum.max()  # harmonics 0 and 1: the circle fit's


def test_network_learns_the_systematic_curves_beyond_zero(campaign, quick_network):
    model, train, seen = quick_network
    truth = systematic_curves(campaign.orientations)
    error = np.abs(model.predict(campaign.orientations) - truth).mean()
    assert error < 0.5 * np.abs(truth).mean()  # already after 40 epochs
    assert len(seen) == model.log.epochs and all(np.isfinite(s[2]) for s in seen)
    assert model.log.validation_mae_um[model.log.best_epoch - 1] == min(model.log.validation_mae_um)
    # Validation orientations come from the training set only; the off-grid ring is never seen.
    val = np.array(model.log.validation_orientations)
    assert len(val) and not (np.isclose(val[:, 0], 43) & np.isclose(val[:, 1], 91)).any()
    assert model.log.diagnostics["validation"]["mae_mean_um"] > 0


def test_network_training_is_reproducible_and_saves_without_pickle(campaign, quick_network, tmp_path):
    model, train, _ = quick_network
    again = FourierNetwork(**QUICK).fit(campaign, train)
    query = [[43, 91], [10, -170], [90, 0]]
    np.testing.assert_array_equal(again.predict(query), model.predict(query))
    path = model.save(tmp_path)
    raw = path.read_bytes()
    header = json.loads(raw[8 : 8 + int.from_bytes(raw[:8], "little")])  # safetensors: JSON header + raw tensors
    assert "__metadata__" in header and "head.weight" in header
    loaded = FourierNetwork.load(tmp_path)
    np.testing.assert_array_equal(loaded.predict(query), model.predict(query))
    assert loaded.config == model.config and loaded.sigma_um == model.sigma_um


def test_network_monte_carlo_adds_the_pooled_spread(quick_network):
    model, _, _ = quick_network
    assert 0.15 < model.sigma_um < 0.19
    sim = model.simulate([[43, 91]], n_repetitions=3000, rng=np.random.default_rng(0), n_points=32)
    assert sim.shape == (1, 3000, 32)
    assert sim.std(axis=1, ddof=1).mean() == pytest.approx(model.sigma_um, rel=0.03)
    np.testing.assert_allclose(sim.mean(axis=1), model.predict([[43, 91]], n_points=32), atol=0.02)


def test_network_repetition_target_trains_too(campaign):
    model = FourierNetwork(target="repetitions", max_epochs=3, batch_size=128).fit(campaign, ~campaign.off_grid_mask())
    assert model.log.epochs == 3 and np.isfinite(model.predict([[43, 91]])).all()
    with pytest.raises(ValueError):
        FourierNetwork(target="median").fit(campaign)


@pytest.mark.slow
def test_network_reaches_the_noise_floor_at_held_out_rings():
    """Fully trained on the synthetic campaign: near the floor at held-out rings, like trilinear or better."""
    from ph_explorer.models.trilinear import TrilinearModel
    from ph_explorer.paper.tables import evaluation_report, mean_mae

    c = lobing_campaign(seed=1, check_orientations=[(15, -20), (75, 40), (45, -20), (43, 91)])
    hold = c.holdout_mask()
    models = {"network": FourierNetwork().fit(c, ~hold), "trilinear": TrilinearModel().fit(c, ~hold)}
    report = evaluation_report(c, models, hold)
    average = mean_mae(report)
    floor = report["noise_floor_um"]
    assert average["network"]["mean"] < 1.6 * floor["mean"]
    assert average["network"]["mean"] <= average["trilinear"]["mean"] + 0.01
    for row in report["orientations"]:
        assert 0.08 < row["mae_um"]["network"]["single"] < 0.22


def test_the_folder_names_the_network_file_without_importing_torch() -> None:
    from ph_explorer.models import network
    from ph_explorer.models.folder import MODEL_TYPES, model_class

    assert MODEL_TYPES["network"][2] == network.FILE_NAME
    assert model_class("network") is FourierNetwork
    probe = "import sys, ph_explorer.diagnosis, ph_explorer.models.hybrid; print('torch' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.stdout.strip() == "False", result.stderr
