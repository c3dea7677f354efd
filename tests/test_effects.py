"""Each effect of the catalog shows its physics: its signature in the deviations, not its code."""

from __future__ import annotations

import numpy as np
import pytest

from ph_explorer.effects import BUILTIN_EFFECTS, DEFAULT_CATALOG, EffectSum, load_user_effects
from ph_explorer.effects.effect import AXES, KINDS, RAD_PER_ARCSEC, Effect
from ph_explorer.effects.probe import support_fourier
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY
from ph_explorer.harmonics import harmonic_spectrum, remove_size_and_centre
from ph_explorer.kinematics import touch_kinematics
from ph_explorer.paths import assets_dir

L_MM = DEFAULT_GEOMETRY.pivot_to_ball_mm
UM_PER_ARCSEC_AT_L = L_MM * 1000.0 * RAD_PER_ARCSEC  # 0.388 um: 1 arcsec at 80 mm
B_SAMPLE = np.arange(-160.0, 181.0, 40.0)


def grid(a_values, b_values=B_SAMPLE):
    return np.array([[a, b] for a in a_values for b in b_values], dtype=float)


def touches_at(orientations, n_rep=1, times=None):
    return touch_kinematics(orientations, DEFAULT_GEOMETRY, n_rep, times)


def after_fit(effect: Effect, touches, seed: int = 0):
    return remove_size_and_centre(effect.forward(touches, np.random.default_rng(seed)))


def test_catalog_has_the_issue_ids_with_documented_parameters():
    need = {"noise", "lobing", "gravity", "a_axis_cyclic", "b_axis_cyclic", "direction", "drift", "ring_form"}
    assert need <= set(DEFAULT_CATALOG)
    for cls in BUILTIN_EFFECTS:
        assert DEFAULT_CATALOG[cls.id] is cls and cls.name and len(cls.teaching) > 150
        for p in cls.parameters:
            assert p.unit is not None and p.description
        for key in cls.scan:
            assert key in {p.name for p in cls.parameters}
        # Described in the ISO 230 vocabulary: where it sits and what kind of error it is.
        assert cls.axis in (*AXES, None) and cls.kind in KINDS, cls.id
    # Only pure noise is no candidate: every other effect is something a model can add.
    assert set(DEFAULT_CATALOG) - set(DEFAULT_CATALOG.candidates()) == {"noise"}


def test_effects_describe_what_they_need_and_how_their_evidence_is_read(mixed_touches):
    drift = DEFAULT_CATALOG["drift"]()
    no_times = touches_at(grid([30.0]))
    assert drift.unmet_needs(mixed_touches) == [] and drift.unmet_needs(no_times) == ["needs touch times (a t_s column)"]
    for cls in BUILTIN_EFFECTS:
        evidence = cls().evidence(mixed_touches)
        assert evidence.x_label and np.broadcast_to(evidence.x, mixed_touches.shape).shape == mixed_touches.shape
    # An axis error is read as an angle against its own phase, weighted by each touch's lever.
    cyclic = DEFAULT_CATALOG["b_axis_cyclic"](cycles_per_rev=22).evidence(mixed_touches)
    assert "arcsec" in cyclic.y_label and cyclic.weight is not None and np.ptp(cyclic.edges) == 360.0


def test_scanned_values_are_settings_of_the_instance():
    cls = DEFAULT_CATALOG["drift"]
    grid_values = cls.scan_grid()
    assert len(grid_values) == len(cls.scan["tau_s"]) * len(cls.scan["cycle_period_s"])
    effect = DEFAULT_CATALOG["b_axis_cyclic"](amplitude_arcsec=0.5).with_settings(cycles_per_rev=22)
    assert effect.settings() == {"cycles_per_rev": 22.0} and effect.params["amplitude_arcsec"] == 0.5
    assert (
        DEFAULT_CATALOG["b_axis_cyclic"].parameters_text({"amplitude_arcsec": 0.953, "phase_deg": 30.8, "cycles_per_rev": 22})
        == "amplitude 0.953 arcsec, phase 30.8 deg, 22 cycles/rev"
    )


