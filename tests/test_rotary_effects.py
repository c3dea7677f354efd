"""The rotary axes in the ISO 230-1 vocabulary: location errors and error motions of A and B.

Each effect is the small-displacement screw of an axis at every touch, read through
base.screw_deviation; these tests check that helper against exact finite motions of the head's
kinematics, and each effect's signature against its mechanism (docs/physics.md, section 4.9).
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.effects.effect import RAD_PER_ARCSEC, UM_PER_MM, rotation_deviation_um_per_arcsec, screw_deviation
from ph_explorer.geometry import DEFAULT_GEOMETRY, ball_centres, head_rotation, radial_directions, rot_z
from ph_explorer.harmonics import harmonic_spectrum, remove_size_and_centre
from ph_explorer.kinematics import touch_kinematics

L_MM = DEFAULT_GEOMETRY.pivot_to_ball_mm
AXIAL_MM = DEFAULT_GEOMETRY.axial_distance_mm
B_SAMPLE = np.arange(-160.0, 181.0, 40.0)
LOCATION = ("b_axis_position", "b_axis_orientation", "a_axis_position", "a_axis_squareness")
MOTIONS = (
    "b_axis_radial_motion",
    "b_axis_axial_motion",
    "b_axis_tilt_motion",
    "a_axis_radial_motion",
    "a_axis_axial_motion",
    "a_axis_tilt_motion",
)
A_EFFECTS = ("a_axis_position", "a_axis_squareness", "a_axis_radial_motion", "a_axis_axial_motion", "a_axis_tilt_motion")


def grid(a_values, b_values=B_SAMPLE):
    return np.array([[a, b] for a in a_values for b in b_values], dtype=float)


def touches_at(orientations, n_rep=1):
    return touch_kinematics(orientations, DEFAULT_GEOMETRY, n_rep)


def after_fit(effect, touches):
    return remove_size_and_centre(effect.forward(touches, None))


def rms(x):
    return float(np.sqrt(np.mean(np.asarray(x) ** 2)))


def rotation(axis, angle_rad):
    """Exact rotation matrices (Rodrigues) about unit axes (..., 3) by angles (...)."""
    axis = np.asarray(axis, dtype=float)
    k = np.zeros(axis.shape[:-1] + (3, 3))
    k[..., 0, 1], k[..., 0, 2], k[..., 1, 2] = -axis[..., 2], axis[..., 1], -axis[..., 0]
    k = k - np.swapaxes(k, -1, -2)
    angle = np.asarray(angle_rad, dtype=float)[..., None, None]
    return np.eye(3) + np.sin(angle) * k + (1.0 - np.cos(angle)) * (k @ k)


MIXED = grid([0.0, 4.0, 15.0, 45.0, 90.0, 105.0], [-150.0, -40.0, 70.0, 180.0])


@pytest.fixture(scope="module")
def mixed():
    return touches_at(MIXED, n_rep=2)


EXAMPLES = {
    "b_axis_position": dict(x_offset_um=1.2, y_offset_um=-0.7),
    "b_axis_orientation": dict(about_x_arcsec=4.0, about_y_arcsec=-2.5),
    "a_axis_position": dict(y_offset_um=0.9, z_offset_um=1.4),
    "a_axis_squareness": dict(about_y_arcsec=6.0),
    "b_axis_radial_motion": dict(x_amplitude_um=0.4, x_phase_deg=30.0, y_amplitude_um=0.2, y_phase_deg=250.0, cycles_per_rev=7),
    "b_axis_axial_motion": dict(amplitude_um=0.3, phase_deg=100.0, cycles_per_rev=11),
    "b_axis_tilt_motion": dict(
        about_x_amplitude_arcsec=1.1, about_x_phase_deg=10.0, about_y_amplitude_arcsec=0.6, about_y_phase_deg=300.0, cycles_per_rev=9
    ),
    "a_axis_radial_motion": dict(y_amplitude_um=0.5, y_phase_deg=45.0, z_amplitude_um=0.3, z_phase_deg=135.0, cycles_per_rev=5),
    "a_axis_axial_motion": dict(amplitude_um=0.25, phase_deg=200.0, cycles_per_rev=3),
    "a_axis_tilt_motion": dict(
        about_y_amplitude_arcsec=0.9, about_y_phase_deg=80.0, about_z_amplitude_arcsec=1.3, about_z_phase_deg=170.0, cycles_per_rev=24
    ),
}


# -- the family in the catalog ----------------------------------------------------------------------
def test_the_rotary_family_is_in_the_catalog_with_iso_symbols():
    kinds = {effect_id: DEFAULT_CATALOG[effect_id].kind for effect_id in (*LOCATION, *MOTIONS, "a_axis_cyclic", "b_axis_cyclic")}
    for axis in "AB":
        mine = {k for effect_id, k in kinds.items() if DEFAULT_CATALOG[effect_id].axis == axis}
        assert mine == {"location", "radial_motion", "axial_motion", "tilt_motion", "angular_positioning"}
    for effect_id in (*LOCATION, *MOTIONS):
        cls = DEFAULT_CATALOG[effect_id]
        symbols = cls.symbol.split(", ")
        # E + direction + axis for error motions, direction + O + axis for location errors.
        pattern = r"^[XYZABC]O[AB]$" if cls.kind == "location" else r"^E[XYZABC][AB]$"
        assert all(re.match(pattern, s) and s[-1] == cls.axis for s in symbols), cls.symbol
        for p in cls.parameters:
            if p.name.endswith("phase_deg"):
                assert p.period == 360.0
            elif p.name != "cycles_per_rev":
                assert p.plausible is not None and p.plausible[0] == 0.0, p.name
        if cls.kind != "location":
            assert cls.scan == {"cycles_per_rev": tuple(range(1, 41))}


@pytest.mark.parametrize("effect_id", sorted(EXAMPLES))
def test_basis_reproduces_forward_and_gives_back_the_parameters(effect_id, mixed):
    effect = DEFAULT_CATALOG[effect_id](**EXAMPLES[effect_id])
    cols, names = effect.basis(mixed)
    assert cols.shape == mixed.shape + (len(names),) and len(set(names)) == len(names)
    np.testing.assert_allclose(cols @ effect.coefficients(), effect.forward(mixed, None), atol=1e-12)
    found = effect.from_coefficients(effect.coefficients())
    for key, value in EXAMPLES[effect_id].items():
        assert found[key] == pytest.approx(value, abs=1e-9), key


# -- the screw helper against exact finite motions ------------------------------------------------
def finite_screw_deviation(t, axis, delta_um, eps_arcsec, point_mm):
    """-d . u_k for the ball rotated exactly by eps about a line through point_mm, then translated by
    delta, both given in the frame the axis sits in."""
    c = ball_centres(t.orientations)[:, None]  # (n_o, 1, n_pt, 3) mm
    u = radial_directions(t.orientations, DEFAULT_GEOMETRY.points_per_circle)[:, None]
    frame = np.eye(3) if axis == "B" else rot_z(t.b_deg)
    eps_rad = np.asarray(eps_arcsec) * RAD_PER_ARCSEC
    turn = rotation(eps_rad / np.linalg.norm(eps_rad), np.linalg.norm(eps_rad))
    local = np.einsum("...ji,...j->...i", frame, c)
    moved = point_mm + np.einsum("ij,...j->...i", turn, local - point_mm) + np.asarray(delta_um) / UM_PER_MM
    d_um = (np.einsum("...ij,...j->...i", frame, moved) - c) * UM_PER_MM
    return -np.einsum("...i,...i->...", d_um, u)


@pytest.mark.parametrize("axis", ["A", "B"])
def test_screw_helper_is_the_first_order_of_a_finite_rotation_and_translation_of_the_ball(axis):
    t = touches_at(MIXED)
    delta_um, eps_arcsec = np.array([0.7, -0.4, 1.1]), np.array([2.0, -3.0, 1.5])
    point_mm = np.array([3.0, -5.0, 20.0])  # the rotation's axis passes here (in the axis frame)
    misses = []
    for scale in (1.0, 0.5):
        exact = finite_screw_deviation(t, axis, scale * delta_um, scale * eps_arcsec, point_mm)
        # Linear: a rotation through a point is the same rotation through the pivot plus -eps x point.
        shift_um = scale * (delta_um - np.cross(eps_arcsec * RAD_PER_ARCSEC, point_mm) * UM_PER_MM)
        linear = screw_deviation(t, axis) @ np.concatenate([shift_um, scale * eps_arcsec])
        misses.append(np.abs(linear - exact).max())
        assert np.abs(exact).max() > 0.5 * scale
    # What is left is second order: (4 arcsec)^2 x 80 mm ~ 3e-5 um, and a quarter of it at half the errors.
    assert misses[0] < 5e-5 and misses[1] == pytest.approx(misses[0] / 4, rel=0.05)


def test_screw_helper_generalises_the_angular_levers_and_has_no_lever_about_the_ring_axis():
    t = touches_at(MIXED)
    for axis, column in (("A", 3), ("B", 5)):
        np.testing.assert_array_equal(rotation_deviation_um_per_arcsec(t, axis), screw_deviation(t, axis)[..., column])
    # A rotation about the ring axis s(A0, B0) through the pivot moves every ball along its ring.
    s0 = -head_rotation(MIXED[:, 0], MIXED[:, 1])[:, None, None, :, 2]
    assert np.abs(np.einsum("...i,...i->...", screw_deviation(t, "B")[..., 3:], s0)).max() < 1e-12
    # ECA (A's tilt about z of B's frame) has exactly the lever of B's angular error, ~ L sin A0.
    np.testing.assert_allclose(screw_deviation(t, "A")[..., 5], screw_deviation(t, "B")[..., 5], atol=1e-15)
    # A translation along z reads -u_k,z = -sin(A0) sin(theta_k): B's axial motion grows with sin A0.
    expected = -np.sin(np.radians(MIXED[:, 0]))[:, None, None] * np.sin(np.radians(t.theta_deg))
    np.testing.assert_allclose(screw_deviation(t, "B")[..., 2], expected, atol=1e-12)


# -- location errors: the effects against the exact kinematics of a misplaced axis line -----------
def exact_location_deviation(t, b_offset_um=(0.0, 0.0), b_tilt_arcsec=(0.0, 0.0), a_offset_um=(0.0, 0.0), a_tilt_arcsec=0.0):
    """-(c_real - c) . u_k with B turning about its real line and A about its real line in B's frame."""
    a_k, b_k = t.a_deg, t.b_deg
    u = radial_directions(t.orientations, DEFAULT_GEOMETRY.points_per_circle)[:, None]
    stylus = np.array([0.0, 0.0, -L_MM])
    # A: turns by A_k about x tilted by the squareness about y, through (0, y, z) of B's frame.
    q0 = np.array([0.0, *a_offset_um]) / UM_PER_MM
    n_a = rotation(np.array([0.0, 1.0, 0.0]), a_tilt_arcsec * RAD_PER_ARCSEC) @ np.array([1.0, 0.0, 0.0])
    in_b = q0 + np.einsum("...ij,j->...i", rotation(n_a, np.radians(a_k)), stylus - q0)
    # B: turns by B_k about z tilted by (about x, about y), through (x, y, 0).
    p0 = np.array([*b_offset_um, 0.0]) / UM_PER_MM
    tilt = np.array([*b_tilt_arcsec, 0.0]) * RAD_PER_ARCSEC
    n_b = (
        np.array([0.0, 0.0, 1.0])
        if not tilt.any()
        else rotation(tilt / np.linalg.norm(tilt), np.linalg.norm(tilt)) @ np.array([0.0, 0.0, 1.0])
    )
    real = p0 + np.einsum("...ij,...j->...i", rotation(n_b, np.radians(b_k)), in_b - p0)
    model = np.einsum("...ij,j->...i", head_rotation(a_k, b_k), stylus)
    np.testing.assert_allclose(model, ball_centres(t.orientations)[:, None], atol=1e-9)
    return -np.einsum("...i,...i->...", (real - model) * UM_PER_MM, u)


