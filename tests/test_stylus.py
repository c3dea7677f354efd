"""The stylus's own effects show their physics: the ball's form read through psi, the stem's bending
under the trigger force and its weight, and what head touches leave of each after the circle fit."""

from __future__ import annotations

import numpy as np
import pytest

from ph_explorer.effects import DEFAULT_CATALOG, load_user_effects
from ph_explorer.effects.stylus import StylusBending, second_moment_m4
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry
from ph_explorer.harmonics import harmonic_spectrum, remove_size_and_centre
from ph_explorer.kinematics import touch_kinematics
from ph_explorer.paths import assets_dir

B_SAMPLE = np.arange(-160.0, 181.0, 40.0)
RHO_OVER_L = DEFAULT_GEOMETRY.contact_radius_mm / DEFAULT_GEOMETRY.pivot_to_ball_mm  # 0.1125: sin of the cone


def grid(a_values, b_values=B_SAMPLE):
    return np.array([[a, b] for a in a_values for b in b_values], dtype=float)


def touches_at(orientations, n_rep=1, geometry=DEFAULT_GEOMETRY):
    return touch_kinematics(orientations, geometry, n_rep)


def after_fit(effect, touches):
    return remove_size_and_centre(effect.forward(touches, np.random.default_rng(0)))


@pytest.fixture(scope="module")
def mixed():
    return touches_at(grid([0.0, 15.0, 45.0, 75.0, 90.0]), n_rep=2)


@pytest.mark.parametrize("effect_id", ["ball_form", "stylus_bending"])
def test_basis_reproduces_forward(effect_id, mixed):
    effect = DEFAULT_CATALOG[effect_id]()
    cols, names = effect.basis(mixed)
    assert cols.shape == mixed.shape + (len(names),) == mixed.shape + (2,)
    np.testing.assert_allclose(cols @ effect.coefficients(), effect.forward(mixed, None), atol=1e-12)
    assert effect.axis == "probe" and effect.kind in ("form", "probe")


# -- ball form ------------------------------------------------------------------------------------
@pytest.mark.parametrize("lobes", [2, 3, 4, 5])
def test_ball_form_is_invisible_at_a0_zero_and_k_upr_near_a0_90_at_every_b0(lobes):
    effect = DEFAULT_CATALOG["ball_form"](amplitude_um=0.2, phase_deg=40.0, lobes=lobes)
    t = touches_at(grid([0.0, 90.0]))
    d = after_fit(effect, t)[:, 0]
    n_b = len(B_SAMPLE)
    # A0 = 0: the probe turns with the point, psi is the same at every touch: a size change only.
    assert np.abs(d[:n_b]).max() < 1e-12
    # A0 = 90: psi runs once round the probe: k lobes of the ball are k UPR, at the full amplitude
    # (psi sweeps nearly uniformly there), and a B sweep changes nothing.
    amp = harmonic_spectrum(d[n_b:])[0]
    assert np.all(amp.argmax(axis=-1) == lobes)
    assert np.allclose(amp[:, lobes], 0.2, rtol=0.05)
    assert np.abs(d[n_b:] - d[n_b]).max() < 1e-9


def test_ball_form_fit_recovers_amplitude_and_phase(mixed):
    truth = DEFAULT_CATALOG["ball_form"](amplitude_um=0.15, phase_deg=250.0, lobes=3)
    cols, _ = truth.basis(mixed)
    coef, *_ = np.linalg.lstsq(cols.reshape(-1, 2), truth.forward(mixed, None).ravel(), rcond=None)
    assert truth.from_coefficients(coef) == pytest.approx({"amplitude_um": 0.15, "phase_deg": 250.0, "lobes": 3.0})


def test_three_ball_lobes_are_the_seat_lobings_first_harmonic(mixed):
    # The same columns up to sign: head touches cannot tell a 3-lobe ball from the seats' 3 UPR.
    ball, _ = DEFAULT_CATALOG["ball_form"](lobes=3).basis(mixed)
    lobing, names = DEFAULT_CATALOG["lobing"]().basis(mixed)
    first = lobing[..., :2] / np.sin(np.radians(mixed.beta_deg))[..., None]  # cos 3psi, sin 3psi
    assert names[:2] == ["lobing_cos3psi", "lobing_sin3psi"]
    np.testing.assert_allclose(-ball, first, atol=1e-12)


def test_a_user_file_cannot_redefine_a_built_in_id(tmp_path):
    path = tmp_path / "mine.py"
    path.write_text(
        "from ph_explorer.effects.effect import Effect\n"
        "class Mine(Effect):\n    id = 'ball_form'\n    def basis(self, touches):\n        return None\n"
    )
    with pytest.raises(InputError) as error:
        DEFAULT_CATALOG.with_file(path)
    line = error.value.line()
    assert "effect id 'ball_form' is already a built-in effect" in line and str(path) in line and "\n" not in line
    # The shipped example writes the same mechanism under its own id.
    example = assets_dir() / "effects_example.py"
    assert [cls.id for cls in load_user_effects(example)] == ["my_ball_form"]
    assert {"ball_form", "my_ball_form"} <= set(DEFAULT_CATALOG.with_file(example))


