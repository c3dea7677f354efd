"""Head-touch kinematics of every touch of a campaign, vectorised.

For each touch: the head's actual joint angles, the force direction in the probe frame (its
azimuth psi and its angle beta to the probe axis), gravity in the probe frame, the touch's rank
in time, the sign of each joint's approach, and whether the head can reach it.

Arrays are shaped (n_orientations, n_repetitions, n_points); quantities fixed by geometry alone
have a repetition axis of length 1 and broadcast.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign, place_in_order
from ph_explorer.geometry import (
    A_LIMIT_DEG,
    DEFAULT_GEOMETRY,
    Geometry,
    ball_centres,
    head_rotation,
    joint_angles,
    point_angles_deg,
    radial_directions,
    wrap_deg,
)

GRAVITY_MACHINE = np.array([0.0, 0.0, -1.0])  # unit vector: gravity along -z
# A ring whose B joint turns more than this over its points while its A joint moves passes near the
# pole (A = 0) without being on it: there the B sweep changes fastest with A0 (docs/physics.md).
POLE_B_SWEEP_DEG = 90.0
# An A sweep below this is a ring on the pole (A0 = 0: A stays at the cone angle, B turns once).
ON_POLE_A_SWEEP_DEG = 1e-6


@dataclass(frozen=True)
class Touches:
    """Kinematics of every touch of a campaign (see module docstring for shapes)."""

    geometry: Geometry
    orientations: NDArray[np.float64]  # (n_o, 2) nominal (A0, B0), deg
    theta_deg: NDArray[np.float64]  # (n_pt,) nominal point angle on the ring
    a_deg: NDArray[np.float64]  # (n_o, 1, n_pt) actual A joint angle at the touch
    b_deg: NDArray[np.float64]  # (n_o, 1, n_pt) actual B joint angle, in (-180, 180]
    force_probe: NDArray[np.float64]  # (n_o, 1, n_pt, 3) unit force of the wall on the ball, probe frame
    psi_deg: NDArray[np.float64]  # (n_o, 1, n_pt) azimuth of the force in the probe x-y plane
    beta_deg: NDArray[np.float64]  # (n_o, 1, n_pt) angle between the force and the probe +z axis
    gravity_probe: NDArray[np.float64]  # (n_o, 1, n_pt, 3) unit gravity vector in the probe frame
    order: NDArray[np.int64]  # (n_o, n_rep, n_pt) rank of the touch in time over the campaign
    times_s: NDArray[np.float64] | None  # (n_o, n_rep, n_pt) or None
    place: NDArray[np.float64]  # (n_o, n_rep, n_pt) the touch's place in the campaign's time order, 0 to 1
    a_approach: NDArray[np.float64]  # (n_o, n_rep, n_pt) sign (+1/-1) of the A joint's approach
    b_approach: NDArray[np.float64]  # (n_o, n_rep, n_pt) sign (+1/-1) of the B joint's approach
    reachable: NDArray[np.bool_]  # (n_o, 1, n_pt) joint angles inside the head's range
    # Quantities derived from these touches that every effect's basis asks for again (memo()).
    _memo: dict[str, NDArray[np.float64]] = field(default_factory=dict, compare=False, repr=False)

    def memo(self, key: str, make: Callable[[], NDArray[np.float64]]) -> NDArray[np.float64]:
        """make(), computed once per Touches (read-only): a search asks for the same levers at every scanned setting."""
        if key not in self._memo:
            value = make()
            value.flags.writeable = False
            self._memo[key] = value
        return self._memo[key]

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.order.shape  # type: ignore[return-value]

    @property
    def n_repetitions(self) -> int:
        return self.order.shape[1]


def touch_kinematics(
    orientations: ArrayLike,
    geometry: Geometry = DEFAULT_GEOMETRY,
    n_repetitions: int = 1,
    times_s: ArrayLike | None = None,
    place: ArrayLike | None = None,
) -> Touches:
    """Kinematics of every touch at the given nominal orientations.

    times_s (n_o, n_rep, n_pt) fixes the touch order; without it the scan order is orientation by
    orientation, repetition by repetition, point 0..N-1. place: each touch's place in the time
    order of the campaign these touches were taken from, 0 to 1 (default: their own order's).
    """
    o = np.atleast_2d(np.asarray(orientations, dtype=float))
    n_pt = geometry.points_per_circle
    centres = ball_centres(o, geometry)  # (n_o, n_pt, 3)
    a_k, b_k = joint_angles(centres)
    u = radial_directions(o, n_pt)
    frames = head_rotation(a_k, b_k)  # (n_o, n_pt, 3, 3), columns = probe axes in machine frame
    # Probe-frame components are R^T v: the wall pushes the ball along -u_k.
    force = np.einsum("opji,opj->opi", frames, -u)
    gravity = np.einsum("opji,j->opi", frames, GRAVITY_MACHINE)
    psi = np.degrees(np.arctan2(force[..., 1], force[..., 0]))
    beta = np.degrees(np.arccos(np.clip(force[..., 2], -1.0, 1.0)))

    shape = (len(o), n_repetitions, n_pt)
    if times_s is None:
        order = np.arange(int(np.prod(shape))).reshape(shape)
        times = None
    else:
        times = np.asarray(times_s, dtype=float)
        if times.shape != shape:
            raise ValueError(f"times_s must be shaped {shape}, got {times.shape}")
        flat = times.ravel()
        order = np.empty(flat.size, dtype=np.int64)
        order[np.argsort(flat, kind="stable")] = np.arange(flat.size)
        order = order.reshape(shape)

    a_approach = approach_sign(np.broadcast_to(a_k[:, None, :], shape), order)
    b_approach = approach_sign(np.broadcast_to(b_k[:, None, :], shape), order)
    reachable = np.abs(a_k) <= A_LIMIT_DEG

    return Touches(
        geometry=geometry,
        orientations=o,
        theta_deg=point_angles_deg(n_pt),
        a_deg=a_k[:, None, :],
        b_deg=b_k[:, None, :],
        force_probe=force[:, None],
        psi_deg=psi[:, None, :],
        beta_deg=beta[:, None, :],
        gravity_probe=gravity[:, None],
        order=order,
        times_s=times,
        place=place_in_order(order) if place is None else np.broadcast_to(np.asarray(place, dtype=float), shape),
        a_approach=a_approach,
        b_approach=b_approach,
        reachable=reachable[:, None, :],
    )


def campaign_touches(campaign: Campaign) -> Touches:
    """Kinematics of every touch of a Campaign, in its own touch order."""
    return touch_kinematics(campaign.orientations, campaign.geometry, campaign.n_repetitions, campaign.times_s, campaign.touch_place())


def approach_sign(joint_deg: NDArray[np.float64], order: NDArray[np.int64]) -> NDArray[np.float64]:
    """Sign of each joint's motion into each touch, from the previous touch of the same circle.

    joint_deg and order are shaped (n_o, n_rep, n_pt). The first touch of a circle takes the sign of
    the move that follows it (the head arrives moving the way the circle goes on). A joint that
    does not move gives +1.
    """
    by_time = np.argsort(order, axis=-1, kind="stable")
    angle = np.take_along_axis(joint_deg, by_time, axis=-1)
    step = wrap_deg(np.diff(angle, axis=-1))
    sign = np.where(step < 0.0, -1.0, 1.0)
    sign = np.concatenate([sign[..., :1], sign], axis=-1)
    out = np.empty_like(sign)
    np.put_along_axis(out, by_time, sign, axis=-1)
    return out


def joint_sweep_deg(touches: Touches) -> NDArray[np.float64]:
    """(n_o, 2) range of the A and B joints over the points of each ring (B unwrapped), deg."""

    def sweep() -> NDArray[np.float64]:
        a = touches.a_deg[:, 0, :]
        b = np.degrees(np.unwrap(np.radians(touches.b_deg[:, 0, :]), axis=-1))
        return np.stack([np.ptp(a, axis=-1), np.ptp(b, axis=-1)], axis=-1)

    return touches.memo("joint_sweep", sweep)


def near_pole(touches: Touches) -> NDArray[np.bool_]:
    """(n_o,) rings whose path passes near the pole without being on it: B turns more than a quarter
    turn while A moves. Rings at A0 = 0 (A fixed, one B turn) share one path at every B0: not near."""
    sweep = joint_sweep_deg(touches)
    return (sweep[:, 1] > POLE_B_SWEEP_DEG) & (sweep[:, 0] > ON_POLE_A_SWEEP_DEG)