@pytest.mark.parametrize(
    "effect_id, params, exact",
    [
        ("b_axis_position", dict(x_offset_um=1.5, y_offset_um=-0.8), dict(b_offset_um=(1.5, -0.8))),
        ("b_axis_orientation", dict(about_x_arcsec=6.0, about_y_arcsec=-4.0), dict(b_tilt_arcsec=(6.0, -4.0))),
        ("a_axis_position", dict(y_offset_um=1.2, z_offset_um=-0.9), dict(a_offset_um=(1.2, -0.9))),
        ("a_axis_squareness", dict(about_y_arcsec=8.0), dict(a_tilt_arcsec=8.0)),
    ],
)
def test_location_errors_are_the_first_order_of_a_misplaced_axis_line(effect_id, params, exact):
    t = touches_at(MIXED)
    misses = []
    for scale in (1.0, 0.5):
        linear = DEFAULT_CATALOG[effect_id](**{k: scale * v for k, v in params.items()}).forward(t, None)
        truth = exact_location_deviation(
            t, **{k: tuple(scale * np.atleast_1d(v)) if isinstance(v, tuple) else scale * v for k, v in exact.items()}
        )
        misses.append(np.abs(linear - truth).max())
        assert np.abs(truth).max() > 0.3 * scale
    # The first order: what is left is second order in the error ((2 x 8 arcsec)^2 x 80 mm ~ 5e-4 um at most).
    assert misses[0] < 1e-3 and misses[1] < 0.3 * misses[0] + 1e-9  # an offset is exactly linear


