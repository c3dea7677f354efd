"""Error motions of the head's two rotary axes (ISO 230-1, ISO 230-7): radial, axial and tilt.

An error motion is the small-displacement screw of the body an axis carries, as a function of that
axis's angle, in the frame the axis sits in (`effect.axis_frame`). Each component is a
sin(m angle + phi) of the touch's joint angle, m scanned from 1 to 40 cycles per revolution, turned
into a radial deviation by `effect.screw_deviation`. Symbols (E + direction + axis): EXB, EYB, EZB,
EAB, EBB for B; EYA, EZA, EXA, EBA, ECA for A.

Method: docs/methods/rotary_axis_errors.md.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Evidence, Parameter, full_shape, joint_angle_deg, screw_deviation
from ph_explorer.kinematics import Touches

CYCLES_PER_REV = tuple(range(1, 41))
# Plausible error motions of a PH20-class head's axes, what remains after the head's own mapping
# (it compensates the repeatable part it can see with its calibration): 0.05-1 um for radial and
# axial motion of a precision bearing at this size, 0.3-2 arcsec for tilt and angular positioning
# (the cyclic errors' teaching text). Each range is generous by 1.5x at the top.
TRANSLATION_MOTION_PLAUSIBLE_UM = (0.0, 1.5)
ANGULAR_MOTION_PLAUSIBLE_ARCSEC = (0.0, 3.0)
# Screw columns of base.screw_deviation: translations along x, y, z, then rotations about them.
X, Y, Z, ABOUT_X, ABOUT_Y, ABOUT_Z = range(6)


def motion_parameters(
    directions: tuple[tuple[str, int, str], ...], unit: str, plausible: tuple[float, float], default: float
) -> tuple[Parameter, ...]:
    """Amplitude and phase per direction (prefix, screw column, description), then cycles_per_rev."""
    out = []
    for prefix, _, description in directions:
        lead = f"{prefix}_" if prefix else ""
        out += [
            Parameter(f"{lead}amplitude_{unit}", unit, default, f"amplitude of the {description}", plausible=plausible),
            Parameter(f"{lead}phase_deg", "deg", 0.0, f"phase of the {description} at joint angle 0", period=360.0),
        ]
    out.append(Parameter("cycles_per_rev", "cycles/rev", 3.0, "cycles per revolution of the joint"))
    return tuple(out)


class _ErrorMotion(Effect):
    """Each direction's screw component is amplitude * sin(m * angle + phase) at the touch's joint angle."""

    axis = "B"
    unit: ClassVar[str] = "um"
    # (parameter prefix, screw column, description); prefix "" when there is one direction.
    directions: ClassVar[tuple[tuple[str, int, str], ...]] = ()
    scan = {"cycles_per_rev": CYCLES_PER_REV}

    def names(self, prefix: str) -> tuple[str, str]:
        lead = f"{prefix}_" if prefix else ""
        return f"{lead}amplitude_{self.unit}", f"{lead}phase_deg"

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        m = self.params["cycles_per_rev"]
        angle = m * np.radians(joint_angle_deg(touches, self.axis))
        sin, cos = np.sin(angle), np.cos(angle)  # once for every direction
        screw = screw_deviation(touches, self.axis)
        columns, names = [], []
        tag = f"{self.id}_{m:g}"
        for prefix, column, _ in self.directions:
            lever = screw[..., column]
            columns += [sin * lever, cos * lever]
            label = f"{tag}_{prefix}" if prefix else tag
            names += [f"{label}_sin", f"{label}_cos"]
        return full_shape(np.stack(columns, axis=-1), touches), names

    def coefficients(self) -> NDArray[np.float64]:
        out = []
        for prefix, _, _ in self.directions:
            amplitude, phase = self.names(prefix)
            # a sin(m x + phi) = a cos(phi) sin(m x) + a sin(phi) cos(m x)
            phi = np.radians(self.params[phase])
            out += [self.params[amplitude] * np.cos(phi), self.params[amplitude] * np.sin(phi)]
        return np.array(out)

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        coef = np.asarray(coef, dtype=float)
        out: dict[str, float] = {}
        for i, (prefix, _, _) in enumerate(self.directions):
            amplitude, phase = self.names(prefix)
            c_sin, c_cos = coef[2 * i : 2 * i + 2]
            out[amplitude] = float(np.hypot(c_sin, c_cos))
            out[phase] = float(np.degrees(np.arctan2(c_cos, c_sin)) % 360.0)
        out["cycles_per_rev"] = self.params["cycles_per_rev"]
        return out

    def evidence(self, touches: Touches) -> Evidence:
        """An angle against its phase: each bin's error motion along the largest direction of this
        instance is the lever-weighted least squares of the radial residual."""
        m = self.params["cycles_per_rev"]
        largest = max(self.directions, key=lambda d: abs(self.params[self.names(d[0])[0]]))
        return Evidence(
            f"{m:g} x {self.axis} joint angle, mod 360 (deg)",
            np.mod(m * joint_angle_deg(touches, self.axis), 360.0),
            edges=np.linspace(0.0, 360.0, 37),
            weight=screw_deviation(touches, self.axis)[..., largest[1]],
            y_label=f"{largest[2]} ({self.unit})",
        )


# -- B: turns about the machine z; its error motions are in the machine frame ---------------------
class BAxisRadialMotion(_ErrorMotion):
    id = "b_axis_radial_motion"
    name = "B-axis radial error motion"
    axis, kind, symbol = "B", "radial_motion", "EXB, EYB"
    directions = (("x", X, "radial motion along x"), ("y", Y, "radial motion along y"))
    parameters = motion_parameters(directions, "um", TRANSLATION_MOTION_PLAUSIBLE_UM, 0.2)
    teaching = (
        "The body B carries translates across its axis as B turns: EXB and EYB, each a_i sin(m B + phi_i), "
        "from bearing race waviness and run-out (m = 1-40 cycles/rev; 0.05-1 um after mapping, estimate). "
        "The ball moves with it, read through -delta . u_k. At A0 = 0, where B turns a full turn with the "
        "point, a motion along one fixed direction splits into harmonics m - 1 and m + 1 of the ring: 0.5 um "
        "rms per um (a 1/rev motion that turns with B is the B line's offset, size and centre only). At larger "
        "A0 the ring's own B sweep samples it: per um 0.28 (3/rev) to 0.47 (22/rev) um rms at A0 = 15, "
        "0.06-0.18 at 90. It depends on B0, and a short period defeats interpolation on the 20-deg B grid."
    )


class BAxisAxialMotion(_ErrorMotion):
    id = "b_axis_axial_motion"
    name = "B-axis axial error motion"
    axis, kind, symbol = "B", "axial_motion", "EZB"
    directions = (("", Z, "axial motion along z"),)
    parameters = motion_parameters(directions, "um", TRANSLATION_MOTION_PLAUSIBLE_UM, 0.2)
    teaching = (
        "The body B carries moves along the B axis (machine z) as B turns: EZB = a sin(m B + phi), from "
        "bearing face run-out or preload waviness (0.05-1 um, estimate). At A0 = 0 the ring lies in a "
        "horizontal plane and a vertical move is along its axis: nothing. Its radial share is "
        "u_k,z = sin A0 sin theta_k, so it grows with sin A0, and a motion that stays constant over the ring's "
        "B sweep is only a centre shift: what shows is its change across the sweep (51 deg at A0 = 15, 13 deg "
        "at 90). Per um: 0.08 um rms at 3/rev from A0 = 15 on; at 22/rev 0.13 at A0 = 15 rising to 0.46 at 90. "
        "Depends on B0."
    )


class BAxisTiltMotion(_ErrorMotion):
    id = "b_axis_tilt_motion"
    name = "B-axis tilt error motion"
    axis, kind, symbol, unit = "B", "tilt_motion", "EAB, EBB", "arcsec"
    directions = (("about_x", ABOUT_X, "tilt motion about x"), ("about_y", ABOUT_Y, "tilt motion about y"))
    parameters = motion_parameters(directions, "arcsec", ANGULAR_MOTION_PLAUSIBLE_ARCSEC, 0.5)
    teaching = (
        "The B axis wobbles as B turns: a rotation of the body it carries about x (EAB) and y (EBB), each "
        "a_i sin(m B + phi_i), through the pivot; from bearing waviness or a bent shaft (0.3-2 arcsec, "
        "estimate). The ball moves by eps x c_k; only the part of eps across the ring axis has a lever, the "
        "79.5 mm from the pivot to the ring plane (0.385 um per arcsec), and a tilt about the ring axis itself "
        "has none. At A0 = 0 a wobble about a fixed direction, read over the full B turn, gives harmonics "
        "m - 1 and m + 1: 0.19 um rms per arcsec (0.14 at 1-2/rev), on every ring of the row; a 1/rev wobble "
        "that turns with B is the tilt of the B axis (size and centre only). At larger A0 only the change "
        "over the ring's B sweep shows: at 22/rev 0.18 at A0 = 15, 0.13 at 90. Depends on B0."
    )


# -- A: turns about the x axis of the frame carried by B; its error motions are in that frame -----
class AAxisRadialMotion(_ErrorMotion):
    id = "a_axis_radial_motion"
    name = "A-axis radial error motion"
    axis, kind, symbol = "A", "radial_motion", "EYA, EZA"
    directions = (("y", Y, "radial motion along y"), ("z", Z, "radial motion along z"))
    parameters = motion_parameters(directions, "um", TRANSLATION_MOTION_PLAUSIBLE_UM, 0.2)
    teaching = (
        "The body A carries translates across the A axis as A turns, along y and z of the frame carried by B "
        "(EYA, EZA, each a_i sin(m A + phi_i); 0.05-1 um, estimate). At A0 = 0, A stays at 6.5 deg over the "
        "ring and B turns with the point: the move is the same in the head's frame at every point, a size "
        "change only. Above that, A sweeps +-6.5 deg around A0 during a ring and what shows is the change of "
        "the motion across that sweep: per um, at 22/rev, 0.24 (y) and 0.07 (z) um rms at A0 = 15, 0.04 and "
        "0.25 at 90; at 2-3/rev 0.01-0.1. The same at every B0: it depends on A0 alone, so only rings off the "
        "A grid can show it to a lattice model, and a period in A shorter than ~2 grid steps (15 deg) does."
    )


class AAxisAxialMotion(_ErrorMotion):
    id = "a_axis_axial_motion"
    name = "A-axis axial error motion"
    axis, kind, symbol = "A", "axial_motion", "EXA"
    directions = (("", X, "axial motion along x"),)
    parameters = motion_parameters(directions, "um", TRANSLATION_MOTION_PLAUSIBLE_UM, 0.2)
    teaching = (
        "The body A carries slides along the A axis as A turns (EXA = a sin(m A + phi), 0.05-1 um, estimate), "
        "from the end float of its bearings. The A axis is horizontal and perpendicular to the stylus: at "
        "A0 = 0 it points along the ring's tangent at every point, so it adds nothing. Above, its radial share "
        "changes round the ring and with the A sweep of +-6.5 deg: per um 0.08 um rms at 2/rev at A0 = 90, "
        "at 22/rev 0.5 at A0 = 15 and 90; a 1/rev motion in sin A is exactly a centre shift. The same at every "
        "B0 (A0 only): a B sweep only carries it round with the head; a lattice model misses it only off the grid."
    )


class AAxisTiltMotion(_ErrorMotion):
    id = "a_axis_tilt_motion"
    name = "A-axis tilt error motion"
    axis, kind, symbol, unit = "A", "tilt_motion", "EBA, ECA", "arcsec"
    directions = (("about_y", ABOUT_Y, "tilt motion about y"), ("about_z", ABOUT_Z, "tilt motion about z"))
    parameters = motion_parameters(directions, "arcsec", ANGULAR_MOTION_PLAUSIBLE_ARCSEC, 0.5)
    teaching = (
        "The A axis wobbles as A turns: rotations of the stylus about y (EBA) and z (ECA) of the frame "
        "carried by B, each a_i sin(m A + phi_i) (0.3-2 arcsec, estimate). ECA is a turn about the vertical "
        "like B's angular error, but a function of A: its lever is ~ L sin A, nothing at A0 = 0. EBA turns "
        "the ball about the horizontal axis that points at the touched point at A0 = 0: zero lever there "
        "too. Both grow with A0 and show through the change over the +-6.5 deg A sweep: per arcsec at 22/rev "
        "0.19 (EBA) and 0.05 (ECA) um rms at A0 = 15, 0.01 and 0.2 at 90. The same at every B0 (A0 only)."
    )
