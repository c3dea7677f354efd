"""Monte Carlo bands with every component (issue 17): coverage on a twin campaign, the budget adding
up in quadrature, the hybrid's parameters, the adaptive Monte Carlo's stopping rule, the task."""

from __future__ import annotations

import copy
import dataclasses
import tomllib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from ph_explorer.campaign import Campaign
from ph_explorer.geometry import point_angles_deg
from ph_explorer.models.crossval import cross_val_predict
from ph_explorer.models.hybrid import HybridModel
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.paths import scenarios_dir
from ph_explorer.twin import scenario_from_dict, simulate
from ph_explorer.uncertainty.bands import Sources, band_coverage, model_bands, orientation_band
from ph_explorer.uncertainty.model_error import (
    OutOfSampleError,
    a_groups,
    harmonic_power,
    out_of_sample_error,
    random_phase_curves,
    white_noise_power,
)
from ph_explorer.uncertainty.montecarlo import adaptive_monte_carlo, batch_size, is_stable, numerical_tolerance, tail_quantiles
from ph_explorer.uncertainty.parameter_spread import parameter_spread
from ph_explorer.uncertainty.task import measured_task, normalised_error, task_uncertainty

CHECKS = [[22, -130], [37, 150], [52, 10], [67, -70], [83, 110], [28, 50], [58, -150], [76, -10], [43, 90], [13, 30], [47, -100], [71, 170]]


@pytest.fixture(scope="module")
def twin():
    """A small twin campaign: the paper's head on a coarse lattice (A step 30, B step 40), 5 repetitions, 32 points."""
    data = copy.deepcopy(tomllib.loads((scenarios_dir() / "paper.toml").read_text(encoding="utf-8")))
    data.update(name="small", repetitions=5, check_orientations=CHECKS)
    data["orientations"] = {"a_deg": [0, 90, 30], "b_deg": [-160, 180, 40], "off_grid": CHECKS}
    data.setdefault("geometry", {})["points_per_circle"] = 32
    scenario = scenario_from_dict(data)
    return scenario, simulate(scenario, 5)


@pytest.fixture(scope="module")
def trilinear(twin):
    _, campaign = twin
    train = ~campaign.holdout_mask()
    return TrilinearModel().fit(campaign.subset(train)), out_of_sample_error(TrilinearModel, campaign, train)


def test_the_full_band_covers_held_out_rings_the_noise_band_does_not(twin, trilinear):
    _, campaign = twin
    model, error = trilinear
    check = campaign.holdout_mask()
    assert check.sum() == len(CHECKS) and campaign.n_points == 32
    bands = model_bands(Sources(model, campaign.n_repetitions, error), campaign.orientations[check], rng=np.random.default_rng(1), ndig=1)
    full = band_coverage(bands, campaign.deviations[check])
    noise = band_coverage(bands, campaign.deviations[check], "repeatability")
    # On a lattice twice as coarse as the paper's the interpolation error is larger than the noise
    # of a 5-repetition mean: the noise-only bands miss it, the full band does not.
    assert noise["mean"] < 0.9 and noise["touch"] < 0.92
    assert 0.93 <= full["mean"] <= 1.0 and full["mean"] > noise["mean"] + 0.1
    assert 0.92 <= full["touch"] <= 0.98 and full["touch"] > noise["touch"]
    for band in bands:
        assert np.all(band.lower["touch"] < band.prediction) and np.all(band.prediction < band.upper["touch"])
        assert np.all(band.upper["mean"] - band.lower["mean"] < band.upper["touch"] - band.lower["touch"])