@pytest.mark.parametrize("effect_id", LOCATION)
def test_location_errors_vanish_at_a0_zero_and_are_the_same_at_every_b0(effect_id):
    effect = DEFAULT_CATALOG[effect_id](**EXAMPLES[effect_id])
    zero = touches_at(grid([0.0]))
    # A0 = 0: B turns a full turn with the point and the error turns with it: size and centre only
    # (the squareness of A moves the ball along the ring's axis or tangent there: nothing at all).
    assert np.abs(effect.forward(zero, None)).max() > (0.0 if effect_id == "a_axis_squareness" else 0.01)
    assert np.abs(after_fit(effect, zero)).max() < 1e-9
    # The error turns with the head: seen from the head it is fixed, so only A0 matters.
    d = after_fit(effect, touches_at(grid([10.0, 45.0])))[:, 0].reshape(2, len(B_SAMPLE), -1)
    assert np.abs(d - d[:, :1]).max() < 1e-9


def test_b_line_offset_peaks_just_above_the_cone_angle_and_fades_with_a0():
    offset = DEFAULT_CATALOG["b_axis_position"](x_offset_um=1.0, y_offset_um=0.0)
    ring = {a: rms(after_fit(offset, touches_at(grid([a])))) for a in (4.0, 7.0, 15.0, 45.0, 90.0)}
    assert ring[7.0] > 0.3 and ring[7.0] > ring[4.0] and ring[7.0] > ring[15.0] > ring[45.0] > ring[90.0]
    assert ring[15.0] == pytest.approx(0.149, abs=0.005) and ring[90.0] < 0.005  # along the A axis at A0 = 90


