"""Fitted parameters come with an expanded uncertainty (k = 2, jackknife over rings), and every
effect parameter declares the range of magnitudes a real head can have (issue 13, item 4)."""

from __future__ import annotations

import numpy as np
import pytest

from ph_explorer.effects import BUILTIN_EFFECTS, DEFAULT_CATALOG, Parameter, load_user_effects
from ph_explorer.geometry import DEFAULT_GEOMETRY
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import touch_kinematics
from ph_explorer.models import least_squares
from ph_explorer.paths import assets_dir
from ph_explorer.twin import load_scenario, shipped_scenario_paths
from ph_explorer.uncertainty.jackknife import jackknife_parameters, jackknife_standard_error

SIGMA_UM = 0.175  # the TP20's touch noise
SEEDS = 40
# Units of a magnitude: every parameter in one of them must declare its plausible range.
MAGNITUDE_UNITS = {"um", "arcsec", "um/h"}


def twin_rings():
    """Rings at A0 = 15..90 step 15 and B0 = -160..180 step 40 (the B lever needs A0 > 0), 2 repetitions."""
    a, b = np.meshgrid(np.arange(15.0, 91.0, 15.0), np.arange(-160.0, 181.0, 40.0), indexing="ij")
    return touch_kinematics(np.column_stack([a.ravel(), b.ravel()]), DEFAULT_GEOMETRY, 2, None)


def fits_over_seeds(effect, seeds=range(SEEDS)):
    """The effect's basis through each repetition's circle fit, data = its signal + noise of
    sigma 0.175 um; per seed the full fit's parameters and their jackknife-over-rings U."""
    touches = twin_rings()
    columns, _ = effect.basis(touches)
    # The circle fit acts on the points of each repetition: the column axis moves out of the way.
    columns = np.moveaxis(remove_size_and_centre(np.moveaxis(columns, -1, 0)), 0, -1)
    design = least_squares.Design(columns, None)
    signal = columns @ effect.coefficients()
    rings = np.arange(touches.shape[0])
    out = []
    for seed in seeds:
        noise = remove_size_and_centre(np.random.default_rng(seed).normal(0.0, SIGMA_UM, touches.shape))
        targets = least_squares.Design((signal + noise)[..., None], None)
        coefficients = least_squares.fit(design, targets)[0][:, 0]
        out.append(jackknife_parameters(effect, least_squares.jackknife(design, targets, rings), coefficients))
    return out


def wrapped(difference_deg, period=360.0):
    return (np.asarray(difference_deg) + 0.5 * period) % period - 0.5 * period


# -- (a) the jackknife U is the scatter of the fit ------------------------------------------------------
def test_jackknife_uncertainty_matches_the_scatter_over_noise_seeds_and_covers_the_truth():
    """B-axis 5/rev error of 1 arcsec on 54 twin rings, 40 noise seeds.

    U/2 (the jackknife standard error, averaged over the seeds) against the standard deviation of
    the fitted amplitude over the seeds: the latter, from 40 draws, has a relative standard error
    of 1/sqrt(2 * 39) = 11 %, the average of 40 jackknife errors (54 rings each) about 2 %; 30 % is
    ~2.6 of their combined standard errors. The truth inside +-U: expected ~95 %, asserted at
    >= 85 % (34 of 40; a binomial(40, 0.95) falls below that with probability < 1 %).
    """
    effect = DEFAULT_CATALOG["b_axis_cyclic"](amplitude_arcsec=1.0, phase_deg=40.0, cycles_per_rev=5)
    results = fits_over_seeds(effect)
    amplitude = np.array([p["amplitude_arcsec"] for p, _ in results])
    u_amplitude = np.array([u["amplitude_arcsec"] for _, u in results])
    phase = np.array([p["phase_deg"] for p, _ in results])
    u_phase = np.array([u["phase_deg"] for _, u in results])

    scatter = amplitude.std(ddof=1)
    assert 0.7 < (u_amplitude.mean() / 2.0) / scatter < 1.3
    covered = np.abs(amplitude - 1.0) <= u_amplitude
    assert covered.sum() >= 0.85 * SEEDS
    # The phase too: its scatter (deg) and its coverage.
    phase_scatter = wrapped(phase - 40.0).std(ddof=1)
    assert 0.7 < (u_phase.mean() / 2.0) / phase_scatter < 1.4
    assert (np.abs(wrapped(phase - 40.0)) <= u_phase).sum() >= 0.85 * SEEDS
    # The scanned order is a chosen setting, not fitted: no uncertainty.
    assert all(u["cycles_per_rev"] == 0.0 and p["cycles_per_rev"] == 5.0 for p, u in results)


# -- (b) a phase wraps ---------------------------------------------------------------------------------
def test_a_phase_near_zero_has_a_small_uncertainty_not_half_a_turn():
    effect = DEFAULT_CATALOG["b_axis_cyclic"](amplitude_arcsec=0.5, phase_deg=1.0, cycles_per_rev=5)
    results = fits_over_seeds(effect, seeds=range(8))
    phases = np.array([p["phase_deg"] for p, _ in results])
    assert (phases > 300.0).any() and (phases < 60.0).any()  # the fits do fall on both sides of 0/360
    for params, u in results:
        assert 0.0 < u["phase_deg"] < 25.0  # ~10 deg (2 x 0.044 / 0.5 rad), never ~180
        assert abs(wrapped(params["phase_deg"] - 1.0)) <= 2.0 * u["phase_deg"]