def test_budget_components_add_up_in_quadrature(twin, trilinear):
    _, campaign = twin
    model, error = trilinear
    band = orientation_band(Sources(model, campaign.n_repetitions, error), (52.0, 10.0), rng=np.random.default_rng(2), ndig=2)
    b = band.budget_um
    assert b["model"] > 0.2 * b["repeatability"] and b["parameters"] == 0.0
    assert b["combined_touch"] ** 2 == pytest.approx(b["repeatability"] ** 2 + b["model"] ** 2 + b["parameters"] ** 2, rel=0.02)
    assert b["combined_mean"] ** 2 == pytest.approx(b["repeatability_mean"] ** 2 + b["model"] ** 2 + b["parameters"] ** 2, rel=0.02)
    assert b["repeatability_mean"] == pytest.approx(b["repeatability"] / np.sqrt(campaign.n_repetitions), rel=0.02)
    # Without the model's error the band is the noise-only one of `simulate`.
    plain = orientation_band(Sources(model, campaign.n_repetitions), (52.0, 10.0), rng=np.random.default_rng(2), ndig=1)
    assert plain.budget_um["model"] == 0.0
    assert plain.budget_um["combined_touch"] == pytest.approx(plain.budget_um["repeatability"], rel=1e-9)
    sims = model.simulate([(52.0, 10.0)], 20_000, np.random.default_rng(3))[0]
    assert np.quantile(sims, 0.975, axis=0) == pytest.approx(plain.upper["touch"], abs=0.02)


def test_the_hybrid_adds_its_parameters_and_they_add_up(twin):
    scenario, campaign = twin
    train = ~campaign.holdout_mask()
    effects = [e for e in scenario.starting_effects if e.candidate and "touch_times" not in e.needs]
    hybrid = HybridModel(effects, "trilinear").fit(campaign.subset(train))
    spread = parameter_spread(hybrid, campaign.subset(train))
    assert spread is not None and spread.covariance.shape[0] == hybrid.coefficients_.size
    band = orientation_band(Sources(hybrid, campaign.n_repetitions, None, spread), (52.0, 10.0), rng=np.random.default_rng(4), ndig=2)
    b = band.budget_um
    assert b["parameters"] > 0.0
    assert b["combined_mean"] ** 2 == pytest.approx(b["repeatability_mean"] ** 2 + b["parameters"] ** 2, rel=0.02)
    # The parameters' power per harmonic is what their draws hold.
    draws = spread.draw((52.0, 10.0), 20_000, campaign.n_points, np.random.default_rng(5))
    assert harmonic_power(draws).mean(axis=0) == pytest.approx(spread.power((52.0, 10.0), campaign.n_points), rel=0.05, abs=1e-9)