def test_an_a_line_offset_along_z_is_invisible_and_along_y_grows_with_a0():
    # ZOA: a lift of the pivot plus a change of stylus length: harmonics 0 and 1 at every orientation.
    z_only = DEFAULT_CATALOG["a_axis_position"](y_offset_um=0.0, z_offset_um=2.0)
    t = touches_at(grid([0.0, 15.0, 45.0, 90.0, 105.0]))
    assert np.abs(z_only.forward(t, None)).max() > 0.5 and np.abs(after_fit(z_only, t)).max() < 1e-9
    y_only = DEFAULT_CATALOG["a_axis_position"](y_offset_um=1.0, z_offset_um=0.0)
    ring = [rms(after_fit(y_only, touches_at(grid([a])))) for a in (15.0, 45.0, 90.0)]
    assert ring[0] < ring[1] < ring[2] and ring[2] == pytest.approx(0.040, abs=0.003)
    square = DEFAULT_CATALOG["a_axis_squareness"](about_y_arcsec=1.0)
    ring = [rms(after_fit(square, touches_at(grid([a])))) for a in (15.0, 45.0, 90.0)]
    assert ring[0] < ring[1] < ring[2] < 0.02


# -- error motions --------------------------------------------------------------------------------
@pytest.mark.parametrize("m", [3, 8, 22])
def test_b_radial_and_tilt_motions_at_a0_zero_split_into_harmonics_m_minus_and_plus_one(m):
    t = touches_at(grid([0.0]))
    radial = DEFAULT_CATALOG["b_axis_radial_motion"](x_amplitude_um=1.0, y_amplitude_um=0.0, cycles_per_rev=m)
    tilt = DEFAULT_CATALOG["b_axis_tilt_motion"](about_x_amplitude_arcsec=1.0, about_y_amplitude_arcsec=0.0, cycles_per_rev=m)
    lever = AXIAL_MM * UM_PER_MM * RAD_PER_ARCSEC  # 0.385 um per arcsec: the full pivot-to-ring lever
    for effect, half in ((radial, 0.5), (tilt, 0.5 * lever)):
        amp = harmonic_spectrum(after_fit(effect, t)[:, 0])[0]
        np.testing.assert_allclose(amp[:, [m - 1, m + 1]], half, rtol=1e-6)
        amp[:, [m - 1, m + 1]] = 0.0
        assert amp.max() < 1e-9
    # Axial motion moves the ball along the ring's axis at A0 = 0: nothing, before any fit.
    axial = DEFAULT_CATALOG["b_axis_axial_motion"](amplitude_um=1.0, cycles_per_rev=m)
    assert np.abs(axial.forward(t, None)).max() < 1e-12