def test_effects_add_like_lmfit_models(mixed_touches):
    lobing, cyclic = DEFAULT_CATALOG["lobing"](), DEFAULT_CATALOG["b_axis_cyclic"](cycles_per_rev=5)
    both = lobing + cyclic
    assert isinstance(both, EffectSum) and [e.id for e in both + DEFAULT_CATALOG["noise"]()] == ["lobing", "b_axis_cyclic", "noise"]
    np.testing.assert_allclose(both.forward(mixed_touches, None), lobing.forward(mixed_touches, None) + cyclic.forward(mixed_touches, None))


# -- lobing -----------------------------------------------------------------------------------------
def test_lobing_largest_harmonic_is_3_upr_at_high_a0_and_nothing_at_a0_zero():
    lobing = DEFAULT_CATALOG["lobing"](amplitude_um=0.25, seat_phase_deg=10.0)
    t = touches_at(grid([0.0, 60.0, 90.0]))
    d = after_fit(lobing, t)[:, 0]  # (n_o, n_pt)
    amp, _ = harmonic_spectrum(d)
    n_b = len(B_SAMPLE)
    # A0 = 0: the probe turns with the point, psi is constant, so the lobing is a pure size change.
    assert np.abs(d[:n_b]).max() < 1e-12
    high = amp[n_b:]
    assert np.all(high.argmax(axis=-1) == 3)
    # Near A0 = 90 psi sweeps the ring almost uniformly: the 3-UPR amplitude is the parameter
    # (times the lateral share sin(beta) = cos(6.5 deg)).
    assert np.allclose(amp[2 * n_b :, 3], 0.25 * np.cos(np.radians(6.46)), rtol=0.05)
    # and 6 UPR follows the support function's ratio 0.23.
    assert np.allclose(amp[2 * n_b :, 6] / amp[2 * n_b :, 3], abs(support_fourier(6) / support_fourier(3)), rtol=0.1)


def test_lobing_is_the_same_at_every_b0_and_shows_side_bands_at_mid_a0():
    lobing = DEFAULT_CATALOG["lobing"](amplitude_um=0.25)
    d = after_fit(lobing, touches_at(grid([30.0])))[:, 0]
    assert np.abs(d - d[0]).max() < 1e-9  # the probe-frame picture only depends on A0
    amp, _ = harmonic_spectrum(d[0])
    assert amp[3] == amp.max()
    assert amp[2] > 0.05 * amp[3] and amp[4] > 0.05 * amp[3]  # psi sweeps unevenly: side-bands


def test_lobing_basis_fit_recovers_amplitude_and_seat_phase():
    truth = DEFAULT_CATALOG["lobing"](amplitude_um=0.3, seat_phase_deg=37.0)
    t = touches_at(grid([30.0, 60.0, 90.0]))
    y = truth.forward(t, np.random.default_rng(0)).ravel()
    cols, names = truth.basis(t)
    assert cols.shape == t.shape + (8,) and len(names) == 8
    coef, *_ = np.linalg.lstsq(cols.reshape(-1, 8), y, rcond=None)
    found = truth.from_coefficients(coef)
    assert found["amplitude_um"] == pytest.approx(0.3, rel=0.02)
    assert found["seat_phase_deg"] == pytest.approx(37.0, abs=0.5)


# -- gravity ----------------------------------------------------------------------------------------
def test_gravity_lobing_grows_with_sin_a_and_its_directional_part_is_one_fold():
    t = touches_at(grid([15.0, 30.0, 45.0, 60.0, 75.0, 90.0], [0.0]))
    lobes = after_fit(DEFAULT_CATALOG["gravity"](directional_um=0.0, lobing_um=0.2), t)[:, 0]
    amp3 = harmonic_spectrum(lobes)[0][:, 3]
    sin_a = np.sin(np.radians([15.0, 30.0, 45.0, 60.0, 75.0, 90.0]))
    assert np.all(np.diff(amp3) > 0)
    # Relative to its value at A0 = 90 the 3-UPR term follows sin A0 (A_k ~ A0 +- 6.5 deg).
    assert np.allclose(amp3[1:] / amp3[-1], sin_a[1:], rtol=0.08)
    directional = after_fit(DEFAULT_CATALOG["gravity"](directional_um=0.5, lobing_um=0.0), t)
    before = DEFAULT_CATALOG["gravity"](directional_um=0.5, lobing_um=0.0).forward(t, None)
    assert np.ptp(before, axis=-1).max() > 0.3  # it does move the touches...
    assert np.abs(directional).max() < 1e-9  # ...but only as size and centre in head touches


