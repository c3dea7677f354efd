"""The conventions of issue 2, tested through the geometry module's public functions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from hypothesis.extra.numpy import arrays

from ph_explorer.geometry import (
    DEFAULT_GEOMETRY,
    Geometry,
    ball_centres,
    head_rotation,
    joint_angles,
    point_angles_deg,
    radial_directions,
    ring_frame,
    stylus_direction,
    wrap_deg,
)

a_values = st.floats(-115.0, 115.0, allow_nan=False)
b_values = st.floats(-180.0, 180.0, allow_nan=False)


def test_defaults() -> None:
    g = DEFAULT_GEOMETRY
    assert (g.pivot_to_ball_mm, g.ball_diameter_mm, g.bore_diameter_mm, g.points_per_circle) == (80.0, 2.0, 20.0, 64)
    assert g.contact_radius_mm == 9.0
    assert g.cone_half_angle_deg == pytest.approx(np.degrees(np.arcsin(9 / 80)))
    assert g.axial_distance_mm == pytest.approx(np.sqrt(80**2 - 81))


@pytest.mark.parametrize(
    "kwargs", [{"ball_diameter_mm": 25.0}, {"pivot_to_ball_mm": -1.0}, {"points_per_circle": 2}, {"bore_diameter_mm": 200.0}]
)
def test_impossible_geometry_is_refused(kwargs: dict) -> None:
    with pytest.raises(ValueError):
        Geometry(**kwargs)


def test_stylus_direction_conventions() -> None:
    np.testing.assert_allclose(stylus_direction(0, 0), [0, 0, -1], atol=1e-15)  # A = 0 points down
    np.testing.assert_allclose(stylus_direction(90, 0), [0, 1, 0], atol=1e-15)  # Rx(90) takes -z to +y
    np.testing.assert_allclose(stylus_direction(90, 90), [-1, 0, 0], atol=1e-15)  # then Rz(90) takes +y to -x


@given(a=a_values, b=b_values)
def test_stylus_direction_is_the_rotated_minus_z(a: float, b: float) -> None:
    np.testing.assert_allclose(stylus_direction(a, b), head_rotation(a, b) @ [0, 0, -1], atol=1e-14)
    r = head_rotation(a, b)
    np.testing.assert_allclose(r @ r.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(r) == pytest.approx(1.0)  # right-handed


def test_rotations_turn_the_right_way() -> None:
    # B turns about +z counter-clockwise seen from above: x goes to y.
    np.testing.assert_allclose(head_rotation(0, 90) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # A turns about the head's x axis: y goes to z.
    np.testing.assert_allclose(head_rotation(90, 0) @ [0, 1, 0], [0, 0, 1], atol=1e-15)


@given(direction=arrays(np.float64, 3, elements=st.floats(-1, 1)).filter(lambda d: np.linalg.norm(d) > 1e-3))
def test_joint_angles_invert_the_stylus_direction(direction: np.ndarray) -> None:
    a, b = joint_angles(direction)
    assert 0.0 <= a <= 180.0 and -180.0 < b <= 180.0  # A = 180 only for the stylus straight up
    np.testing.assert_allclose(stylus_direction(a, b), direction / np.linalg.norm(direction), atol=1e-12)


def test_ring_frame_and_points() -> None:
    frame = ring_frame(30.0, 40.0)
    np.testing.assert_allclose(-frame[:, 2], stylus_direction(30.0, 40.0), atol=1e-15)  # axis = s(A0, B0)
    u = radial_directions([[30.0, 40.0]], 64)[0]
    np.testing.assert_allclose(u[0], frame[:, 0], atol=1e-15)  # point 0 along e1
    np.testing.assert_allclose(u[16], frame[:, 1], atol=1e-15)  # 90 deg later along e2
    np.testing.assert_allclose(u @ stylus_direction(30.0, 40.0), 0, atol=1e-15)
    np.testing.assert_allclose(point_angles_deg(8), [0, 45, 90, 135, 180, 225, 270, 315])


@given(a=a_values, b=b_values)
@settings(max_examples=50)
def test_ball_centres_lie_on_the_ring_and_the_sphere(a: float, b: float) -> None:
    g = DEFAULT_GEOMETRY
    c = ball_centres([[a, b]], g)[0]
    s = stylus_direction(a, b)
    np.testing.assert_allclose(np.linalg.norm(c, axis=-1), g.pivot_to_ball_mm, rtol=1e-13)  # |c_k| = L
    np.testing.assert_allclose(c @ s, g.axial_distance_mm, rtol=1e-13)  # in the ring plane
    radial = c - np.outer(c @ s, s)
    np.testing.assert_allclose(np.linalg.norm(radial, axis=-1), g.contact_radius_mm, rtol=1e-12)


def test_wrap() -> None:
    np.testing.assert_allclose(wrap_deg([180.0, -180.0, 190.0, -190.0, 360.0]), [-180, -180, -170, 170, 0])


@pytest.mark.parametrize("tilt_rad", [1e-4, 1e-7, 1e-10])
def test_joint_angles_keep_precision_near_vertical(tilt_rad: float) -> None:
    """A stylus a hair off vertical (down or up) keeps its tilt: 80 mm x error stays under 1e-9 mm."""
    for down in (True, False):
        d = np.array([np.sin(tilt_rad), 0.0, -np.cos(tilt_rad) if down else np.cos(tilt_rad)])
        a, b = joint_angles(d)
        expected = np.degrees(tilt_rad) if down else 180.0 - np.degrees(tilt_rad)
        assert a == pytest.approx(expected, rel=1e-9, abs=1e-12)
        assert 80.0 * np.linalg.norm(stylus_direction(a, b) - d) < 1e-9
