"""Head-touch kinematics: joint sweeps, force and gravity in the probe frame, order, approach, reach."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from ph_explorer.campaign import Campaign
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry, ball_centres, stylus_direction
from ph_explorer.kinematics import campaign_touches, joint_sweep_deg, near_pole, touch_kinematics

RHO_OVER_L = 9.0 / 80.0


def test_a0_zero_turns_b_a_full_circle_at_the_cone_angle() -> None:
    t = touch_kinematics([[0.0, 0.0]])
    np.testing.assert_allclose(t.a_deg, np.degrees(np.arcsin(RHO_OVER_L)), atol=1e-12)
    sweep = joint_sweep_deg(t)[0]
    assert sweep[0] == pytest.approx(0.0, abs=1e-9)
    assert sweep[1] == pytest.approx(360.0 * 63 / 64)  # 354.4 deg: one step short of a full turn


@pytest.mark.parametrize("a0,b_sweep", [(15.0, 50.0), (45.0, 18.0)])
@pytest.mark.parametrize("b0", [-160.0, 0.0, 90.0])
def test_b_sweep_shrinks_as_the_ring_tilts(a0: float, b0: float, b_sweep: float) -> None:
    sweep = joint_sweep_deg(touch_kinematics([[a0, b0]]))[0]
    assert sweep[1] == pytest.approx(b_sweep, abs=2.0)
    # A swings +-cone angle around A0 (64 points straddle the extremes exactly at k = 0 and 32).
    assert sweep[0] == pytest.approx(2 * np.degrees(np.arcsin(RHO_OVER_L)), abs=0.05)


def test_b_sweep_falls_monotonically_with_a0() -> None:
    sweeps = joint_sweep_deg(touch_kinematics([[a, 10.0] for a in (5, 15, 30, 45, 60, 90)]))[:, 1]
    assert np.all(np.diff(sweeps) < 0)


def test_near_the_pole_is_between_a0_zero_and_one_and_a_half_cone_angles() -> None:
    """On the pole (A0 = 0) a ring turns B once at fixed A; just off it, inside the cone (A0 < 6.46
    deg here) B still turns once while A swings 2 A0; past the cone B's sweep falls below a quarter
    turn by A0 = 9.3 deg (92 deg at A9). Only the rings between are near the pole."""
    a0 = np.array([0.0, 0.5, 3.0, 6.0, 7.0, 9.0, 10.0, 15.0, 45.0, -3.0])
    near = near_pole(touch_kinematics(np.stack([a0, np.full(a0.size, 30.0)], axis=1)))
    assert near.tolist() == [False, True, True, True, True, True, False, False, False, True]
    # A longer stylus in a wider bore has a wider cone (8.05 deg): A9 then sweeps B 127 deg.
    wide = Geometry(100.0, 2.0, 30.0, 64)
    assert near_pole(touch_kinematics([[0.0, 0.0], [9.0, 45.0], [12.0, 45.0]], wide)).tolist() == [False, True, False]


@given(orientations=arrays(np.float64, (20, 2), elements=st.floats(-115, 115, allow_nan=False)).map(lambda o: o * [1.0, 180.0 / 115.0]))
@settings(max_examples=40, deadline=None)
def test_joint_angles_reach_the_ball_centres(orientations: np.ndarray) -> None:
    """(A_k, B_k) put the ball back on c_k within 1e-9 mm, over many random orientations."""
    t = touch_kinematics(orientations)
    tip = DEFAULT_GEOMETRY.pivot_to_ball_mm * stylus_direction(t.a_deg[:, 0], t.b_deg[:, 0])
    assert np.abs(tip - ball_centres(orientations)).max() < 1e-9
    assert (t.a_deg >= 0).all() and (t.a_deg < 180).all()


@given(a0=st.floats(-115, 115), b0=st.floats(-180, 180))
@settings(max_examples=40, deadline=None)
def test_force_direction_in_the_probe_frame(a0: float, b0: float) -> None:
    """The wall pushes along -u_k; its angle beta to the probe axis has cos(beta) = rho / L."""
    t = touch_kinematics([[a0, b0]])
    f = t.force_probe[0, 0]
    np.testing.assert_allclose(np.linalg.norm(f, axis=-1), 1.0, atol=1e-12)
    np.testing.assert_allclose(np.cos(np.radians(t.beta_deg[0, 0])), RHO_OVER_L, atol=1e-12)
    psi, beta = np.radians(t.psi_deg[0, 0]), np.radians(t.beta_deg[0, 0])
    rebuilt = np.stack([np.sin(beta) * np.cos(psi), np.sin(beta) * np.sin(psi), np.cos(beta)], axis=-1)
    np.testing.assert_allclose(rebuilt, f, atol=1e-12)


def test_force_azimuth_is_fixed_at_a0_zero_and_turns_when_tilted() -> None:
    """At A0 = 0 the probe turns with B, so it always sees the force from the same side; at A0 = 90
    B hardly moves and the force azimuth goes once round the probe."""
    t = touch_kinematics([[0.0, 30.0], [90.0, 30.0]])
    assert np.ptp(t.psi_deg[0, 0]) < 1e-9
    turned = np.degrees(np.unwrap(np.radians(t.psi_deg[1, 0])))
    assert abs(turned[-1] - turned[0]) == pytest.approx(360.0 * 63 / 64, abs=1.0)


def test_force_scales_with_a_larger_stylus_cone() -> None:
    g = Geometry(pivot_to_ball_mm=50.0, bore_diameter_mm=30.0)
    t = touch_kinematics([[20.0, 0.0]], g)
    np.testing.assert_allclose(np.cos(np.radians(t.beta_deg)), 14.0 / 50.0, atol=1e-12)


@given(a0=st.floats(-115, 115), b0=st.floats(-180, 180))
@settings(max_examples=30, deadline=None)
def test_gravity_in_the_probe_frame_depends_on_a_only(a0: float, b0: float) -> None:
    t = touch_kinematics([[a0, b0]])
    a = np.radians(t.a_deg[0, 0])
    expected = np.stack([np.zeros_like(a), -np.sin(a), -np.cos(a)], axis=-1)
    np.testing.assert_allclose(t.gravity_probe[0, 0], expected, atol=1e-12)


def _times(shape: tuple[int, int, int], backwards_reps: tuple[int, ...] = ()) -> np.ndarray:
    """Touch times: circle after circle, each scanned forwards or, for some repetitions, backwards."""
    n_o, n_rep, n_pt = shape
    k = np.arange(n_pt)
    times = np.empty(shape)
    for o in range(n_o):
        for r in range(n_rep):
            local = k[::-1] if r in backwards_reps else k
            times[o, r] = (o * n_rep + r) * n_pt + local
    return times


def test_touch_order_follows_t_s() -> None:
    times = _times((2, 2, 64), backwards_reps=(1,))
    t = touch_kinematics([[30.0, 0.0], [60.0, 20.0]], n_repetitions=2, times_s=times)
    assert t.order[0, 0, 0] == 0 and t.order[0, 1, 63] == 64 and t.order[0, 1, 0] == 127
    assert sorted(t.order.ravel()) == list(range(256))
    plain = touch_kinematics([[30.0, 0.0], [60.0, 20.0]], n_repetitions=2)
    np.testing.assert_array_equal(plain.order.ravel(), np.arange(256))


@pytest.mark.parametrize("a0", [0.0, 10.0, 45.0, 90.0])
def test_approach_signs_flip_when_the_scan_reverses(a0: float) -> None:
    times = _times((1, 2, 64), backwards_reps=(1,))
    t = touch_kinematics([[a0, 20.0]], n_repetitions=2, times_s=times)
    pairs = [(t.b_approach[0, 0], t.b_approach[0, 1])]
    if a0 != 0.0:  # at A0 = 0 the A joint stands still (A_k = cone angle) and keeps +1
        pairs.append((t.a_approach[0, 0], t.a_approach[0, 1]))
    else:
        assert (t.a_approach == 1).all()
    for forward, backward in pairs:
        assert set(np.unique(forward)) <= {-1.0, 1.0}
        # Going backwards, touch k is reached from k+1: its sign is minus the forward move into k+1.
        shifted = np.append(forward[1:], forward[-1])
        np.testing.assert_array_equal(backward, -shifted)
    if a0 == 0.0:
        # B turns monotonically with the point: every forward touch approaches with +B.
        assert (t.b_approach[0, 0] == 1).all() and (t.b_approach[0, 1] == -1).all()


def test_reachability_flags_a_beyond_115() -> None:
    t = touch_kinematics([[100.0, 0.0], [112.0, 0.0], [-112.0, 45.0], [115.0, 0.0]])
    reachable = t.reachable[:, 0, :]
    assert reachable[0].all()
    for i in (1, 2, 3):
        a = t.a_deg[i, 0]
        np.testing.assert_array_equal(reachable[i], a <= 115.0)
        assert (~reachable[i]).sum() > 0
    assert (~reachable[3]).sum() > (~reachable[1]).sum()  # deeper tilt, more touches out of range


def test_campaign_touches_shapes_and_times() -> None:
    dev = np.zeros((3, 4, 16))
    times = _times(dev.shape)
    c = Campaign([[0, 0], [30, 60], [90, -120]], dev, times)
    t = campaign_touches(c)
    assert t.shape == (3, 4, 16)
    assert t.a_deg.shape == (3, 1, 16) and t.force_probe.shape == (3, 1, 16, 3)
    assert t.a_approach.shape == (3, 4, 16)
    np.testing.assert_array_equal(t.order, c.touch_order())