# -- rotary axes ------------------------------------------------------------------------------------
@pytest.mark.parametrize("cycles", [1, 3, 22])
def test_b_axis_cyclic_leaves_nothing_at_a0_zero(cycles):
    effect = DEFAULT_CATALOG["b_axis_cyclic"](amplitude_arcsec=2.0, cycles_per_rev=cycles, phase_deg=25.0)
    before = effect.forward(touches_at(grid([0.0])), None)
    assert np.abs(before).max() < 1e-12  # a turn about z moves the ball along the ring, not across it


def test_b_axis_cyclic_grows_with_sin_a0():
    a0 = np.array([15.0, 30.0, 45.0, 60.0, 75.0, 90.0])
    # 1/rev with its peak at B0 = 0: eps ~ 1 arcsec over every ring's small B sweep.
    effect = DEFAULT_CATALOG["b_axis_cyclic"](amplitude_arcsec=1.0, cycles_per_rev=1, phase_deg=90.0)
    before = effect.forward(touches_at(grid(a0[1:], [0.0])), None)[:, 0]
    one_upr = harmonic_spectrum(before)[0][:, 1]
    lever = UM_PER_ARCSEC_AT_L * DEFAULT_GEOMETRY.axial_distance_mm / L_MM * np.sin(np.radians(a0[1:]))
    assert np.allclose(one_upr, lever, rtol=0.04)
    # A short-period error (16.4 deg) shows after the fit too. Where each ring's B sweep covers more
    # than one period (A0 >= 45), its rms over B0 follows sin A0; at A0 = 15 it is less than half.
    short = DEFAULT_CATALOG["b_axis_cyclic"](amplitude_arcsec=1.0, cycles_per_rev=22)
    rms = np.array([np.sqrt(np.mean(after_fit(short, touches_at(grid([a], np.arange(-180.0, 180.0, 5.0)))) ** 2)) for a in a0])
    per_sin = rms[2:] / np.sin(np.radians(a0[2:]))
    assert np.ptp(per_sin) < 0.12 * per_sin.mean()
    assert rms[0] < 0.5 * rms[-1] and rms[-1] > 0.08


def test_a_axis_cyclic_moves_the_tip_by_the_full_lever():
    # eps peaks at each ring's A0 (phase 90 - A0 for 1/rev): the radial deviation reaches ~ eps L.
    for a0 in (0.0, 45.0, 90.0):
        effect = DEFAULT_CATALOG["a_axis_cyclic"](amplitude_arcsec=1.0, cycles_per_rev=1, phase_deg=90.0 - a0)
        before = effect.forward(touches_at(grid([a0], [-120.0, 10.0, 100.0])), None)
        assert np.abs(before).max() == pytest.approx(UM_PER_ARCSEC_AT_L, rel=0.03)
    # A short-period A error shows after the fit at A0 > 0, and not at A0 = 0 where A stays fixed.
    short = DEFAULT_CATALOG["a_axis_cyclic"](amplitude_arcsec=1.0, cycles_per_rev=24)
    assert np.abs(after_fit(short, touches_at(grid([0.0])))).max() < 1e-9
    assert np.ptp(after_fit(short, touches_at(grid([45.0]))), axis=-1).min() > 0.15


def test_cyclic_basis_takes_cycles_per_rev_and_recovers_parameters():
    truth = DEFAULT_CATALOG["b_axis_cyclic"](amplitude_arcsec=0.8, cycles_per_rev=22, phase_deg=200.0)
    t = touches_at(grid([15.0, 45.0, 75.0], np.arange(-180.0, 180.0, 10.0)))
    y = truth.forward(t, None).ravel()
    residual = {}
    for m in (20, 21, 22, 23):
        cols, names = truth.with_settings(cycles_per_rev=m).basis(t)
        coef, *_ = np.linalg.lstsq(cols.reshape(-1, 2), y, rcond=None)
        residual[m] = np.linalg.norm(y - cols.reshape(-1, 2) @ coef)
        if m == 22:
            found = truth.with_settings(cycles_per_rev=m).from_coefficients(coef)
    assert min(residual, key=residual.get) == 22 and residual[22] < 1e-9
    assert found == pytest.approx({"amplitude_arcsec": 0.8, "phase_deg": 200.0, "cycles_per_rev": 22.0})