# -- stylus bending -------------------------------------------------------------------------------
def test_bending_deflections_follow_the_cantilever_formulas():
    steel = StylusBending(length_mm=20.0, diameter_mm=1.5, youngs_modulus_gpa=210.0, density_g_cm3=7.85, ball_mass_mg=16.7)
    probing, weight = steel.deflections_um()
    ei = 210e9 * np.pi * 0.0015**4 / 64.0
    assert second_moment_m4(1.5) == pytest.approx(np.pi * 0.0015**4 / 64.0)
    assert probing == pytest.approx(0.08 * 0.02**3 / (3 * ei) * 1e6) == pytest.approx(4.09, abs=0.01)
    w = 7850.0 * 9.81 * np.pi * 0.0015**2 / 4.0
    assert weight == pytest.approx((w * 0.02**4 / (8 * ei) + 16.7e-6 * 9.81 * 0.02**3 / (3 * ei)) * 1e6)
    # L^3 under a tip force, d^-4 through I, 1/E; no force, no probing deflection.
    assert StylusBending(length_mm=40.0).deflections_um()[0] == pytest.approx(8 * probing)
    assert StylusBending(diameter_mm=3.0).deflections_um()[0] == pytest.approx(probing / 16)
    assert StylusBending(youngs_modulus_gpa=620.0).deflections_um()[0] == pytest.approx(probing * 210 / 620)
    assert StylusBending(force_n=0.0).deflections_um()[0] == 0.0
    # Without ball, the weight term is the distributed load's w L^4 / (8 E I) alone: L^4.
    bare = StylusBending(ball_mass_mg=0.0)
    assert StylusBending(ball_mass_mg=0.0, length_mm=40.0).deflections_um()[1] == pytest.approx(16 * bare.deflections_um()[1])
    assert not StylusBending().implausible(StylusBending().from_coefficients(StylusBending().coefficients()))
    assert StylusBending.implausible({"probing_deflection_um": 45.0}) == ["probing deflection 45 um, plausible 0-30 um"]


def test_bending_under_the_probing_force_is_a_size_change_at_every_touch(mixed):
    effect = StylusBending(density_g_cm3=0.0, ball_mass_mg=0.0)  # the probing part alone
    before = effect.forward(mixed, None)
    # The ball gives way along the lateral force; the point reads out by the deflection times the
    # lateral share sin(beta), and beta is the same at every head touch (cos beta = rho / L).
    assert np.allclose(before, effect.deflections_um()[0] * np.sqrt(1.0 - RHO_OVER_L**2), atol=1e-12)
    assert np.abs(remove_size_and_centre(before)).max() < 1e-12


def test_bending_under_the_weight_is_a_sag_towards_minus_z_that_the_circle_fit_removes():
    a0 = np.array([0.0, 15.0, 45.0, 90.0])
    effect = StylusBending(force_n=0.0)  # the weight part alone
    sag = effect.deflections_um()[1]
    t = touches_at(grid(a0, [-120.0, 30.0]))
    before = effect.forward(t, None)[:, 0]
    # In the ring frame: size sag cos(A0) sin(cone) cos(cone) + centre shift sag sin(A0) cos^2(cone)
    # along e2 (the ring's uphill direction): nothing above harmonic 1, whatever B0.
    amp, _ = harmonic_spectrum(before)
    cone_cos2 = 1.0 - RHO_OVER_L**2
    a = np.repeat(np.radians(a0), 2)
    assert np.allclose(before.mean(axis=-1), sag * np.cos(a) * RHO_OVER_L * np.sqrt(cone_cos2), atol=1e-12)
    assert np.allclose(amp[:, 1], sag * np.sin(a) * cone_cos2, atol=1e-12)
    assert amp[:, 2:].max() < 1e-12
    # A0 = 0: the lateral gravity is sin of the cone angle at every touch: a size change only.
    assert np.ptp(before[:2], axis=-1).max() < 1e-12
    assert np.abs(after_fit(effect, t)).max() < 1e-12


def test_the_weight_sag_vanishes_with_the_lever_of_gravity():
    # A ring barely larger than the ball keeps the stylus vertical at A0 = 0 (the cone closes):
    # lateral gravity, and with it the sag, goes to zero there.
    tight = Geometry(bore_diameter_mm=2.02)
    t = touches_at(grid([0.0], [0.0]), geometry=tight)
    effect = StylusBending(force_n=0.0)
    assert np.abs(effect.forward(t, None)).max() < 1e-3 * effect.deflections_um()[1]
