"""The Gaussian-process data part (models.gaussian_process): scikit-learn's regressor on the head's
feature map, linear in its curves once its kernel is fixed, its own out-of-sample weights, its
files without pickle, and a hybrid that fits physical terms beside it."""

from __future__ import annotations

import dataclasses
import zipfile

import numpy as np
import pytest
from synthetic import lobing_campaign, scenario_with

from ph_explorer.campaign import Campaign
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.geometry import point_angles_deg
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.models.crossval import cross_val_predict, out_of_sample_weights
from ph_explorer.models.folder import MODEL_TYPES, model_class
from ph_explorer.models.gaussian_process import GaussianProcessModel, features
from ph_explorer.models.hybrid import HybridModel
from ph_explorer.twin import simulate


@pytest.fixture(scope="module")
def campaign() -> Campaign:
    return lobing_campaign(seed=2)


@pytest.fixture(scope="module")
def fitted(campaign) -> GaussianProcessModel:
    return GaussianProcessModel().fit(campaign, ~campaign.holdout_mask())


def test_the_feature_map_is_the_axis_angles_and_keeps_the_probes_turn_at_a_zero() -> None:
    """The features are (A in radians, cos B, sin B): at A = 0 the stylus points one way at every B,
    but the probe is turned, so curves turned with the probe are not forced equal; B = -180 is B = 180."""
    x = features([[0.0, 0.0], [0.0, 90.0], [0.0, -180.0], [0.0, 180.0], [90.0, 0.0]])
    assert not np.allclose(x[0], x[1]) and np.allclose(x[2], x[3])
    assert np.allclose(x[0], [0, 1, 0]) and np.allclose(x[1], [0, 0, 1]) and np.allclose(x[4], [np.pi / 2, 1, 0])


def test_with_its_kernel_fixed_it_is_linear_in_the_curves_it_learns(campaign, fitted) -> None:
    train = ~campaign.holdout_mask()
    factory = fitted.linear_smoother(campaign, train)
    rng = np.random.default_rng(0)
    one, two = (dataclasses.replace(campaign, deviations=rng.normal(size=campaign.deviations.shape)) for _ in range(2))
    both = dataclasses.replace(campaign, deviations=one.deviations + 2.0 * two.deviations)
    at = np.array([[43.0, 90.0], [7.5, -170.0], [0.0, 33.0]])
    predicted = [factory().fit(c, train).interpolate(at) for c in (one, two, both)]
    assert np.allclose(predicted[2], predicted[0] + 2.0 * predicted[1], atol=1e-10)


def test_its_out_of_sample_weights_are_its_leave_one_ring_out_predictions(campaign, fitted) -> None:
    """W from unit vectors (crossval.out_of_sample_weights) predicts each training ring from the
    others and each check ring from every training ring, as the GP refitted without the ring does."""
    train = ~campaign.holdout_mask()
    factory = fitted.linear_smoother(campaign, train)
    weights = out_of_sample_weights(campaign.orientations, train, factory)
    assert np.allclose(np.diag(weights)[train], 0.0) and np.allclose(weights[:, ~train], 0.0)
    direct = cross_val_predict(factory, campaign, train)
    assert np.allclose(weights @ campaign.deviations.mean(axis=1), direct, atol=1e-9)


def test_it_learns_a_lobing_that_turns_with_the_probe_at_a_zero() -> None:
    """A 3-lobe pattern carried by the probe turns with B at every A, A = 0 included: the GP
    predicts it at B values it never saw, where a map collapsing A = 0 to one point could not."""
    a, b = np.meshgrid([0.0, 15, 30, 45, 60, 75, 90], np.arange(-180.0, 180.0, 20.0), indexing="ij")
    lattice = np.column_stack([a.ravel(), b.ravel()])
    unseen = np.array([[0.0, 10.0], [0.0, -130.0], [52.5, 75.0]])
    orientations = np.vstack([lattice, unseen])
    theta = np.radians(point_angles_deg(64))[None, :]
    curves = remove_size_and_centre(0.4 * np.cos(3 * (theta - np.radians(orientations[:, 1:]))))
    rng = np.random.default_rng(1)
    deviations = curves[:, None, :] + 0.02 * rng.standard_normal((len(orientations), 4, 64))
    model = GaussianProcessModel().fit(Campaign(orientations, deviations, check_orientations=unseen), np.arange(len(lattice)))
    error = np.abs(model.predict(unseen) - curves[-3:]).mean(axis=1)
    assert (error < 0.1 * 0.4 * 2 / np.pi).all(), error  # within a tenth of the pattern's mean size


def test_the_same_data_learns_its_kernel_once(campaign, fitted, monkeypatch) -> None:
    """A diagnosis fits its baseline and every step on the same rings: the likelihood is maximised
    once for them, and other data gets a kernel of its own."""
    from sklearn.gaussian_process import GaussianProcessRegressor

    from ph_explorer.models import gaussian_process

    learnt = []
    fit = GaussianProcessRegressor.fit

    def counted(self, x, y):
        learnt.append(self.optimizer is not None)
        return fit(self, x, y)

    monkeypatch.setattr(GaussianProcessRegressor, "fit", counted)
    train = ~campaign.holdout_mask()
    again = GaussianProcessModel().fit(campaign, train)
    assert not any(learnt) and np.array_equal(again.theta, fitted.theta)  # read back, not learnt
    other = dataclasses.replace(campaign, deviations=campaign.deviations * 1.5)
    GaussianProcessModel().fit(other, train)
    assert learnt.count(True) == 1 and len(gaussian_process._THETAS) <= gaussian_process.THETAS_KEPT