# -- direction ------------------------------------------------------------------------------------
def scan_times(orientations, n_rep, alternating):
    n_o, n_pt = len(orientations), DEFAULT_GEOMETRY.points_per_circle
    o, r, k = np.indices((n_o, n_rep, n_pt))
    position = np.where(alternating & (r % 2 == 1), n_pt - 1 - k, k)
    return ((o * n_rep + r) * n_pt + position) * 2.0


def test_direction_shows_only_when_the_scan_order_changes_between_repetitions():
    o = grid([30.0, 60.0, 90.0])
    effect = DEFAULT_CATALOG["direction"](a_lost_motion_arcsec=1.0, b_lost_motion_arcsec=1.0)
    same = after_fit(effect, touches_at(o, 4, scan_times(o, 4, False)))
    alternating = after_fit(effect, touches_at(o, 4, scan_times(o, 4, True)))
    assert np.abs(same - same[:, :1]).max() < 1e-12  # a fixed part of every repetition's curve
    assert np.ptp(same, axis=-1).min() > 0.1
    # Alternating: reversed repetitions approach every point from the other side.
    flip = alternating[:, 1] - alternating[:, 0]
    assert np.sqrt(np.mean(flip**2)) > 0.1
    assert np.abs(alternating[:, 2] - alternating[:, 0]).max() < 1e-12


# -- drift ----------------------------------------------------------------------------------------
def test_drift_shows_only_with_time_changing_within_a_circle():
    o = grid([45.0, 90.0])
    n_rep, n_pt = 3, DEFAULT_GEOMETRY.points_per_circle
    effect = DEFAULT_CATALOG["drift"](head_rate_um_per_h=30.0, stylus_rate_um_per_h=20.0, head_cycle_um=1.0)
    circle = np.arange(len(o) * n_rep).reshape(len(o), n_rep, 1) * 200.0
    frozen = np.broadcast_to(circle, (len(o), n_rep, n_pt)).copy()  # every touch of a circle at one time
    moving = circle + 2.0 * np.arange(n_pt)
    assert np.abs(after_fit(effect, touches_at(o, n_rep, frozen))).max() < 1e-10
    assert np.ptp(after_fit(effect, touches_at(o, n_rep, moving)), axis=-1).min() > 0.05
    with pytest.raises(InputError, match="t_s"):
        effect.forward(touches_at(o, n_rep, None), None)


def test_drift_of_the_stylus_is_seen_through_rho_over_l():
    o = grid([0.0], [0.0])
    n_pt = DEFAULT_GEOMETRY.points_per_circle
    times = (np.arange(n_pt) * 3600.0 / n_pt).reshape(1, 1, n_pt)  # one hour over the circle
    d = DEFAULT_CATALOG["drift"](stylus_rate_um_per_h=1.0).forward(touches_at(o, 1, times), None)
    rho_over_l = DEFAULT_GEOMETRY.contact_radius_mm / L_MM
    assert np.ptp(d) == pytest.approx(rho_over_l * (n_pt - 1) / n_pt, rel=1e-9)


def test_a_scan_library_holds_every_settings_basis_columns():
    """An effect's scan_library is its basis at every scan_grid() setting, gathered from distinct
    columns (the diagnosis's scan makes each once): checked for every catalog effect that has one."""
    o = grid([0.0, 45.0, 90.0])
    n_rep, n_pt = 2, DEFAULT_GEOMETRY.points_per_circle
    times = np.arange(len(o) * n_rep * n_pt, dtype=float).reshape(len(o), n_rep, n_pt) * 7.0
    touches = touches_at(o, n_rep, times)
    with_library = 0
    for cls in BUILTIN_EFFECTS:
        effect = cls()
        library = effect.scan_library(touches)
        if library is None:
            continue
        with_library += 1
        columns, indices = library
        grid_settings = effect.scan_grid()
        assert len(indices) == len(grid_settings) and columns.shape[-1] < sum(len(i) for i in indices)
        for settings, index in zip(grid_settings, indices):
            own = effect.with_settings(**settings).basis(touches)[0]
            assert np.array_equal(columns[..., index], own), (cls.id, settings)
    assert with_library >= 1  # drift's 36 settings share a ramp, a warm-up per tau and a cycle per period


