"""A model's own error, estimated out of sample: what its Monte Carlo band holds beside the noise.

Method. The one cross-validation (`crossval.cross_val_predict`) predicts training rings from the
model fitted without them, twice: (1) the rings split into FOLDS groups left out in turn (every
FOLDS-th ring in measuring order: a left-out ring keeps its neighbours in A and most in B), and (2)
along A: every training ring of one interior A value left out together (with more than FOLDS
interior values, every FOLDS-th value together), so that a row is predicted from the rows beside
it. (1) sees what the model cannot interpolate between neighbouring rings, (2) what it cannot
interpolate between A values: an effect that changes quickly with A (near the vertical, say) is
invisible to (1), since every ring of a row shares it. The residual r_i = measured mean curve of
ring i - its out-of-sample prediction holds the model's error at that ring plus the noise of the
ring's own mean, independent of the prediction (white, variance v_i = s_i^2 N / (N - 3) / R per
point before the circle fit, s_i the ring's post-fit repetition sigma). Per harmonic k (2..N/2:
the circle fit removes 0 and 1) the model's error power at ring i is

    P_ik = p_k(r_i) - e_k(v_i)

with p_k harmonic k's share of the mean square over the points (Parseval: sum_k p_k = mean r^2) and
e_k = 2 v / N (v / N at the Nyquist harmonic) what white noise puts there. The two errors are
independent directions of interpolation, so their powers add; a ring of an edge A value (never
left out along A: it would be extrapolated) takes the kernel mean (below) of the other rings'
power along A. At an orientation (A, B) the model's error variance per harmonic is the
Gaussian-kernel weighted mean of P_ik over the training rings, in A only, width one A step of the
training lattice, pooled over B; a negative mean (a model error too small to see under the noise)
is zero. Why in A and not in B: every head effect acts through levers that are functions of A (sin
A for a B-axis error, the A sweep for an A-axis error, gravity sin A), so a model's error changes
with A; along B it repeats with periods the model cannot resolve, so pooling over B estimates the
variance of what it misses.

Off the lattice. A ring left out of the cross-validation is predicted from neighbours twice as far
as an orientation between the lattice's nodes is, and an error the lattice aliases (a period of
one lattice step) is the same at every node, invisible to any fold. Where the campaign has
held-out check rings, measured off the lattice, the size of this estimate is calibrated on them
(`bands.calibrate_model_error`): `scale` multiplies every variance, chosen so that the stated
share of their mean-curve points falls inside the mean band; its shape in A and over the
harmonics stays the cross-validation's. Without check rings `scale` is 1 and
`calibration_rings` 0: the band is then not checked off the lattice.

A draw of the error is a random-phase Gaussian curve with that variance per harmonic: at an
orientation it has not measured, the model does not know the phase of its own error. Phase-locked
draws would keep the pointwise shape but not the random sign; with the phase free, RONt and the
harmonics of a task see the right spread.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign, lattice_axes
from ph_explorer.geometry import point_angles_deg
from ph_explorer.models.base import DeviationModel, as_orientations
from ph_explorer.models.crossval import cross_val_predict

FILE_NAME = "uncertainty.npz"
# Groups of the cross-validation: every FOLDS-th training ring in measuring order left out together
# (on a lattice measured row by row, each left-out ring has its B neighbours in the fit).
FOLDS = 5


def harmonic_power(curves: ArrayLike) -> NDArray[np.float64]:
    """Each harmonic's share of the mean square over the points, (..., N//2 + 1) um^2 (Parseval)."""
    c = np.asarray(curves, dtype=float)
    n = c.shape[-1]
    spectrum = np.fft.rfft(c, axis=-1)
    scale = np.full(spectrum.shape[-1], 2.0 / n**2)
    scale[0] = 1.0 / n**2
    if n % 2 == 0:
        scale[-1] = 1.0 / n**2
    return np.abs(spectrum) ** 2 * scale