def test_a_tilt_about_the_ring_axis_has_no_lever():
    # Stylus along +x (A0 = 90, B0 = -90): a wobble of B about x turns every ball about the ring axis.
    t = touches_at(np.array([[90.0, -90.0]]))
    wobble = DEFAULT_CATALOG["b_axis_tilt_motion"](about_x_amplitude_arcsec=2.0, about_y_amplitude_arcsec=0.0, cycles_per_rev=5)
    assert np.abs(wobble.forward(t, None)).max() < 1e-12
    other = DEFAULT_CATALOG["b_axis_tilt_motion"](about_x_amplitude_arcsec=0.0, about_y_amplitude_arcsec=2.0, cycles_per_rev=5)
    assert np.abs(other.forward(t, None)).max() > 0.1


def test_the_location_errors_of_b_are_the_part_of_its_1_per_rev_motions_that_turns_with_it(mixed):
    # A line offset (x0, 0) displaces the body by (I - Rz(B)) (x0, 0): -x0 (cos B, sin B) besides a constant.
    x0 = 1.3
    offset = DEFAULT_CATALOG["b_axis_position"](x_offset_um=x0, y_offset_um=0.0)
    radial = DEFAULT_CATALOG["b_axis_radial_motion"](
        x_amplitude_um=x0, x_phase_deg=270.0, y_amplitude_um=x0, y_phase_deg=180.0, cycles_per_rev=1
    )
    np.testing.assert_allclose(after_fit(offset, mixed), after_fit(radial, mixed), atol=1e-12)
    tilt = DEFAULT_CATALOG["b_axis_orientation"](about_x_arcsec=x0, about_y_arcsec=0.0)
    wobble = DEFAULT_CATALOG["b_axis_tilt_motion"](
        about_x_amplitude_arcsec=x0, about_x_phase_deg=270.0, about_y_amplitude_arcsec=x0, about_y_phase_deg=180.0, cycles_per_rev=1
    )
    np.testing.assert_allclose(after_fit(tilt, mixed), after_fit(wobble, mixed), atol=1e-12)