# -- ring form ------------------------------------------------------------------------------------
def test_ring_form_is_identical_at_every_orientation():
    form = DEFAULT_CATALOG["ring_form"](form_um=0.2, shape_seed=3)
    d = after_fit(form, touches_at(grid([0.0, 15.0, 45.0, 90.0]), n_rep=2))
    assert np.abs(d - d[:1, :1]).max() < 1e-12
    assert np.ptp(d[0, 0]) == pytest.approx(0.2, rel=0.1)
    amp, _ = harmonic_spectrum(d[0, 0])
    assert amp[:2].max() < 1e-12 and amp[16:].max() < 1e-12 and amp[2:16].min() > 0


# -- noise ----------------------------------------------------------------------------------------
def test_noise_alone_reproduces_the_noise_floor_figures():
    sigma = 0.175
    t = touches_at(grid([0.0, 30.0, 60.0, 90.0], np.arange(-160.0, 181.0, 20.0)), n_rep=10)
    d = after_fit(DEFAULT_CATALOG["noise"](sigma_um=sigma), t, seed=11)  # (72, 10, 64)
    assert np.mean(np.ptp(d, axis=-1)) / sigma == pytest.approx(4.69, rel=0.1)
    assert np.mean(np.abs(d).max(axis=-1)) / sigma == pytest.approx(2.60, rel=0.1)
    assert np.mean(np.abs(d)) / sigma == pytest.approx(0.80, rel=0.1)
    assert np.mean(np.abs(d)) == pytest.approx(0.14, rel=0.1)  # single-repetition floor, um
    assert np.mean(np.abs(d.mean(axis=1))) == pytest.approx(0.044, rel=0.1)  # 10-repetition floor
    assert np.sqrt(np.mean(d.var(axis=1, ddof=1))) == pytest.approx(sigma, rel=0.05)


# -- linear bases ---------------------------------------------------------------------------------
EXAMPLES = {
    "a_axis_cyclic": dict(amplitude_arcsec=1.2, phase_deg=70.0, cycles_per_rev=4),
    "b_axis_cyclic": dict(amplitude_arcsec=0.9, phase_deg=250.0, cycles_per_rev=22),
    "direction": dict(a_lost_motion_arcsec=0.7, b_lost_motion_arcsec=1.1),
    "drift": dict(stylus_rate_um_per_h=2.0, head_step_um=3.0, head_cycle_um=0.5, cycle_phase_deg=40.0, tau_s=600.0),
    "ring_form": dict(form_um=0.25, shape_seed=5),
    "lobing": dict(amplitude_um=0.2, seat_phase_deg=15.0),
    "gravity": dict(directional_um=0.1, lobing_um=0.15, seat_phase_deg=15.0),
}


@pytest.fixture(scope="module")
def mixed_touches():
    o = grid([0.0, 15.0, 45.0, 75.0])
    return touches_at(o, 2, scan_times(o, 2, True) + 100.0)


@pytest.mark.parametrize("effect_id", ["a_axis_cyclic", "b_axis_cyclic", "direction", "drift", "ring_form"])
def test_basis_reproduces_forward_for_the_linear_effects(effect_id, mixed_touches):
    effect = DEFAULT_CATALOG[effect_id](**EXAMPLES[effect_id])
    cols, names = effect.basis(mixed_touches)
    assert cols.shape == mixed_touches.shape + (len(names),)
    np.testing.assert_allclose(cols @ effect.coefficients(), effect.forward(mixed_touches, None), atol=1e-12)
    found = effect.from_coefficients(effect.coefficients())
    for key, value in EXAMPLES[effect_id].items():
        if key in found:
            assert found[key] == pytest.approx(value, abs=1e-9), key


