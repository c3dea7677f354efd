"""Effects of the TP20 probe itself: touch noise, kinematic-seat lobing, gravity on the seats."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Evidence, Parameter, full_shape
from ph_explorer.errors import InputError
from ph_explorer.kinematics import Touches

# Harmonics of the three-seat support function that the basis keeps (docs/physics.md).
SEAT_HARMONICS = (3, 6, 9, 12)


def support_function(psi_rad: NDArray[np.float64], seat_phase_rad: float) -> NDArray[np.float64]:
    """h(psi) = max_i cos(psi + pi - psi_i) for three seats at psi_i = seat_phase + 0, 120, 240 deg."""
    seats = seat_phase_rad + np.array([0.0, 2.0, 4.0]) * np.pi / 3.0
    return np.cos(psi_rad[..., None] + np.pi - seats).max(axis=-1)


def support_fourier(n: int) -> float:
    """Cosine coefficient of harmonic n (a multiple of 3) of h for seat phase 0; h's mean for n = 0.

    On one 120-deg period h(x) = cos(x), |x| <= 60 deg (x measured from a seat's lobe centre).
    """
    if n == 0:
        return 3.0 * np.sqrt(3.0) / (2.0 * np.pi)
    if n % 3:
        return 0.0

    # (3/pi) * integral_{-pi/3}^{pi/3} cos x cos(n x) dx
    def part(k: float) -> float:
        return np.sin(k * np.pi / 3.0) / k if k else np.pi / 3.0

    return float(3.0 / np.pi * (part(n - 1) + part(n + 1)))


H3 = support_fourier(3)  # 0.2067: the 3-UPR share of h

# Plausible 3-lobe amplitude of the pre-travel: the lobing teaching text's "0.1-0.4 um" after
# qualification, generous by 1.5x at the top. Gravity's two terms are changes of that same
# pre-travel (their teaching text gives no size of its own; defaults 0.1 um, estimates), so they
# share its bound.
LOBING_PLAUSIBLE_UM = (0.0, 0.6)
# Three seats: their azimuth repeats every 120 deg.
SEAT_PERIOD_DEG = 120.0


def lobing_columns(touches: Touches, weight: NDArray[np.float64]) -> tuple[NDArray[np.float64], list[str]]:
    """cos/sin of harmonics 3, 6, 9, 12 of psi, times a per-touch weight, (n_o, n_rep, n_pt, 8)."""
    psi = np.radians(touches.psi_deg)[..., None]
    n = np.array(SEAT_HARMONICS, dtype=float)
    cols = np.empty(psi.shape[:-1] + (2 * n.size,))
    cols[..., 0::2] = np.cos(n * psi) * weight[..., None]
    cols[..., 1::2] = np.sin(n * psi) * weight[..., None]
    names = [f"{trig}{k}psi" for k in SEAT_HARMONICS for trig in ("cos", "sin")]
    return full_shape(cols, touches), names


def lobing_coefficients(amplitude_um: float, seat_phase_deg: float) -> NDArray[np.float64]:
    """Coefficients of `lobing_columns` for the support function scaled to a 3-UPR amplitude."""
    shift = np.pi - np.radians(seat_phase_deg)  # h(psi) = sum c_n cos(n (psi + shift))
    out = []
    for k in SEAT_HARMONICS:
        c = amplitude_um * support_fourier(k) / H3
        out += [c * np.cos(k * shift), -c * np.sin(k * shift)]
    return np.array(out)


def lobing_from_coefficients(coef: NDArray[np.float64]) -> dict[str, float]:
    """3-UPR amplitude, seat phase and higher-harmonic ratios from fitted lobing coefficients."""
    coef = np.asarray(coef, dtype=float)
    amps = np.hypot(coef[0::2], coef[1::2])
    # cos(3 psi) c - sin(3 psi) s' with c = A cos(3 shift), s' = A sin(3 shift)
    three_shift = np.arctan2(-coef[1], coef[0])
    seat = (180.0 - np.degrees(three_shift) / 3.0) % 120.0
    out = {"amplitude_um": float(amps[0]), "seat_phase_deg": float(seat)}
    for k, a in zip(SEAT_HARMONICS[1:], amps[1:]):
        out[f"ratio_{k}_to_3"] = float(a / amps[0]) if amps[0] > 0 else float("nan")
    return out


def lateral_share(touches: Touches) -> NDArray[np.float64]:
    """sin(beta): the share of the probing force across the stylus, (n_o, 1, n_pt)."""
    return np.sin(np.radians(touches.beta_deg))


def lateral_gravity(touches: Touches) -> NDArray[np.float64]:
    """Gravity across the stylus in the probe frame (x, y), |g_lat| = sin A_k, (n_o, 1, n_pt, 2)."""
    return touches.gravity_probe[..., :2]


class Noise(Effect):
    id = "noise"
    axis = "probe"
    kind = "noise"
    name = "Touch repeatability (noise)"
    teaching = (
        "Each trigger of the TP20 scatters by its unidirectional repeatability: 0.35 um (2 sigma) in the "
        "spec, sigma = 0.175 um per touch, independent from touch to touch. Signature: the repetitions of "
        "one ring differ; over 64 points E[range] = 4.69 sigma = 0.82 um and E|e| = 0.80 sigma = 0.14 um. "
        "No model can predict it: it sets the floor of every MAE, 0.14 um against single repetitions and "
        "0.044 um against the mean of 10."
    )
    # "0.35 um (2 sigma) in the spec": a sigma of more than 1.5x that 2-sigma figure is no working TP20's.
    parameters = (
        Parameter("sigma_um", "um", 0.175, "standard deviation of one touch", plausible=(0.0, 0.5)),
        # Heavy tails (a dusty ball, a vibration): Student-t, scaled to the same standard deviation.
        Parameter("dof", "", 0.0, "degrees of freedom of a Student-t noise (0: Gaussian; else above 2)"),
    )
    candidate = False  # pure noise: nothing a model can add

    def __init__(self, **params: float) -> None:
        super().__init__(**params)
        dof = self.params["dof"]
        if dof != 0.0 and not dof > 2.0:
            raise InputError(f"effect {self.id!r}: dof must be 0 (Gaussian) or above 2 (a finite variance), got {dof:g}", column="dof")

    def forward(self, touches: Touches, rng: np.random.Generator) -> NDArray[np.float64]:
        sigma, dof = self.params["sigma_um"], self.params["dof"]
        if dof == 0.0:
            return rng.normal(0.0, sigma, size=touches.shape)
        return sigma * np.sqrt((dof - 2.0) / dof) * rng.standard_t(dof, size=touches.shape)

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        return np.zeros(touches.shape + (0,)), []

    def coefficients(self) -> NDArray[np.float64]:
        return np.zeros(0)

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        return {}


class Lobing(Effect):
    id = "lobing"
    axis = "probe"
    kind = "probe"
    name = "Kinematic-seat lobing of the TP20"
    teaching = (
        "The TP20 module sits on three kinematic seats at 120 deg. The lateral probing force needed to "
        "tilt it off its seats, and so the pre-travel, follows the support function "
        "h(psi) = max_i cos(psi + pi - psi_i) of the force azimuth psi in the probe frame: harmonics 3, 6, "
        "9, 12 in psi (1 : 0.23 : 0.10 : 0.056), scaled by the lateral share of the force sin(beta). "
        "Residual 3-lobe amplitude after qualification 0.1-0.4 um. In head touches at A0 = 0 the probe "
        "turns with the point, psi stays constant over the ring and the lobing is invisible (pure size); "
        "as A0 grows psi sweeps a full turn in a non-uniform way, so the ring shows 3 UPR with side-bands "
        "(2, 4, 5 UPR) at mid A0 and a clean 3 UPR near A0 = 90. Depends on A0 only, smoothly: "
        "an interpolating model learns it wherever it has data."
    )
    parameters = (
        Parameter(
            "amplitude_um",
            "um",
            0.25,
            "3-UPR amplitude of the pre-travel variation in psi at full lateral share",
            plausible=LOBING_PLAUSIBLE_UM,
        ),
        Parameter("seat_phase_deg", "deg", 0.0, "azimuth of the first seat in the probe frame", period=SEAT_PERIOD_DEG),
    )

    def forward(self, touches: Touches, rng: np.random.Generator) -> NDArray[np.float64]:
        h = support_function(np.radians(touches.psi_deg), np.radians(self.params["seat_phase_deg"]))
        p = self.params["amplitude_um"] / H3 * (h - support_fourier(0)) * lateral_share(touches)
        return full_shape(p, touches)

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        cols, names = lobing_columns(touches, lateral_share(touches))
        return cols, [f"lobing_{n}" for n in names]

    def coefficients(self) -> NDArray[np.float64]:
        return lobing_coefficients(self.params["amplitude_um"], self.params["seat_phase_deg"])

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        return lobing_from_coefficients(coef)

    def evidence(self, touches: Touches) -> Evidence:
        return Evidence("force azimuth psi in the probe frame (deg)", touches.psi_deg)


class Gravity(Effect):
    id = "gravity"
    axis = "probe"
    kind = "probe"
    name = "Gravity on the probe's seats"
    teaching = (
        "The weight of the stylus assembly acts on the kinematic seats. In the probe frame gravity depends "
        "on A only: axial -cos A, lateral sin A. Its lateral part helps or opposes the probing force: the "
        "trigger comes earlier when the force on the ball pushes the way gravity already pulls, a "
        "pre-travel change directional_um * (g_lat . f_lat); and it unloads the seats unequally, deepening "
        "the three-seat lobing in proportion to |g_lat| = sin A (lobing_um at A = 90). In head touches the "
        "directional part is exactly one-fold (g . f is linear in the ring's radial direction, and the probe "
        "axis stays on a cone around the ring axis), so the circle fit absorbs it entirely: what shows is "
        "the lobing growing with sin A. "
        "Smooth in A: data-driven models learn it where they have data, not beyond the measured A range."
    )
    parameters = (
        Parameter(
            "directional_um",
            "um",
            0.1,
            "pre-travel change with the lateral force along lateral gravity, at A = 90",
            plausible=LOBING_PLAUSIBLE_UM,
        ),
        Parameter("lobing_um", "um", 0.1, "extra 3-UPR lobing amplitude at A = 90 (scales with sin A)", plausible=LOBING_PLAUSIBLE_UM),
        Parameter("seat_phase_deg", "deg", 0.0, "azimuth of the first seat in the probe frame", period=SEAT_PERIOD_DEG),
    )

    def _directional(self, touches: Touches) -> NDArray[np.float64]:
        # Unit lateral force direction (probe x-y) dotted with the lateral gravity vector.
        psi = np.radians(touches.psi_deg)
        g = lateral_gravity(touches)
        return (g[..., 0] * np.cos(psi) + g[..., 1] * np.sin(psi)) * lateral_share(touches)

    def _lobing_weight(self, touches: Touches) -> NDArray[np.float64]:
        return np.linalg.norm(lateral_gravity(touches), axis=-1) * lateral_share(touches)

    def forward(self, touches: Touches, rng: np.random.Generator) -> NDArray[np.float64]:
        h = support_function(np.radians(touches.psi_deg), np.radians(self.params["seat_phase_deg"]))
        lobes = self.params["lobing_um"] / H3 * (h - support_fourier(0)) * self._lobing_weight(touches)
        return full_shape(self.params["directional_um"] * self._directional(touches) + lobes, touches)

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        lobes, names = lobing_columns(touches, self._lobing_weight(touches))
        directional = full_shape(self._directional(touches)[..., None], touches)
        return np.concatenate([directional, lobes], axis=-1), ["gravity_directional"] + [f"gravity_{n}" for n in names]

    def coefficients(self) -> NDArray[np.float64]:
        lobes = lobing_coefficients(self.params["lobing_um"], self.params["seat_phase_deg"])
        return np.concatenate([[self.params["directional_um"]], lobes])

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        coef = np.asarray(coef, dtype=float)
        lobes = lobing_from_coefficients(coef[1:])
        return {"directional_um": float(coef[0]), "lobing_um": lobes.pop("amplitude_um"), **lobes}

    def evidence(self, touches: Touches) -> Evidence:
        return Evidence("nominal A0 (deg)", np.broadcast_to(touches.orientations[:, :1, None], touches.a_deg.shape))
