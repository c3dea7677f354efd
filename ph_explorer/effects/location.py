"""Location errors of the head's two rotary axes (ISO 230-1): where each axis line really lies.

A location error is a constant small screw E (delta0, eps0, in the frame the axis sits in) that
moves the real axis line: the real joint is E R(angle) E^-1. To first order the body the axis
carries is displaced by delta = (I - R(theta)) delta0, eps = (I - R(theta)) eps0, which
`effect.screw_deviation` turns into radial deviations. Symbols: <direction>O<axis>, e.g. XOB.

Method: docs/methods/rotary_axis_errors.md.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Evidence, Parameter, full_shape, joint_angle_deg, screw_deviation
from ph_explorer.effects.motions import ABOUT_X, ABOUT_Y, X, Y, Z
from ph_explorer.geometry import rot_x, rot_z
from ph_explorer.kinematics import Touches

# Plausible residual location errors after the head has been qualified (its calibration locates the
# axes from touches on a sphere with a 0.35 um repeatable probe over ~80 mm of lever): position
# offsets of 0.1-2 um, orientation errors of 1-10 arcsec (10 arcsec is 3.9 um at the 80 mm lever,
# the most such a calibration leaves unseen). Generous by 1.5x at the top.
POSITION_PLAUSIBLE_UM = (0.0, 3.0)
ORIENTATION_PLAUSIBLE_ARCSEC = (0.0, 15.0)


class _Location(Effect):
    """A constant screw of an axis line, seen through (I - R(joint angle)) at every touch."""

    axis = "B"
    kind = "location"
    # (parameter name, screw column of base.screw_deviation) of each component of the constant screw.
    components: ClassVar[tuple[tuple[str, int], ...]] = ()

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        angle = joint_angle_deg(touches, self.axis)
        # The axis's nominal rotation in its own frame: about z for B, about x for A.
        turn = np.eye(3) - (rot_z(angle) if self.axis == "B" else rot_x(angle))  # (n_o, 1, n_pt, 3, 3)
        screw = screw_deviation(touches, self.axis)
        columns = []
        for _, column in self.components:
            block = screw[..., 3 * (column // 3) : 3 * (column // 3) + 3]  # translations or rotations
            # The deviation of a unit delta0 (or eps0) along j is the screw's sensitivity . (I - R) e_j.
            columns.append(np.einsum("...i,...i->...", block, turn[..., :, column % 3]))
        return full_shape(np.stack(columns, axis=-1), touches), [f"{self.id}_{name}" for name, _ in self.components]

    def evidence(self, touches: Touches) -> Evidence:
        return Evidence(f"{self.axis} joint angle (deg)", joint_angle_deg(touches, self.axis))


class BAxisPosition(_Location):
    id = "b_axis_position"
    name = "B-axis position offset"
    axis, symbol = "B", "XOB, YOB"
    components = (("x_offset_um", X), ("y_offset_um", Y))
    parameters = (
        Parameter("x_offset_um", "um", 0.5, "offset of the B axis line along x (XOB)", plausible=POSITION_PLAUSIBLE_UM),
        Parameter("y_offset_um", "um", 0.0, "offset of the B axis line along y (YOB)", plausible=POSITION_PLAUSIBLE_UM),
    )
    teaching = (
        "The B axis line does not pass where the head's model puts it (through the pivot, where it meets "
        "A): it is offset by (XOB, YOB) in the machine's x-y plane, 0.1-2 um after the head's qualification "
        "(estimate). Turning B by B_k then moves the ball by (I - Rz(B_k)) (XOB, YOB): the offset turns with "
        "the head, so in head touches its signature is the same at every B0 and depends on A0 only. At A0 = 0 "
        "the B joint turns a full turn with the point and the offset turns with it: a pure size and centre "
        "change, invisible after the circle fit. Above the cone angle (6.5 deg) B sweeps less and less: per um "
        "0.34 um rms near A0 = 7, 0.15 at 15, 0.04-0.06 at 45, and at A0 = 90 0.04 along the stylus's lean "
        "(YOB), nothing along the A axis (XOB); mostly 2 UPR. It is exactly the part of a 1/rev radial error "
        "motion that turns with B. Smooth in A0 above 15 deg: a lattice model learns it, only rings between "
        "A0 = 0 and 15 deg can show it, and there it is the B axis's tilt (1 arcsec ~ 0.39 um: 99 % shared); "
        "over all A0 they differ by ~30 % rms, and a second stylus length separates them."
    )


class BAxisOrientation(_Location):
    id = "b_axis_orientation"
    name = "B-axis tilt from the machine z"
    axis, symbol = "B", "AOB, BOB"
    components = (("about_x_arcsec", ABOUT_X), ("about_y_arcsec", ABOUT_Y))
    parameters = (
        Parameter("about_x_arcsec", "arcsec", 3.0, "tilt of the B axis about x (AOB)", plausible=ORIENTATION_PLAUSIBLE_ARCSEC),
        Parameter("about_y_arcsec", "arcsec", 0.0, "tilt of the B axis about y (BOB)", plausible=ORIENTATION_PLAUSIBLE_ARCSEC),
    )
    teaching = (
        "The B axis is tilted from the machine z by AOB about x and BOB about y, 1-10 arcsec after "
        "qualification (estimate). The real B turn is E Rz(B) E^-1: the ball rotates by (I - Rz(B_k)) eps0, "
        "a tilt that turns with B, through the ~80 mm lever. Like the offset of the B line, its signature is "
        "the same at every B0 (A0 only). At A0 = 0 the full B turn per ring carries the tilt round with the "
        "point: size and centre only, invisible. Per arcsec 0.08 um rms near A0 = 8, 0.055 at 15, 0.015-0.022 "
        "at 45, 0-0.015 at 90, mostly 2 UPR. It is the part of a 1/rev tilt error motion that turns with B. "
        "Smooth in A0 above 15 deg: a lattice model learns it; only rings at small A0 show it, where it "
        "is an offset of the B line by L times the tilt (99 % shared): one stylus length cannot tell them apart."
    )


class AAxisPosition(_Location):
    id = "a_axis_position"
    name = "A-axis position offset"
    axis, symbol = "A", "YOA, ZOA"
    components = (("y_offset_um", Y), ("z_offset_um", Z))
    parameters = (
        Parameter("y_offset_um", "um", 0.5, "offset of the A axis line along y of B's frame (YOA)", plausible=POSITION_PLAUSIBLE_UM),
        Parameter("z_offset_um", "um", 0.0, "offset of the A axis line along z of B's frame (ZOA)", plausible=POSITION_PLAUSIBLE_UM),
    )
    teaching = (
        "The A axis line, which should cross the B axis at the pivot, is offset in the frame carried by B: "
        "along y (YOA: A and B do not meet) and along z (ZOA: they meet above or below the pivot), 0.1-2 um "
        "(estimate). Turning A moves the ball by (I - Rx(A_k)) (0, YOA, ZOA) in that frame. ZOA is exactly "
        "invisible in head touches: it equals a constant lift of the pivot plus a change of stylus length "
        "(harmonics 0 and 1). YOA leaves, per um, nothing at A0 = 0 (size only), 0.006 um rms at A0 = 15, 0.017 "
        "at 45, 0.04 at 90 (2 UPR), the same at every B0; a B sweep only turns it with the head. Smooth in A0: "
        "a lattice model learns it."
    )


class AAxisSquareness(_Location):
    id = "a_axis_squareness"
    name = "A-axis squareness to B"
    axis, symbol = "A", "BOA"
    components = (("about_y_arcsec", ABOUT_Y),)
    parameters = (
        Parameter("about_y_arcsec", "arcsec", 3.0, "tilt of the A axis about y of B's frame (BOA)", plausible=ORIENTATION_PLAUSIBLE_ARCSEC),
    )
    teaching = (
        "The A axis is not square to B: it is tilted about the y axis of the frame carried by B by BOA "
        "(1-10 arcsec after qualification, estimate). Turning A then also turns the stylus a little about "
        "(I - Rx(A_k)) y, a rotation that grows from nothing at A = 0. A tilt of A about z of that frame "
        "(COA) is not defined for the head: with the ball on the stylus axis it is the B axis's zero, a "
        "constant rotation about z that only shifts the circle. Per arcsec BOA leaves nothing at A0 = 0, "
        "0.002 um rms at A0 = 15, 0.006 at 45, 0.015 at 90 (2 UPR), the same at every B0: tiny, and smooth "
        "in A0, so a lattice model learns it."
    )