def test_its_files_hold_no_pickle_and_give_the_same_curves_and_variance(fitted, tmp_path) -> None:
    path = fitted.save(tmp_path)
    with zipfile.ZipFile(path) as archive:
        names = sorted(archive.namelist())
    assert names == ["n_repetitions.npy", "sigma_curve.npy", "theta.npy", "train_curves.npy", "train_features.npy"]
    again = GaussianProcessModel.load(tmp_path)  # np.load(allow_pickle=False): refitted from the data
    at = np.array([[43.0, 90.0], [7.5, -170.0]])
    assert np.allclose(again.predict(at), fitted.predict(at), atol=1e-12)
    assert np.allclose(again.variance(at), fitted.variance(at), atol=1e-15)
    assert np.allclose(again.predict(at, n_points=32), fitted.predict(at, n_points=32), atol=1e-12)
    assert "gp" in MODEL_TYPES and model_class("gp") is GaussianProcessModel
    # A file of another feature map (the five features before 2026-11-28) is refused, by name, not misread.
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    np.savez(path, **{**arrays, "train_features": np.zeros((len(arrays["train_curves"]), 5))})
    with pytest.raises(ValueError, match=r"gp\.npz: a GP of an earlier feature map \(5 features, not 3\)"):
        GaussianProcessModel.load(tmp_path)


def test_its_variance_grows_away_from_the_rings(campaign, fitted) -> None:
    """The variance of the model's error is smallest at a training ring and grows between rings."""
    train = np.flatnonzero(~campaign.holdout_mask())
    at_rings = fitted.variance(campaign.orientations[train])
    between = fitted.variance(campaign.orientations[train] + [[3.75, 5.0]])
    assert at_rings.shape == (train.size, 64) and (at_rings >= 0).all()
    assert (between.mean(axis=1) > at_rings.mean(axis=1)).mean() > 0.9


def test_a_hybrid_with_a_gp_part_finds_a_b_axis_error_beside_it() -> None:
    """The paper's rings with a B 2/rev error of 1.8 arcsec (and the ring's form, the touch noise):
    the hybrid's physical fit, through the GP's own out-of-sample weights, recovers its amplitude."""
    b_axis = DEFAULT_CATALOG["b_axis_cyclic"]
    campaign = simulate(scenario_with(b_axis(amplitude_arcsec=1.8, phase_deg=40.0, cycles_per_rev=2)), 3)
    hybrid = HybridModel([b_axis(cycles_per_rev=2)], "gp").fit(campaign, ~campaign.holdout_mask())
    assert hybrid.data_part.name == "gp" and hybrid.smoother_.model_name == "gp"
    (fitted,) = hybrid.effect_parameters()
    assert fitted["params"]["amplitude_arcsec"] == pytest.approx(1.8, rel=0.1)


def test_diagnose_takes_the_gp_as_its_data_part_and_saves_it_in_the_study(campaign, tmp_path) -> None:
    """`diagnose --data-part gp`: the baseline and every step's hybrid learn their data part with the
    GP, and the study file records it."""
    import json

    from command_line import run_cli

    from ph_explorer.io.writer import write_campaign

    path = write_campaign(campaign, tmp_path / "lobing.csv")
    study = tmp_path / "study.json"
    done = run_cli("diagnose", "--data", path, "--data-part", "gp", "--add", "lobing", "--json", "--save", study)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    assert report["baseline"]["model"] == "gp" and report["steps"][1]["model"] == "hybrid, gp data part"
    assert report["steps"][1]["added"] == ["lobing"] and json.loads(study.read_text())["data_part"] == "gp"


def test_its_own_error_is_its_posterior_spread_as_white_noise_and_calibrated_as_any(campaign, fitted) -> None:
    """The band's model component of a GP is its posterior variance (no cross-validation): over the
    harmonics 2..N/2 it adds up to the per-point variance, and the held-out rings scale it as they
    scale the cross-validation's error of any other model."""
    from ph_explorer.uncertainty.bands import Sources, band_variance, calibrate_model_error
    from ph_explorer.uncertainty.model_error import PosteriorError, own_error, white_power

    power = white_power(np.array([2.0, 0.5]), 64)
    assert np.allclose(power.sum(axis=1), [2.0, 0.5]) and np.allclose(power[:, :2], 0.0)
    train = ~campaign.holdout_mask()
    error = own_error(GaussianProcessModel, fitted, campaign, train)
    assert isinstance(error, PosteriorError) and error.n_points == 64
    at = np.array([[43.0, 90.0], [7.5, -170.0]])
    assert np.allclose(error.variance(at).sum(axis=1), fitted.variance(at).mean(axis=1))
    sources = Sources(fitted, campaign.n_repetitions, error)
    without = band_variance(sources, at, 64, "mean", ("repeatability",))
    assert np.allclose(band_variance(sources, at, 64, "mean") - without, fitted.variance(at).mean(axis=1)[:, None])
    rings = np.arange(6)  # any six rings will do to calibrate on: the scale's mechanism is tested here
    far_off = campaign.mean_curves()[rings] + remove_size_and_centre(0.5 * np.cos(3 * np.radians(point_angles_deg(64))))
    calibrated = calibrate_model_error(sources, campaign.orientations[rings], far_off)
    assert calibrated.error.calibration_rings == rings.size and calibrated.error.scale > 1.0