def test_b_motions_depend_on_b0_and_what_the_b_sweep_samples():
    t = touches_at(grid([45.0], np.arange(-180.0, 180.0, 20.0)))
    for effect_id in ("b_axis_radial_motion", "b_axis_axial_motion", "b_axis_tilt_motion"):
        d = after_fit(DEFAULT_CATALOG[effect_id](cycles_per_rev=22), t)[:, 0]
        assert np.abs(d - d[:1]).max() > 0.05, effect_id
    # A constant axial motion is a centre shift; a slow one barely changes over the 13-deg sweep at A0 = 90.
    t90 = touches_at(grid([90.0]))
    assert np.abs(remove_size_and_centre(screw_deviation(t90, "B")[..., 2])).max() < 1e-12
    slow, fast = (rms(after_fit(DEFAULT_CATALOG["b_axis_axial_motion"](amplitude_um=1.0, cycles_per_rev=m), t90)) for m in (1, 22))
    assert slow < 0.04 < 0.3 < fast


@pytest.mark.parametrize("effect_id", A_EFFECTS)
def test_a_effects_are_nothing_but_size_at_a0_zero_and_depend_on_a0_alone(effect_id):
    effect = DEFAULT_CATALOG[effect_id](**EXAMPLES[effect_id])
    assert np.abs(after_fit(effect, touches_at(grid([0.0])))).max() < 1e-9  # A stays at 6.5 deg, B turns with the point
    d = after_fit(effect, touches_at(grid([30.0, 75.0])))[:, 0].reshape(2, len(B_SAMPLE), -1)
    assert np.abs(d).max() > 0.005
    assert np.abs(d - d[:, :1]).max() < 1e-9


def test_a_tilt_motion_about_z_grows_like_the_b_lever_and_about_y_has_none_at_a0_zero():
    t = touches_at(grid([0.0, 30.0, 90.0], [0.0]))
    screw = screw_deviation(t, "A")  # at A0 = 90, B0 = 0 the y axis of B's frame is the ring axis: little lever
    # ECA: ~ L sin A0 (the lever of B's angular error); EBA: about the horizontal axis through the touched point at A0 = 0.
    peak = np.abs(screw[..., 5]).max(axis=-1)[:, 0]
    np.testing.assert_allclose(peak, AXIAL_MM * UM_PER_MM * RAD_PER_ARCSEC * np.sin(np.radians([0.0, 30.0, 90.0])), atol=1e-12)
    assert np.abs(screw[0, ..., 4]).max() < 1e-12 and np.abs(screw[1, ..., 4]).max() > 0.15


# -- the teaching scenarios that hide them --------------------------------------------------------
@pytest.mark.parametrize("name", ["near_vertical", "head_2"])
def test_teaching_scenarios_hide_a_rotary_effect_the_design_can_see_without_naming_it(name):
    from ph_explorer.models.crossval import OutOfSampleSmoother
    from ph_explorer.twin import load_scenario

    scenario = load_scenario(name)
    (hidden,) = [e for e, h in zip(scenario.effects, scenario.hidden) if h]
    cls = type(hidden)
    assert cls.kind in ("location", "radial_motion", "tilt_motion") and all(p.admits(hidden.params[p.name]) for p in cls.parameters)
    # Spoiler-free: the one-line description names neither the effect nor its axis, kind or symbols.
    words = {cls.id, *cls.id.split("_"), cls.kind, *cls.kind.split("_"), *cls.symbol.split(", "), *cls.name.lower().split()}
    text = scenario.description.lower()
    named = [
        w for w in words if len(w) > 2 and w.lower() not in {"axis", "the", "from"} and re.search(rf"\b{re.escape(w.lower())}\b", text)
    ]
    assert not named and "axis" not in text, named
    # What the hidden effect leaves out of sample at the held-out rings, well above the floor of the
    # mean of 10 repetitions (0.044 um).
    held = np.array([any(np.allclose(o, c) for c in scenario.check_orientations) for o in scenario.orientations])
    touches = touch_kinematics(scenario.orientations, scenario.geometry, 1)
    residual = OutOfSampleSmoother(scenario.orientations, ~held).residual(after_fit(hidden, touches))
    assert np.mean(np.abs(residual[held])) > 0.055
