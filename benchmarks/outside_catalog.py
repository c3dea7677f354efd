"""Effects of shapes the catalog lacks, for the benchmarks only (never in a catalog the diagnosis uses).

A local defect of an axis (a damaged gear tooth, a dent in an encoder track) is an angular error
confined to a few degrees of its joint angle: a bump, not a cycle. A probe module whose seats wore
unevenly adds a seven-lobe term in the force azimuth; the catalog's probe terms have 2-5 lobes
(ball form) and the seats' 3, 6, 9, 12. Each names the variable of the signature that should read
it first (`truth_variable`) and the variables of the same joint (`joint_variables`): a ring's
nominal B0 is where the B joint stands during that ring, give or take the head's own sweep into
each touch, so a B defect read first in b0_deg still sends the metrologist to the right axis.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Parameter, full_shape, joint_angle_deg, rotation_deviation_um_per_arcsec
from ph_explorer.geometry import wrap_deg
from ph_explorer.kinematics import Touches

BUMP_WIDTH_DEG = 6.0  # the defect's width (one sigma of a Gaussian in the joint angle)


class _JointBump(Effect):
    """An angular error of one axis, amplitude * exp(-(d / w)^2 / 2) at joint angle distance d from the centre."""

    axis: ClassVar[str] = "B"
    kind = "angular_positioning"
    truth_variable: ClassVar[str] = ""
    joint_variables: ClassVar[tuple[str, ...]] = ()
    parameters = (
        Parameter("amplitude_arcsec", "arcsec", 2.0, "peak angular error at the defect", plausible=(0.0, 6.0)),
        Parameter("centre_deg", "deg", 0.0, "joint angle of the defect", period=360.0),
    )

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        distance = wrap_deg(joint_angle_deg(touches, self.axis) - self.params["centre_deg"])
        column = np.exp(-0.5 * (distance / BUMP_WIDTH_DEG) ** 2) * rotation_deviation_um_per_arcsec(touches, self.axis)
        return full_shape(column[..., None], touches), [f"{self.id}_amplitude"]

    def coefficients(self) -> NDArray[np.float64]:
        return np.array([self.params["amplitude_arcsec"]])

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        return {"amplitude_arcsec": float(coef[0]), "centre_deg": self.params["centre_deg"]}


class BJointBump(_JointBump):
    id = "b_joint_bump"
    name = "A local defect of the B axis (outside the catalog)"
    axis = "B"
    truth_variable = "b_joint_deg"
    joint_variables = ("b_joint_deg", "b0_deg")


class AJointBump(_JointBump):
    id = "a_joint_bump"
    name = "A local defect of the A axis (outside the catalog)"
    axis = "A"
    truth_variable = "a_joint_deg"
    joint_variables = ("a_joint_deg", "a0_deg")


class ProbeSevenLobes(Effect):
    id = "probe_seven_lobes"
    name = "Seven lobes in the probe's force azimuth (outside the catalog)"
    axis = "probe"
    kind = "probe"
    truth_variable: ClassVar[str] = "probe_azimuth_deg"
    joint_variables: ClassVar[tuple[str, ...]] = ("probe_azimuth_deg",)
    parameters = (
        Parameter("amplitude_um", "um", 0.2, "amplitude of the seven-lobe pre-travel term at a lateral force", plausible=(0.0, 0.6)),
        Parameter("phase_deg", "deg", 0.0, "phase of the lobes", period=360.0),
    )

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        psi, lateral = np.radians(touches.psi_deg), np.sin(np.radians(touches.beta_deg))
        columns = np.stack([np.cos(7 * psi) * lateral, np.sin(7 * psi) * lateral], axis=-1)
        return full_shape(columns, touches), ["seven_lobes_cos", "seven_lobes_sin"]

    def coefficients(self) -> NDArray[np.float64]:
        phase = np.radians(self.params["phase_deg"])
        return self.params["amplitude_um"] * np.array([np.cos(phase), np.sin(phase)])

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        return {"amplitude_um": float(np.hypot(*coef[:2])), "phase_deg": float(np.degrees(np.arctan2(coef[1], coef[0])) % 360.0)}


OUTSIDE_EFFECTS: tuple[type[Effect], ...] = (BJointBump, AJointBump, ProbeSevenLobes)
