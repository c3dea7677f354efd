"""Effects of the stylus itself: the form of its ball, and its bending under the probing force and
under its own weight.

Both sit in the probe frame. The wall touches the ball at the point opposite the force, on the
latitude beta of the ball (cos beta = rho / L at every head touch), at the azimuth psi + 180 deg:
so what is fixed on the ball is read through psi alone. The stylus bends as a cantilever from the
probe module, along the lateral probing force and along the lateral part of gravity
(docs/physics.md, sections `ball_form` and `stylus_bending`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Evidence, Parameter, full_shape, parameter_text
from ph_explorer.effects.probe import lateral_gravity, lateral_share
from ph_explorer.kinematics import Touches

# Sphericity of a stylus ball, 0.08-0.25 um by grade (ISO 3290 grades 3-10), generous by 1.5x.
BALL_FORM_PLAUSIBLE_UM = (0.0, 0.4)
# Lobes per turn of the ball that a diagnosis tries: low orders dominate the form of a lapped ball.
BALL_LOBES = (2.0, 3.0, 4.0, 5.0)

# Standard gravity (m/s^2): the weight of the stem and the ball.
G_M_S2 = 9.81
# The TP20 standard-force module triggers at 0.08 N in the probe's XY plane (Renishaw's figure for
# the SF module; 0.055 N for the low-force module, 0.10 N for medium and extended force).
TP20_SF_TRIGGER_FORCE_N = 0.08
# Plausible deflections at the tip (um), from the cantilever formulas for the styli a TP20 carries
# (10-50 mm long, stems 1.5-3 mm, steel, ceramic, carbide or carbon fibre; docs/physics.md, `stylus_bending`): the
# largest, a 50 mm x 2 mm steel stem, bends 20 um under 0.08 N and 1.2 um under its weight at A = 90;
# generous by 1.5x at the top.
PROBING_DEFLECTION_PLAUSIBLE_UM = (0.0, 30.0)
GRAVITY_DEFLECTION_PLAUSIBLE_UM = (0.0, 2.0)


class BallForm(Effect):
    id = "ball_form"
    axis = "probe"
    kind = "form"
    name = "Form error of the stylus ball"
    teaching = (
        "The stylus ball is not a perfect sphere (sphericity 0.08-0.25 um by grade). The wall touches the "
        "ball at the point opposite the probing force, fixed in the probe frame by the force azimuth psi: "
        "a larger local radius makes the wall read closer, a deviation of minus the radius error at that "
        "point, modelled as one harmonic of psi, `lobes` per turn of the ball. At A0 = 0 the probe turns "
        "with the point, psi stays put and the ring only changes size: invisible. From A0 = 15 psi runs "
        "once round the probe during a ring, so the ball's k lobes show as about k UPR (side-bands at mid "
        "A0, clean near A0 = 90), the same at every B0: a B sweep changes nothing. 3 lobes are the same "
        "columns as the seat lobing's first harmonic: head touches cannot tell them apart."
    )
    parameters = (
        Parameter("amplitude_um", "um", 0.05, "amplitude of the ball's radius error", plausible=BALL_FORM_PLAUSIBLE_UM),
        Parameter("phase_deg", "deg", 0.0, "azimuth of the first high point in the probe frame, times lobes", period=360.0),
        Parameter("lobes", "UPR", 2.0, "undulations of the ball's radius per turn of psi"),
    )
    scan = {"lobes": BALL_LOBES}

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        k = self.params["lobes"]
        psi = np.radians(touches.psi_deg)  # (n_o, 1, n_pt): the same at every repetition
        # A high point of the ball where the wall touches it reads the wall closer: minus its radius error.
        columns = -np.stack([np.cos(k * psi), np.sin(k * psi)], axis=-1)
        return full_shape(columns, touches), [f"ball_cos{k:g}psi", f"ball_sin{k:g}psi"]

    def coefficients(self) -> NDArray[np.float64]:
        phase = np.radians(self.params["phase_deg"])
        return self.params["amplitude_um"] * np.array([np.cos(phase), np.sin(phase)])

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        c, s = np.asarray(coef, dtype=float)[:2]
        return {
            "amplitude_um": float(np.hypot(c, s)),
            "phase_deg": float(np.degrees(np.arctan2(s, c)) % 360.0),
            "lobes": self.params["lobes"],
        }

    def evidence(self, touches: Touches) -> Evidence:
        return Evidence("force azimuth psi in the probe frame (deg)", touches.psi_deg)


def second_moment_m4(diameter_mm: float) -> float:
    """I = pi d^4 / 64 of a round stem, m^4."""
    return float(np.pi * (diameter_mm * 1e-3) ** 4 / 64.0)


class StylusBending(Effect):
    id = "stylus_bending"
    axis = "probe"
    kind = "probe"
    name = "Stylus bending under the probing force and its own weight"
    teaching = (
        "The stylus is a cantilever from the probe module. The lateral trigger force F (0.08 N for a TP20 "
        "standard-force module) bends it by F L^3 / (3 E I), I = pi d^4 / 64: 4.1 um for a 20 mm x 1.5 mm "
        "steel stem, 0.5 um at 10 mm, 20 um for 50 mm x 2 mm. The ball gives way along the force, so the "
        "head travels that much further: the point reads out by the deflection times the lateral share "
        "sin(beta). Its weight bends it by w L^4 / (8 E I) + m_ball g L^3 / (3 E I) along the lateral "
        "gravity, sin A in the probe frame: 0.06 um for the 20 mm steel stem at A = 90, up to ~1 um for "
        "long thin ones. In head touches beta is the same at every touch (cos beta = rho/L), so the probing "
        "part is a pure size change; the weight part is one-fold (a sag of the ball towards -z: at A0 = 0 a "
        "size change, growing with sin A0 as a centre shift), and a B sweep only turns that shift with the "
        "ring. The circle fit removes both entirely: qualification with the same stylus absorbs them, and "
        "no ring campaign by head touches can see or fit them."
    )
    parameters = (
        Parameter("length_mm", "mm", 20.0, "free length of the stylus from the probe module to the ball centre"),
        Parameter("diameter_mm", "mm", 1.5, "diameter of the stylus stem"),
        Parameter("youngs_modulus_gpa", "GPa", 210.0, "Young's modulus of the stem (steel 210, zirconia 200, carbide 620)"),
        Parameter("density_g_cm3", "g/cm3", 7.85, "density of the stem (steel 7.85, zirconia 6.0, carbide 15)"),
        Parameter("ball_mass_mg", "mg", 16.7, "mass of the ball (a 2 mm ruby ball: 16.7 mg)"),
        Parameter("force_n", "N", TP20_SF_TRIGGER_FORCE_N, "lateral force at which the probe triggers"),
    )
    # The fitted coefficients are deflections; their plausible ranges (from_coefficients' outputs).
    deflections = {
        "probing_deflection_um": PROBING_DEFLECTION_PLAUSIBLE_UM,
        "gravity_deflection_um": GRAVITY_DEFLECTION_PLAUSIBLE_UM,
    }

    def deflections_um(self) -> tuple[float, float]:
        """Tip deflection (um) under the trigger force, and under the weight with gravity fully lateral (A = 90)."""
        p = self.params
        length = p["length_mm"] * 1e-3
        stiffness = p["youngs_modulus_gpa"] * 1e9 * second_moment_m4(p["diameter_mm"])  # E I, N m^2
        if stiffness <= 0.0:
            return 0.0, 0.0
        weight_per_m = p["density_g_cm3"] * 1e3 * G_M_S2 * np.pi * (p["diameter_mm"] * 1e-3) ** 2 / 4.0
        ball_weight = p["ball_mass_mg"] * 1e-6 * G_M_S2
        probing = p["force_n"] * length**3 / (3.0 * stiffness)
        weight = weight_per_m * length**4 / (8.0 * stiffness) + ball_weight * length**3 / (3.0 * stiffness)
        return probing * 1e6, weight * 1e6

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        # Probing: the ball gives way along the lateral force by the deflection; the point reads out
        # by it times the share of that direction on the radial one, sin(beta).
        probing = lateral_share(touches)
        # Weight: the ball sags along the lateral gravity g_lat (|g_lat| = sin A_k); the touch reads
        # -d . u_k = deflection * (g_lat . f_lat), f_lat the lateral part of the unit force -u_k.
        weight = np.einsum("...i,...i->...", lateral_gravity(touches), touches.force_probe[..., :2])
        columns = np.stack([probing, weight], axis=-1)
        return full_shape(columns, touches), ["stylus_bending_probing", "stylus_bending_gravity"]

    def coefficients(self) -> NDArray[np.float64]:
        return np.array(self.deflections_um())

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        c = np.asarray(coef, dtype=float)
        return {"probing_deflection_um": float(c[0]), "gravity_deflection_um": float(c[1])}

    @classmethod
    def parameters_text(cls, params: Mapping[str, float], uncertainties: Mapping[str, float] | None = None) -> str:
        u = uncertainties or {}
        return ", ".join(parameter_text(k, float(v), "um" if k in cls.deflections else "", u.get(k)) for k, v in params.items())

    @classmethod
    def implausible(cls, params: Mapping[str, float]) -> list[str]:
        # The fit gives deflections, not the stylus's dimensions: judge them by their own ranges.
        out = super().implausible({k: v for k, v in params.items() if k not in cls.deflections})
        for name, (low, high) in cls.deflections.items():
            if name in params and not low <= abs(float(params[name])) <= high:
                out.append(f"{parameter_text(name, float(params[name]), 'um')}, plausible {low:g}-{high:g} um")
        return out

    def evidence(self, touches: Touches) -> Evidence:
        return Evidence("nominal A0 (deg)", np.broadcast_to(touches.orientations[:, :1, None], touches.a_deg.shape))