def white_noise_power(variance: ArrayLike, n_points: int) -> NDArray[np.float64]:
    """What white noise of the given per-point variance (..., ) puts in each harmonic, (..., N//2 + 1)."""
    share = np.full(n_points // 2 + 1, 2.0 / n_points)
    share[0] = 1.0 / n_points
    if n_points % 2 == 0:
        share[-1] = 1.0 / n_points
    return np.asarray(variance, dtype=float)[..., None] * share


def random_phase_curves(power: NDArray[np.float64], n_trials: int, n_points: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """(n_trials, n_points) Gaussian curves whose harmonic k has mean square power[k] (k >= 2 only)."""
    k = np.arange(2, min(power.size - 1, n_points // 2) + 1)
    if k.size == 0:
        return np.zeros((n_trials, n_points))
    theta = np.radians(point_angles_deg(n_points))
    # a cos + b sin with a, b ~ N(0, p) has mean square (a^2 + b^2) / 2, expectation p (at the
    # Nyquist harmonic sin vanishes at the points and a^2 alone has expectation p).
    scale = np.sqrt(np.maximum(power[k], 0.0))
    a = rng.standard_normal((n_trials, k.size)) * scale
    b = rng.standard_normal((n_trials, k.size)) * scale
    return a @ np.cos(np.outer(k, theta)) + b @ np.sin(np.outer(k, theta))


@dataclass(frozen=True)
class OutOfSampleError:
    """The model's error power per harmonic at each training ring, and its kernel in A."""

    orientations: NDArray[np.float64]  # (n_rings, 2) training orientations, deg
    power: NDArray[np.float64]  # (n_rings, N//2 + 1) um^2, noise removed (may be < 0 at one ring)
    width_deg: float  # the kernel's width in A (inf: pooled over every ring)
    scale: float = 1.0  # the variance's calibration on held-out rings off the lattice (see the docstring)
    calibration_rings: int = 0  # the held-out rings that calibrated `scale` (0: not calibrated)

    @property
    def n_points(self) -> int:
        return 2 * (self.power.shape[1] - 1)

    @classmethod
    def from_residuals(
        cls, orientations: ArrayLike, residuals: ArrayLike, noise_variance: ArrayLike, width_deg: float | None = None
    ) -> "OutOfSampleError":
        """From out-of-sample residual curves (n, N) and the per-point noise variance of each ring's mean (n,)."""
        o = as_orientations(orientations)
        return cls(o, error_power(residuals, noise_variance), a_step(o) if width_deg is None else float(width_deg))

    def weights(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, n_rings) kernel weights in A, rows summing to 1."""
        o = as_orientations(orientations)
        if not np.isfinite(self.width_deg) or self.width_deg <= 0:
            return np.full((len(o), len(self.orientations)), 1.0 / len(self.orientations))
        z = (o[:, None, 0] - self.orientations[None, :, 0]) / self.width_deg
        w = np.exp(-0.5 * z**2)
        return w / w.sum(axis=1, keepdims=True)

    def variance(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, N//2 + 1) the model's error power per harmonic at each orientation, um^2, >= 0."""
        return self.scale * np.maximum(self.weights(orientations) @ self.power, 0.0)

    def scaled(self, scale: float, calibration_rings: int) -> "OutOfSampleError":
        """The same error with its variance calibrated by `scale` on that many held-out rings."""
        return replace(self, scale=float(scale), calibration_rings=int(calibration_rings))

    def draw(self, orientation: ArrayLike, n_trials: int, n_points: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """(n_trials, n_points) draws of the model's error curve at one orientation."""
        return random_phase_curves(self.variance(orientation)[0], n_trials, n_points, rng)

    def arrays(self, prefix: str) -> dict[str, NDArray[np.float64]]:
        return {
            f"{prefix}.orientations": self.orientations,
            f"{prefix}.power": self.power,
            f"{prefix}.width_deg": np.array(self.width_deg),
            f"{prefix}.scale": np.array(self.scale),
            f"{prefix}.calibration_rings": np.array(self.calibration_rings),
        }


def error_power(residuals: ArrayLike, noise_variance: ArrayLike) -> NDArray[np.float64]:
    """(n, N//2 + 1) the model's error power per harmonic of out-of-sample residual curves (n, N), um^2:
    their power less what the noise of each ring's mean (per-point variance (n,)) puts there."""
    r = np.asarray(residuals, dtype=float)
    power = harmonic_power(r) - white_noise_power(noise_variance, r.shape[-1])
    power[:, :2] = 0.0  # the circle fit removes size and centre
    return power


def a_groups(orientations: ArrayLike, train: ArrayLike, folds: int | None = FOLDS) -> list[NDArray[np.int64]]:
    """The cross-validation along A: the training rings of each interior A value (the smallest and the
    largest would be extrapolated), every folds-th value together when there are more than `folds`."""
    rings = np.flatnonzero(np.asarray(train, dtype=bool))
    a = np.round(as_orientations(orientations)[rings, 0], 6)  # one A value: equal to 1e-6 deg
    values = np.unique(a)[1:-1]
    chunks = [values[f::folds] for f in range(folds)] if folds is not None and values.size > folds else [values[i : i + 1] for i in range(values.size)]
    return [rings[np.isin(a, chunk)] for chunk in chunks]


def a_step(orientations: NDArray[np.float64]) -> float:
    """The training lattice's A step (deg), inf when the rings hold one A value."""
    a_axis, _ = lattice_axes(orientations)
    return float(np.median(np.diff(a_axis))) if a_axis.size > 1 else float("inf")


def ring_noise_variance(campaign: Campaign) -> NDArray[np.float64]:
    """(n_o,) per-point variance of each ring's mean curve before the circle fit (see the module docstring)."""
    n, r = campaign.n_points, campaign.n_repetitions
    post_fit = np.mean(campaign.repetition_sigma() ** 2, axis=1)
    return post_fit * n / (n - 3.0) / r


def out_of_sample_error(
    make_model: Callable[[], DeviationModel], campaign: Campaign, train: ArrayLike, folds: int | None = FOLDS, strict: bool = True
) -> OutOfSampleError:
    """The model's error at its training rings by the cross-validation in folds and along A (see the
    module docstring)."""
    mask = np.asarray(train, dtype=bool)
    means, noise = campaign.mean_curves(), ring_noise_variance(campaign)
    in_folds = means - cross_val_predict(make_model, campaign, mask, folds=folds, strict=strict, held_out=False)
    error = OutOfSampleError.from_residuals(campaign.orientations[mask], in_folds[mask], noise[mask])
    groups = a_groups(campaign.orientations, mask, folds)
    if not groups:
        return error
    along_a = means - cross_val_predict(make_model, campaign, mask, strict=strict, groups=groups, held_out=False)
    rows = np.concatenate(groups)
    position = np.cumsum(mask) - 1  # a ring's row among the training rings
    seen = np.zeros(int(mask.sum()), dtype=bool)
    seen[position[rows]] = True
    power_a = np.zeros_like(error.power)
    power_a[position[rows]] = error_power(along_a[rows], noise[rows])
    weights = error.weights(error.orientations[~seen])[:, seen]
    power_a[~seen] = weights @ power_a[seen] / weights.sum(axis=1, keepdims=True)
    return replace(error, power=error.power + power_a)


def save_errors(errors: Mapping[str, OutOfSampleError], directory: str | Path, n_repetitions: int) -> Path:
    """Write every model's error (name -> OutOfSampleError) into directory/uncertainty.npz (no pickle)."""
    path = Path(directory) / FILE_NAME
    arrays: dict[str, NDArray] = {"n_repetitions": np.array(int(n_repetitions)), "models": np.array(sorted(errors))}
    for name, error in errors.items():
        arrays.update(error.arrays(name))
    with open(path, "wb") as handle:
        np.savez_compressed(handle, **arrays)
    return path


def load_errors(directory: str | Path) -> tuple[dict[str, OutOfSampleError], int]:
    """(name -> OutOfSampleError, repetitions of the training campaign) from directory/uncertainty.npz."""
    with np.load(Path(directory) / FILE_NAME, allow_pickle=False) as data:
        # Files written before the calibration off the lattice have no scale: 1, not calibrated.
        errors = {
            str(name): OutOfSampleError(
                data[f"{name}.orientations"],
                data[f"{name}.power"],
                float(data[f"{name}.width_deg"]),
                float(data[f"{name}.scale"]) if f"{name}.scale" in data else 1.0,
                int(data[f"{name}.calibration_rings"]) if f"{name}.calibration_rings" in data else 0,
            )
            for name in data["models"]
        }
        return errors, int(data["n_repetitions"])