def test_the_wrap_is_centred_on_the_full_fit_and_follows_the_declared_period():
    cyclic = DEFAULT_CATALOG["b_axis_cyclic"](cycles_per_rev=3)
    offsets = np.array([-2.0, -1.0, 0.0, 1.0, 2.0, 1.5])

    def rows(centre_deg):
        phase = np.radians(centre_deg + offsets)
        return np.column_stack([np.cos(phase), np.sin(phase)])  # amplitude 1, sin(m x + phase)

    expected = 2.0 * jackknife_standard_error(offsets)
    for centre in (0.0, 359.5, 180.0):
        params, u = jackknife_parameters(cyclic, rows(centre), rows(centre)[2])
        assert params["phase_deg"] == pytest.approx(centre % 360.0)
        assert u["phase_deg"] == pytest.approx(expected)
        assert u["amplitude_arcsec"] == pytest.approx(0.0, abs=1e-12)
    # Three seats repeat every 120 deg: a seat phase fitted near 0/120 wraps there.
    lobing = DEFAULT_CATALOG["lobing"]()
    seats = np.array([119.0, 119.5, 0.2, 0.6, 1.0])
    rows_lobing = np.stack([DEFAULT_CATALOG["lobing"](amplitude_um=0.2, seat_phase_deg=s).coefficients() for s in seats])
    _, u = jackknife_parameters(lobing, rows_lobing, rows_lobing[2])
    assert u["seat_phase_deg"] == pytest.approx(2.0 * jackknife_standard_error(wrapped(seats - 0.2, 120.0)), rel=1e-6)
    assert u["seat_phase_deg"] < 3.0


def test_jackknife_of_too_few_groups_is_unknown_and_shapes_are_checked():
    cyclic = DEFAULT_CATALOG["a_axis_cyclic"]()
    params, u = jackknife_parameters(cyclic, np.array([[1.0, 0.0]]), np.array([1.0, 0.0]))
    assert params["amplitude_arcsec"] == 1.0 and np.isnan(u["amplitude_arcsec"])
    with pytest.raises(ValueError):
        jackknife_parameters(cyclic, np.array([1.0, 0.0]), np.array([1.0, 0.0]))


# -- (c) implausible fits are named ----------------------------------------------------------------------
def test_implausible_names_a_value_outside_its_range_with_the_range():
    cls = DEFAULT_CATALOG["b_axis_cyclic"]
    lines = cls.implausible({"amplitude_arcsec": 15.0, "phase_deg": 30.0, "cycles_per_rev": 2.0})
    assert lines == ["amplitude 15 arcsec, plausible 0-3 arcsec"]
    assert cls.implausible({"amplitude_arcsec": 1.0, "phase_deg": 400.0, "cycles_per_rev": 2.0}) == []
    # A signed parameter is judged by its magnitude; derived outputs that are no parameter are not judged.
    drift = DEFAULT_CATALOG["drift"].implausible({"head_step_um": -1210.0, "stylus_rate_um_per_h": 0.5})
    assert drift == ["head step -1.21e+03 um, plausible magnitude 0-5 um"]
    assert DEFAULT_CATALOG["lobing"].implausible({"amplitude_um": 0.2, "ratio_6_to_3": 40.0}) == []
    assert DEFAULT_CATALOG["lobing"].implausible({"amplitude_um": float("nan")}) != []


def test_a_parameter_declares_its_range_and_period_by_keyword_and_old_calls_still_work():
    old = Parameter("amplitude_um", "um", 0.1, "extra pre-travel")
    assert old.plausible is None and old.period is None and old.admits(1e6)
    new = Parameter("amplitude_um", "um", 0.1, "extra pre-travel", plausible=(0, 0.3))
    assert new.plausible == (0.0, 0.3) and new.admits(-0.2) and not new.admits(0.31) and new.range_text() == "0-0.3 um"
    for bad in ({"plausible": (0.5, 0.1)}, {"plausible": (-1.0, 1.0)}, {"period": 0.0}):
        with pytest.raises(ValueError):
            Parameter("x", "um", 0.0, "x", **bad)


# -- (d) every magnitude has a range, and the shipped scenarios lie inside them ------------------------
def example_effects():
    return load_user_effects(assets_dir() / "effects_example.py")


@pytest.mark.parametrize("cls", [*BUILTIN_EFFECTS, *example_effects()], ids=lambda cls: cls.id)
def test_every_magnitude_declares_a_plausible_range_and_every_phase_a_period(cls):
    for p in cls.parameters:
        if p.unit in MAGNITUDE_UNITS:
            assert p.plausible is not None and p.plausible[0] == 0.0 and p.plausible[1] > 0.0, (cls.id, p.name)
        if "phase" in p.name:
            assert p.period is not None and p.plausible is None, (cls.id, p.name)
        if p.name in cls.scan:
            assert p.plausible is None, (cls.id, p.name)
    assert cls.implausible(cls().params) == [], cls.id  # the defaults are plausible


@pytest.mark.parametrize("path", shipped_scenario_paths(), ids=lambda path: path.stem)
def test_the_shipped_scenarios_are_plausible(path):
    """A scenario the tool would call implausible would be a bug (head_5's 1.6 arcsec
    lost motion, a worn drive, included)."""
    scenario = load_scenario(path)
    for effect in scenario.effects:
        assert effect.implausible(effect.params) == [], (scenario.name, effect)