@pytest.mark.parametrize("effect_id", ["lobing", "gravity"])
def test_seat_bases_reproduce_forward_up_to_harmonic_12(effect_id, mixed_touches):
    effect = DEFAULT_CATALOG[effect_id](**EXAMPLES[effect_id])
    cols, _ = effect.basis(mixed_touches)
    forward = remove_size_and_centre(effect.forward(mixed_touches, None))
    linear = remove_size_and_centre(cols @ effect.coefficients())
    # The support function's harmonics above 12 (4 % of the 3-UPR term and falling) are left out.
    assert np.sqrt(np.mean((forward - linear) ** 2)) < 0.06 * np.sqrt(np.mean(forward**2))
    found = effect.from_coefficients(effect.coefficients())
    assert found["seat_phase_deg"] == pytest.approx(15.0)


def test_noise_has_no_basis_columns(mixed_touches):
    cols, names = DEFAULT_CATALOG["noise"]().basis(mixed_touches)
    assert cols.shape == mixed_touches.shape + (0,) and names == []


def test_bad_parameters_are_input_errors():
    with pytest.raises(InputError, match="no parameter 'amplitude'"):
        DEFAULT_CATALOG.make({"id": "lobing", "amplitude": 1.0})
    with pytest.raises(InputError, match="unknown effect"):
        DEFAULT_CATALOG.make({"id": "wobble"})
    with pytest.raises(InputError, match="must be a number"):
        DEFAULT_CATALOG.make({"id": "noise", "sigma_um": "big"})


# -- user effects ---------------------------------------------------------------------------------
def test_user_effect_file_makes_a_new_catalog_and_leaves_the_default_alone():
    catalog = DEFAULT_CATALOG.with_file(assets_dir() / "effects_example.py")
    assert list(catalog)[: len(DEFAULT_CATALOG)] == list(DEFAULT_CATALOG) and "my_ball_form" in catalog
    assert "my_ball_form" not in DEFAULT_CATALOG and "my_ball_form" in catalog.candidates()
    assert [c.id for c in load_user_effects(assets_dir() / "effects_example.py")] == ["my_ball_form"]
    effect = catalog.make({"id": "my_ball_form", "amplitude_um": 0.1, "lobes": 2, "phase_deg": 30.0})
    t = touches_at(grid([0.0, 45.0, 90.0]), n_rep=2)
    d = after_fit(effect, t)
    # Fixed in the probe frame: invisible where psi stays put (A0 = 0), 2 UPR where psi sweeps (A0 = 90).
    n_b = len(B_SAMPLE)
    assert np.abs(d[:n_b]).max() < 1e-12
    assert np.all(harmonic_spectrum(d[2 * n_b :, 0])[0].argmax(axis=-1) == 2)
    coef, *_ = np.linalg.lstsq(effect.basis(t)[0].reshape(-1, 2), effect.forward(t, None).ravel(), rcond=None)
    assert effect.from_coefficients(coef)["amplitude_um"] == pytest.approx(0.1)


EFFECT_HEADER = "from ph_explorer.effects.effect import Effect\n"
BAD_EFFECT_FILES = {
    "cannot import": "import numpy as np\ndef oops(:\n",
    "defines no subclass": "x = 1\n",
    "already a built-in": EFFECT_HEADER + "class MyNoise(Effect):\n    id = 'noise'\n    def basis(self, touches):\n        return None\n",
    "scanned 'lobes' is not one of its parameters": EFFECT_HEADER
    + "class Odd(Effect):\n    id = 'odd'\n    scan = {'lobes': (2, 3)}\n    def basis(self, touches):\n        return None\n",
    "defines neither basis": EFFECT_HEADER + "class Empty(Effect):\n    id = 'empty'\n",
}


@pytest.mark.parametrize("problem", sorted(BAD_EFFECT_FILES))
def test_bad_user_effect_files_are_input_errors(tmp_path, problem):
    path = tmp_path / "effects.py"
    path.write_text(BAD_EFFECT_FILES[problem])
    with pytest.raises(InputError, match=problem):
        load_user_effects(path)
    with pytest.raises(InputError, match=problem):
        DEFAULT_CATALOG.with_file(path)


def test_a_missing_user_effect_file_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_user_effects(tmp_path / "missing.py")