def test_model_error_spectrum_removes_the_noise_of_the_mean():
    rng = np.random.default_rng(6)
    n, rings, variance = 64, 4000, 0.01
    # Pure white noise residuals: the model's error power is zero within sampling error.
    residuals = rng.normal(0.0, np.sqrt(variance), (rings, n))
    error = OutOfSampleError.from_residuals(np.column_stack([np.zeros(rings), np.zeros(rings)]), residuals, np.full(rings, variance))
    assert abs(error.power.mean(axis=0)[2:].sum()) < 0.03 * variance
    # A known error spectrum comes back, and draws have it.
    power = np.zeros(n // 2 + 1)
    power[[3, 7, n // 2]] = [0.02, 0.01, 0.005]
    draws = random_phase_curves(power, 20_000, n, rng)
    assert harmonic_power(draws).mean(axis=0) == pytest.approx(power, abs=1e-3)
    assert white_noise_power(variance, n).sum() == pytest.approx(variance)  # Parseval
    noisy = OutOfSampleError.from_residuals(np.zeros((2000, 2)), draws[:2000] + rng.normal(0, 0.1, (2000, n)), np.full(2000, 0.01))
    assert noisy.variance([(0.0, 0.0)])[0] == pytest.approx(power, abs=2e-3)


def test_tolerance_and_stopping_rule():
    assert batch_size(0.95) == 10_000 and batch_size(0.999) == 100_000
    assert numerical_tolerance(np.array([0.0734, 0.18, 0.0]), 2) == pytest.approx([0.0005, 0.005, 0.0])
    assert numerical_tolerance(np.array([0.18]), 1) == pytest.approx([0.05])
    delta = np.array([0.01, 0.0])  # the second quantity is left out (u = 0)
    steady = np.tile(np.array([[1.0, 0.0], [0.1, 0.0], [0.8, 0.0], [1.2, 0.0]]), (3, 1, 1))
    assert is_stable(steady, delta) and not is_stable(steady[:1], delta)  # one batch never suffices
    jumpy = steady.copy()
    jumpy[:, 2, 0] += np.array([0.0, 0.02, -0.02])  # y_low moves: s = 0.0115, 2 s > delta
    assert not is_stable(jumpy, delta)


@settings(max_examples=60, deadline=None)
@given(
    trials=st.integers(2, 3000),
    quantities=st.integers(1, 6),
    tail=st.floats(0.0, 0.5),
    seed=st.integers(0, 2**32 - 1),
    ties=st.booleans(),
)
def test_the_batch_endpoints_are_numpys_quantiles_to_the_bit(trials, quantities, tail, seed, ties):
    """tail_quantiles sorts instead of partitioning (faster): the same numbers as np.quantile's
    linear method, ties, constant quantities and NaN included."""
    rng = np.random.default_rng(seed)
    values = rng.standard_normal((trials, quantities)) * rng.uniform(1e-3, 1e3, quantities)
    if ties:
        values = np.round(values, 1)
        values[:, 0] = 0.0  # a component left out: all its trials zero
    np.testing.assert_array_equal(tail_quantiles(values, tail), np.quantile(values, [tail, 1.0 - tail], axis=0))
    values[trials // 2, -1] = np.nan
    np.testing.assert_array_equal(tail_quantiles(values, tail), np.quantile(values, [tail, 1.0 - tail], axis=0))


def test_adaptive_monte_carlo_runs_until_the_tolerance_is_met():
    def draw(m, rng):
        return rng.normal(0.0, [0.012, 0.15], (m, 2))

    coarse = adaptive_monte_carlo(draw, 0.95, np.random.default_rng(7), ndig=1, trials_per_batch=1000)
    fine = adaptive_monte_carlo(draw, 0.95, np.random.default_rng(7), ndig=2, trials_per_batch=1000)
    assert coarse.converged and fine.converged and coarse.batches >= 2
    assert fine.trials > coarse.trials
    # At convergence the endpoints sit within the tolerance of the exact ones.
    assert np.all(np.abs(fine.upper - 1.959964 * np.array([0.012, 0.15])) <= 2 * fine.tolerance)
    capped = adaptive_monte_carlo(draw, 0.95, np.random.default_rng(7), ndig=4, trials_per_batch=1000, max_trials=3000)
    assert not capped.converged and capped.trials == 3000
    with pytest.raises(ValueError):
        adaptive_monte_carlo(draw, 1.0)


def test_task_uncertainty_and_normalised_error(twin, trilinear):
    _, campaign = twin
    model, error = trilinear
    i = int(np.flatnonzero(campaign.holdout_mask())[0])
    task = task_uncertainty(Sources(model, campaign.n_repetitions, error), campaign.orientations[i], rng=np.random.default_rng(8))
    assert task["converged"] and task["k"] == 2.0 and set(task["harmonics_um"]) == {str(h) for h in range(2, 16)}
    ront = task["ront_um"]
    assert 0 < ront["lower"] < ront["value"] < ront["upper"] and ront["U"] > 0
    measured = measured_task(campaign.deviations[i : i + 1])
    assert measured["value"].shape == (1, 15) and np.all(measured["U"] > 0)
    assert normalised_error([1.0, 1.0], [0.3, 0.0], [1.5, 1.0], [0.4, 0.1]).tolist() == pytest.approx([1.0, 0.0])


def test_cross_validation_in_folds_never_fits_the_ring_it_predicts(twin):
    _, campaign = twin
    train = ~campaign.holdout_mask()
    base = cross_val_predict(TrilinearModel, campaign, train, folds=5, strict=True)
    ring = int(np.flatnonzero(train)[7])
    deviations = campaign.deviations.copy()
    deviations[ring] += np.cos(3 * np.radians(point_angles_deg(campaign.n_points)))  # 1 um of 3 UPR
    after = cross_val_predict(TrilinearModel, dataclasses.replace(campaign, deviations=deviations), train, folds=5, strict=True)
    assert np.allclose(after[ring], base[ring])  # the ring is never in its own fit
    assert not np.allclose(after, base)  # but it is in the fits that predict the others


def test_an_error_that_changes_with_a_alone_is_seen_by_the_cross_validation_along_a():
    # Every ring of a row shares its curve, 1 um of 3 UPR times (A / 90)^2: interpolating between
    # neighbours in a row is exact, between rows 15 deg apart it is not. The folds alone see nothing;
    # the rows left out along A see the curvature: at A = 45 the trilinear predicts the row from
    # A = 30 and 60, off by (45^2 - (30^2 + 60^2) / 2) / 90^2 = -0.028 um of 3 UPR.
    a_values, b_values, n = np.arange(0.0, 91.0, 15.0), np.arange(-160.0, 181.0, 20.0), 32
    orientations = np.array([(a, b) for a in a_values for b in b_values])
    theta = np.radians(point_angles_deg(n))
    curves = (orientations[:, 0:1] / 90.0) ** 2 * np.cos(3 * theta)
    campaign = Campaign(orientations, np.repeat(curves[:, None, :], 3, axis=1))
    train = np.ones(len(orientations), dtype=bool)
    assert [np.unique(orientations[g, 0]).tolist() for g in a_groups(orientations, train)] == [[15.0], [30.0], [45.0], [60.0], [75.0]]
    folds_only = cross_val_predict(TrilinearModel, campaign, train, folds=5, strict=True)
    assert np.allclose(folds_only, curves, atol=1e-9)
    error = out_of_sample_error(TrilinearModel, campaign, train)
    expected = 0.5 * (45.0**2 - (30.0**2 + 60.0**2) / 2.0) ** 2 / 90.0**4  # mean square of 3 UPR
    at_45 = error.power[np.flatnonzero(orientations[:, 0] == 45.0)]
    assert at_45[:, 3] == pytest.approx(expected, rel=1e-6) and np.allclose(np.delete(at_45, 3, axis=1), 0.0, atol=1e-12)
    # The edge rows (never left out along A: extrapolated) take the kernel mean of the others.
    assert np.all(error.power[orientations[:, 0] == 0.0, 3] > 0.0)
    # More interior A values than folds: every folds-th value left out together, every ring once.
    many = np.column_stack([np.arange(0.0, 91.0, 5.0), np.zeros(19)])
    groups = a_groups(many, np.ones(19, dtype=bool))
    assert len(groups) == 5 and sorted(np.concatenate(groups).tolist()) == list(range(1, 18))


def test_the_model_error_is_calibrated_on_held_out_rings_and_the_band_follows(twin, trilinear, tmp_path):
    """calibrate_model_error: the smallest scale of the model error's variance with which `level` of the
    held-out rings' mean-curve points lie in the (Gaussian) mean band; a band calibrated on some
    held-out rings then covers the others; the scale survives the model folder's file."""
    from ph_explorer.uncertainty.bands import band_variance, calibrate_model_error
    from ph_explorer.uncertainty.model_error import load_errors, save_errors

    _, campaign = twin
    model, error = trilinear
    check = np.flatnonzero(campaign.holdout_mask())
    sources = Sources(model, campaign.n_repetitions, error)
    orientations, means = campaign.orientations[check], campaign.mean_curves()[check]
    calibrated = calibrate_model_error(sources, orientations, means)
    scale = calibrated.error.scale
    assert calibrated.error.calibration_rings == len(check) and scale > 0 and error.scale == 1.0
    residual = np.abs(means - model.predict(orientations, n_points=campaign.n_points))

    def covered(s: float) -> float:
        return float(np.mean(residual <= 1.959964 * np.sqrt(band_variance(sources, orientations, campaign.n_points, "mean", scale=s))))

    assert covered(scale) >= 0.95 > covered(0.98 * scale)
    # Rings whose error is twice as large need a larger scale (about four times, in variance).
    doubled = calibrate_model_error(
        sources,
        orientations,
        model.predict(orientations, n_points=campaign.n_points) + 2 * (means - model.predict(orientations, n_points=campaign.n_points)),
    )
    assert doubled.error.scale > 2.5 * scale
    # A model error the cross-validation saw as nothing cannot be scaled up: the band stays finite.
    nothing = calibrate_model_error(
        Sources(model, campaign.n_repetitions, dataclasses.replace(error, power=0 * error.power)), orientations, means
    )
    assert np.all(np.isfinite(band_variance(nothing, orientations, campaign.n_points)))
    # Too few rings say too little: the cross-validation's size is kept.
    assert calibrate_model_error(sources, orientations[:4], means[:4]) is sources
    # Calibrated on the first half of the check rings, the band covers the mean curves of the second.
    half = len(check) // 2
    first = calibrate_model_error(sources, orientations[:half], means[:half])
    bands = model_bands(first, orientations[half:], rng=np.random.default_rng(9), ndig=1)
    assert band_coverage(bands, campaign.deviations[check[half:]])["mean"] >= 0.85
    # The model folder's file keeps the scale; a file written before it reads as not calibrated.
    save_errors({"trilinear": calibrated.error}, tmp_path, campaign.n_repetitions)
    loaded, _ = load_errors(tmp_path)
    assert loaded["trilinear"].scale == scale and loaded["trilinear"].calibration_rings == len(check)
    with np.load(tmp_path / "uncertainty.npz") as data:
        old = {k: data[k] for k in data.files if not (k.endswith(".scale") or ".calibration_" in k)}
    np.savez(tmp_path / "uncertainty.npz", **old)
    loaded, _ = load_errors(tmp_path)
    assert loaded["trilinear"].scale == 1.0 and loaded["trilinear"].calibration_rings == 0
    assert np.all(loaded["trilinear"].scale_at(orientations) == 1.0)


def test_the_gaussian_band_is_the_monte_carlo_band_without_its_trials(twin, trilinear):
    """The explorer's instant band (prediction +- z sqrt(variance)) against the adaptive Monte Carlo's,
    for the trilinear model with its error and for a hybrid with its parameters: within a few
    hundredths of a um on every point (the Monte Carlo's own tolerance at ndig 2 is ~0.005 um)."""
    from ph_explorer.uncertainty.bands import gaussian_band

    scenario, campaign = twin
    model, error = trilinear
    train = ~campaign.holdout_mask()
    hybrid = HybridModel([e for e in scenario.starting_effects if e.candidate], "trilinear").fit(campaign.subset(train))
    for sources in (
        Sources(model, campaign.n_repetitions, dataclasses.replace(error, scale=1.7, calibration_rings=12)),
        Sources(hybrid, campaign.n_repetitions, None, parameter_spread(hybrid, campaign.subset(train))),
    ):
        mc = orientation_band(sources, (52.0, 10.0), rng=np.random.default_rng(5), ndig=2)
        for band in ("touch", "mean"):
            low, high = gaussian_band(sources, (52.0, 10.0), band=band)
            assert np.max(np.abs(low - mc.lower[band])) < 0.03 and np.max(np.abs(high - mc.upper[band])) < 0.03, band
        low, high = gaussian_band(sources, (52.0, 10.0), components=("repeatability",))
        assert np.max(np.abs(high - mc.upper["repeatability"])) < 0.03


def test_the_explorers_band_holds_the_model_error_and_can_leave_it_out(twin):
    """The explorer's dataset: the trilinear model's error is estimated on first use (cross-validated,
    calibrated on the held-out rings); its band is wider with it than the noise-only band; a
    replaced model loses the old model's error."""
    from ph_explorer.app.dataset import dataset_for

    _, campaign = twin
    dataset = dataset_for(campaign, "twin", None)
    assert dataset.errors == {}
    low, high = dataset.band("trilinear", 52.0, 10.0)
    noise_low, noise_high = dataset.band("trilinear", 52.0, 10.0, with_model_error=False)
    # The band of the mean of the repetitions is narrower, and the model's error is a larger share of it.
    mean_low, mean_high = dataset.band("trilinear", 52.0, 10.0, kind="mean")
    mean_noise_low, mean_noise_high = dataset.band("trilinear", 52.0, 10.0, with_model_error=False, kind="mean")
    assert np.all(mean_high - mean_low < high - low)
    assert np.mean(mean_high - mean_low) / np.mean(mean_noise_high - mean_noise_low) > np.mean(high - low) / np.mean(noise_high - noise_low)
    error = dataset.errors["trilinear"]
    assert error.calibration_rings == len(CHECKS) and error.scale > 0
    assert np.all(high - low > noise_high - noise_low)
    refit = dataset.with_model("trilinear", TrilinearModel().fit(campaign, dataset.train_mask))
    assert "trilinear" not in refit.errors and dataset.with_figures({}).errors["trilinear"] is error


def test_the_calibration_is_local_in_a_where_the_check_rings_say_so(tmp_path):
    """Localized conformal calibration: each point's score is the scale it needs; the scale at an A is
    the weighted quantile of the check rings' scores. Rings whose points need 9 times the scale below
    A = 20 deg make the rings choose a finite kernel width and a larger scale there; rings that all
    need the same choose the campaign's scale (inf: the widest of equal choices); every local scale
    rests on at least MIN_CALIBRATION_RINGS rings' worth of weight; the file keeps it all."""
    from ph_explorer.uncertainty.model_error import (
        MIN_CALIBRATION_RINGS,
        calibration_width,
        load_errors,
        local_calibration_weights,
        save_errors,
        weighted_quantile,
    )

    # The weighted quantile: ring 0 (scores 1..4) with weight 3, ring 1 (scores 10..40) with weight 1.
    scores = np.array([[1.0, 2.0, 3.0, 4.0], [10.0, 20.0, 30.0, 40.0]])
    assert weighted_quantile(scores, [[3.0, 1.0]], 0.75).tolist() == [4.0]
    assert weighted_quantile(scores, [[3.0, 1.0]], 0.76).tolist() == [10.0]
    assert weighted_quantile(scores, [[0.0, 1.0]], 0.5).tolist() == [20.0]
    a = np.array([3.0, 6.0, 9.0, 12.0, 15.0, 18.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 90.0])
    weights = local_calibration_weights(a, a, 10.0, leave_out=True)
    assert np.all(np.diag(weights) == 0) and np.allclose(weights.sum(axis=1), 1)
    assert np.all(1.0 / np.sum(weights**2, axis=1) >= MIN_CALIBRATION_RINGS - 1e-9)
    rng = np.random.default_rng(3)
    base = rng.exponential(1.0, (a.size, 64))
    steep = base * np.where(a < 20.0, 9.0, 1.0)[:, None]
    width = calibration_width(a, steep, 0.95, 10.0)
    assert np.isfinite(width)
    error = OutOfSampleError(np.c_[a, np.zeros_like(a)], np.ones((a.size, 33)), 10.0).calibrated(a, steep, 0.95)
    assert error.calibration_width_deg == width and error.calibration_rings == a.size
    near, far = error.scale_at([[8.0, 0.0], [70.0, 0.0]])
    assert near > 4.0 * far and far < error.scale < near
    same = np.tile(base[:1], (a.size, 1))
    assert calibration_width(a, same, 0.95, 10.0) == float("inf")
    flat = OutOfSampleError(np.c_[a, np.zeros_like(a)], np.ones((a.size, 33)), 10.0).calibrated(a, same, 0.95)
    assert np.all(flat.scale_at([[8.0, 0.0], [70.0, 0.0]]) == flat.scale)
    save_errors({"trilinear": error}, tmp_path, 10)
    loaded = load_errors(tmp_path)[0]["trilinear"]
    np.testing.assert_array_equal(loaded.scale_at([[8.0, 0.0], [70.0, 0.0]]), [near, far])
