"""Conventions and head-touch geometry of a PH20 five-axis head measuring a ring gauge.

Machine frame right-handed, z up; mm, degrees at the interfaces, um for deviations. B turns about
+z, A about the head's x after B; the stylus direction is s(A, B) = Rz(B) Rx(A) (0, 0, -1), both
axes meeting at the pivot (the origin). The ring at (A0, B0) has its axis along s(A0, B0), point k
at theta_k = 360 k / N from e1 towards e2. A touch puts the ball centre at
c_k = sqrt(L^2 - rho^2) s(A0, B0) + rho u_k; its joint angles solve Rz(B_k) Rx(A_k) (0,0,-1) = c_k/L.
Everything here is vectorised: angles may be arrays of any shape.

Method: docs/methods/head_geometry.md.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

# PH20 joint limits (Renishaw spec): A +-115 deg; B is continuous but campaigns state it in [-180, 180].
A_LIMIT_DEG = 115.0
B_LIMIT_DEG = 180.0

# Seconds of arc per degree: angular errors are quoted in arcsec.
ARCSEC_PER_DEG = 3600.0


@dataclass(frozen=True)
class Geometry:
    """The measuring set-up: head, stylus and ring (mm), and the points per circle."""

    pivot_to_ball_mm: float = 80.0
    ball_diameter_mm: float = 2.0
    bore_diameter_mm: float = 20.0
    points_per_circle: int = 64

    def __post_init__(self) -> None:
        if not (self.pivot_to_ball_mm > 0 and self.ball_diameter_mm > 0):
            raise ValueError("pivot_to_ball_mm and ball_diameter_mm must be positive")
        if not self.bore_diameter_mm > self.ball_diameter_mm:
            raise ValueError("the bore must be larger than the ball")
        if self.contact_radius_mm >= self.pivot_to_ball_mm:
            raise ValueError("the ring is too large for the stylus to reach by head touches")
        if self.points_per_circle < 3:
            raise ValueError("a circle needs at least 3 points")

    @property
    def contact_radius_mm(self) -> float:
        """rho: radius of the circle travelled by the ball centre (bore radius - ball radius)."""
        return 0.5 * (self.bore_diameter_mm - self.ball_diameter_mm)

    @property
    def cone_half_angle_deg(self) -> float:
        """Half-angle of the cone the stylus sweeps around the ring axis during one circle."""
        return float(np.degrees(np.arcsin(self.contact_radius_mm / self.pivot_to_ball_mm)))

    @property
    def axial_distance_mm(self) -> float:
        """Distance from the pivot to the ring plane along the ring axis."""
        return float(np.sqrt(self.pivot_to_ball_mm**2 - self.contact_radius_mm**2))

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


DEFAULT_GEOMETRY = Geometry()


def rot_x(angle_deg: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices about x, shape (..., 3, 3)."""
    a = np.radians(np.asarray(angle_deg, dtype=float))
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def rot_z(angle_deg: ArrayLike) -> NDArray[np.float64]:
    """Rotation matrices about z, shape (..., 3, 3)."""
    a = np.radians(np.asarray(angle_deg, dtype=float))
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def head_rotation(a_deg: ArrayLike, b_deg: ArrayLike) -> NDArray[np.float64]:
    """Rz(B) Rx(A): columns are the probe frame (x, y, z) in the machine frame, shape (..., 3, 3)."""
    return rot_z(b_deg) @ rot_x(a_deg)


def stylus_direction(a_deg: ArrayLike, b_deg: ArrayLike) -> NDArray[np.float64]:
    """s(A, B) = Rz(B) Rx(A) (0, 0, -1): unit vector from the pivot to the ball, shape (..., 3)."""
    a = np.radians(np.asarray(a_deg, dtype=float))
    b = np.radians(np.asarray(b_deg, dtype=float))
    a, b = np.broadcast_arrays(a, b)
    return np.stack([-np.sin(b) * np.sin(a), np.cos(b) * np.sin(a), -np.cos(a)], axis=-1)


def joint_angles(direction: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(A, B) in degrees with Rz(B) Rx(A) (0,0,-1) = direction / |direction|, A in [0, 180).

    B is in (-180, 180]; it is undefined where A = 0 (the stylus points straight down) and
    returned as 0 there.
    """
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    # atan2 rather than arccos(-d_z): arccos loses precision for a stylus near vertical.
    a = np.degrees(np.arctan2(np.hypot(d[..., 0], d[..., 1]), -d[..., 2]))
    b = np.degrees(np.arctan2(-d[..., 0], d[..., 1]))
    b = np.where(np.hypot(d[..., 0], d[..., 1]) < 1e-15, 0.0, b)
    b = np.where(b <= -180.0, b + 360.0, b)
    return a, b


def point_angles_deg(n_points: int) -> NDArray[np.float64]:
    """theta_k = 360 k / N, the nominal angular position of each point on the ring."""
    return 360.0 * np.arange(n_points) / n_points


def ring_frame(a0_deg: ArrayLike, b0_deg: ArrayLike) -> NDArray[np.float64]:
    """Rz(B0) Rx(A0): columns e1, e2 and -axis of the ring frame, shape (..., 3, 3).

    Column 0 is e1, column 1 is e2; the ring axis s(A0, B0) is minus column 2.
    """
    return head_rotation(a0_deg, b0_deg)


def radial_directions(orientations_deg: ArrayLike, n_points: int) -> NDArray[np.float64]:
    """u_k for every orientation and point, shape (n_orientations, n_points, 3)."""
    o = np.atleast_2d(np.asarray(orientations_deg, dtype=float))
    frame = ring_frame(o[:, 0], o[:, 1])  # (n, 3, 3)
    theta = np.radians(point_angles_deg(n_points))
    e1, e2 = frame[:, None, :, 0], frame[:, None, :, 1]
    return np.cos(theta)[None, :, None] * e1 + np.sin(theta)[None, :, None] * e2


def ball_centres(orientations_deg: ArrayLike, geometry: Geometry = DEFAULT_GEOMETRY) -> NDArray[np.float64]:
    """c_k in mm in the machine frame (pivot at the origin), shape (n_orientations, n_points, 3)."""
    o = np.atleast_2d(np.asarray(orientations_deg, dtype=float))
    axis = stylus_direction(o[:, 0], o[:, 1])[:, None, :]
    u = radial_directions(o, geometry.points_per_circle)
    return geometry.axial_distance_mm * axis + geometry.contact_radius_mm * u


def wrap_deg(angle_deg: ArrayLike) -> NDArray[np.float64]:
    """Angles wrapped into [-180, 180)."""
    return (np.asarray(angle_deg, dtype=float) + 180.0) % 360.0 - 180.0
