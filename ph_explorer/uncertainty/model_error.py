"""A model's own error, estimated out of sample: what its Monte Carlo band holds beside the noise.

The cross-validation predicts training rings without them, in FOLDS groups and along A; per
harmonic, each ring's residual power minus what its own noise puts there is the model's error
power. At an orientation the error variance is its Gaussian-kernel mean in A (pooled over B),
scaled on held-out check rings where the campaign has them (`bands.calibrate_model_error`,
localized conformal). A draw of the error is a random-phase Gaussian curve with that variance.

Method: docs/methods/out_of_sample_error.md.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign, lattice_axes
from ph_explorer.geometry import point_angles_deg
from ph_explorer.models.crossval import cross_val_predict
from ph_explorer.models.deviation_model import DeviationModel, as_orientations, save_arrays

FILE_NAME = "uncertainty.npz"
# Groups of the cross-validation: every FOLDS-th training ring in measuring order left out together
# (on a lattice measured row by row, each left-out ring has its B neighbours in the fit).
FOLDS = 5
# Held-out rings needed to calibrate the model error's size, and the rings' worth of weight (n_eff,
# see docs/methods/out_of_sample_error.md) behind a local scale: a local scale rests on as much as the campaign's.
MIN_CALIBRATION_RINGS = 5


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
    scale: float = 1.0  # the variance's calibration on held-out rings off the lattice, the campaign's (docs/methods/out_of_sample_error.md)
    calibration_rings: int = 0  # the held-out rings that calibrated `scale` (0: not calibrated)
    calibration_a_deg: NDArray[np.float64] | None = None  # (m,) their A, for the local scale
    calibration_scores: NDArray[np.float64] | None = None  # (m, N) each mean-curve point's scale to be inside
    calibration_level: float = 0.95  # the share of points the calibration holds
    calibration_width_deg: float = float("inf")  # the local scale's kernel in A (inf: the campaign's scale everywhere)

    @property
    def n_points(self) -> int:
        return 2 * (self.power.shape[1] - 1)

    @classmethod
    def from_residuals(
        cls, orientations: ArrayLike, residuals: ArrayLike, noise_variance: ArrayLike, width_deg: float | None = None
    ) -> OutOfSampleError:
        """From out-of-sample residual curves (n, N) and the per-point noise variance of each ring's mean (n,)."""
        o = as_orientations(orientations)
        return cls(o, error_power(residuals, noise_variance), a_step(o) if width_deg is None else float(width_deg))

    def weights(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, n_rings) kernel weights in A, rows summing to 1."""
        return a_kernel(as_orientations(orientations)[:, 0], self.orientations[:, 0], self.width_deg)

    def base_power(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, N//2 + 1) the error power per harmonic at each orientation before calibration, um^2, >= 0."""
        return np.maximum(self.weights(orientations) @ self.power, 0.0)

    def variance(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, N//2 + 1) the model's error power per harmonic at each orientation, um^2, >= 0."""
        return self.scale_at(orientations)[:, None] * self.base_power(orientations)

    def scale_at(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m,) the variance's calibration scale at each orientation: local where check rings scored it."""
        o = as_orientations(orientations)
        if self.calibration_scores is None or self.calibration_a_deg is None:
            return np.full(len(o), self.scale)
        weights = local_calibration_weights(o[:, 0], self.calibration_a_deg, self.calibration_width_deg)
        return weighted_quantile(self.calibration_scores, weights, self.calibration_level)

    def calibrated(self, a_deg: ArrayLike, scores: ArrayLike, level: float) -> OutOfSampleError:
        """The same error calibrated on held-out rings at A = a_deg (m,) whose mean-curve points need
        the scales `scores` (m, N) to be inside their band: `level` of them overall, and locally in A
        with the kernel width the rings choose (`calibration_width`)."""
        a, s = np.asarray(a_deg, dtype=float), np.asarray(scores, dtype=float)
        scale = float(weighted_quantile(s, np.ones((1, a.size)), level)[0])
        return replace(
            self,
            scale=scale,
            calibration_rings=a.size,
            calibration_a_deg=a,
            calibration_scores=s,
            calibration_level=float(level),
            calibration_width_deg=calibration_width(a, s, level, self.width_deg),
        )

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
            f"{prefix}.calibration_level": np.array(self.calibration_level),
            f"{prefix}.calibration_width_deg": np.array(self.calibration_width_deg),
        } | (
            {}
            if self.calibration_scores is None
            else {
                f"{prefix}.calibration_a_deg": np.asarray(self.calibration_a_deg, dtype=float),
                f"{prefix}.calibration_scores": self.calibration_scores,
            }
        )


@dataclass(frozen=True)
class PosteriorError(OutOfSampleError):
    """A model's own error from its posterior (a Gaussian process: `model.variance`), not from a
    cross-validation: at any orientation, the posterior's per-point variance spread over harmonics
    2..N/2 as white noise spreads it. Calibrated on held-out rings as the cross-validation's is;
    `power` holds it at the training rings (what `weights` and a saved file would read)."""

    model: DeviationModel | None = None  # with variance(orientations, n_points) -> (m, N) um^2

    def base_power(self, orientations: ArrayLike) -> NDArray[np.float64]:
        return posterior_power(self.model, as_orientations(orientations), self.n_points)  # type: ignore[arg-type]

    def arrays(self, prefix: str) -> dict[str, NDArray[np.float64]]:
        return {**super().arrays(prefix), f"{prefix}.posterior": np.array(True)}  # read back with its model (load_errors)


def posterior_power(model: DeviationModel, orientations: NDArray[np.float64], n_points: int) -> NDArray[np.float64]:
    """(m, N//2 + 1): a model's posterior variance at the orientations, per point averaged, as harmonic power (white_power)."""
    return white_power(model.variance(orientations, n_points).mean(axis=1), n_points)  # type: ignore[attr-defined]


def white_power(variance: ArrayLike, n_points: int) -> NDArray[np.float64]:
    """(..., N//2 + 1): a per-point variance (...,) after the circle fit, spread over harmonics 2..N/2
    in the shares white noise has there (harmonics 0 and 1 hold nothing)."""
    share = white_noise_power(1.0, n_points)
    share[:2] = 0.0
    return np.asarray(variance, dtype=float)[..., None] * share / share.sum()


def has_posterior(model: DeviationModel) -> bool:
    """Whether the model knows its own error at any orientation (a posterior variance: a GP)."""
    return callable(getattr(model, "variance", None))


def own_error(make_model: Callable[[], DeviationModel], model: DeviationModel, campaign: Campaign, train: ArrayLike) -> OutOfSampleError:
    """A model's own error before calibration: its posterior's when it has one (PosteriorError), else
    the cross-validation's (out_of_sample_error, with `make_model` for its refits)."""
    mask = np.asarray(train, dtype=bool)
    if not has_posterior(model):
        return out_of_sample_error(make_model, campaign, mask)
    o = campaign.orientations[mask]
    return PosteriorError(o, posterior_power(model, o, campaign.n_points), a_step(o), model=model)


def a_kernel(a_deg: ArrayLike, centres_a_deg: ArrayLike, width_deg: float) -> NDArray[np.float64]:
    """(m, n) Gaussian weights in A of n centres at m values of A, rows summing to 1 (uniform when
    the width is not finite)."""
    a, centres = np.asarray(a_deg, dtype=float), np.asarray(centres_a_deg, dtype=float)
    if not np.isfinite(width_deg) or width_deg <= 0:
        return np.full((a.size, centres.size), 1.0 / centres.size)
    w = np.exp(-0.5 * ((a[:, None] - centres[None, :]) / width_deg) ** 2)
    return w / w.sum(axis=1, keepdims=True)


def local_calibration_weights(a_deg: ArrayLike, centres_a_deg: ArrayLike, width_deg: float, leave_out: bool = False) -> NDArray[np.float64]:
    """(m, n) the check rings' weights at each A: the kernel in A, widened by steps of 2^(1/4) until
    they count at least MIN_CALIBRATION_RINGS rings (n_eff = 1 / sum w^2 for rows summing to 1); all
    rings alike when the width is inf or nothing narrower does. leave_out: the A values are the
    centres' own and each row leaves its own ring out (weight 0)."""
    a = np.asarray(a_deg, dtype=float)
    n = np.asarray(centres_a_deg).size
    own = np.eye(a.size, n, dtype=bool) if leave_out else np.zeros((a.size, n), dtype=bool)
    out = np.where(own, 0.0, 1.0 / max(n - int(leave_out), 1))
    pending = np.ones(a.size, dtype=bool) if np.isfinite(width_deg) and width_deg > 0 else np.zeros(a.size, dtype=bool)
    for factor in 2.0 ** (np.arange(41) / 4.0):
        if not pending.any():
            break
        w = np.where(own[pending], 0.0, a_kernel(a[pending], centres_a_deg, width_deg * factor))
        w /= w.sum(axis=1, keepdims=True)
        enough = 1.0 / np.sum(w**2, axis=1) >= min(MIN_CALIBRATION_RINGS, n - int(leave_out)) - 1e-9
        rows = np.flatnonzero(pending)[enough]
        out[rows], pending[rows] = w[enough], False
    return out


def calibration_width(a_deg: ArrayLike, scores: ArrayLike, level: float, step_deg: float) -> float:
    """The local calibration's kernel width in A, chosen by the check rings themselves: each ring's
    scale from the others (leave one ring out) at widths of 1 to 8 A steps and inf (the campaign's
    scale everywhere); the width whose rings hold closest to `level` of their own points, ring by
    ring (mean squared difference), the widest among equals. Localising helps only where what
    the cross-validation misses changes along A more than the rings' scatter: otherwise the
    campaign's scale wins."""
    a, s = np.asarray(a_deg, dtype=float), np.asarray(scores, dtype=float)
    widths = [float("inf")] + ([step_deg * 2.0 ** (i / 2.0) for i in range(6, -1, -1)] if np.isfinite(step_deg) and step_deg > 0 else [])
    losses = []
    for width in widths:
        scale = weighted_quantile(s, local_calibration_weights(a, a, width, leave_out=True), level)
        losses.append(float(np.mean((np.mean(s <= scale[:, None], axis=1) - level) ** 2)))
    return widths[int(np.argmin(losses))]  # the first of equals: the widest


def weighted_quantile(scores: ArrayLike, weights: ArrayLike, level: float) -> NDArray[np.float64]:
    """(q,) the smallest score s with which `level` of the weight lies at scores <= s: the N points of
    ring j (scores (m, N)) share its weight weights[:, j] (q, m) equally. A score may be inf (no scale
    holds that point)."""
    s = np.asarray(scores, dtype=float)
    w = np.asarray(weights, dtype=float)
    flat = s.ravel()
    order = np.argsort(flat, kind="stable")
    cumulative = np.cumsum(np.repeat(w / s.shape[1], s.shape[1], axis=1)[:, order], axis=1)  # (q, m N) in score order
    first = np.argmax(cumulative >= level * cumulative[:, -1:] * (1.0 - 1e-12), axis=1)
    return flat[order][first]


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
    chunks = (
        [values[f::folds] for f in range(folds)]
        if folds is not None and values.size > folds
        else [values[i : i + 1] for i in range(values.size)]
    )
    return [rings[np.isin(a, chunk)] for chunk in chunks]


def a_step(orientations: NDArray[np.float64]) -> float:
    """The training lattice's A step (deg), inf when the rings hold one A value."""
    a_axis, _ = lattice_axes(orientations)
    return float(np.median(np.diff(a_axis))) if a_axis.size > 1 else float("inf")


def ring_noise_variance(campaign: Campaign) -> NDArray[np.float64]:
    """(n_o,) per-point variance of each ring's mean curve before the circle fit (docs/methods/out_of_sample_error.md)."""
    n, r = campaign.n_points, campaign.n_repetitions
    post_fit = np.mean(campaign.repetition_sigma() ** 2, axis=1)
    return post_fit * n / (n - 3.0) / r


def out_of_sample_error(
    make_model: Callable[[], DeviationModel], campaign: Campaign, train: ArrayLike, folds: int | None = FOLDS, strict: bool = True
) -> OutOfSampleError:
    """The model's error at its training rings by the cross-validation in folds and along A (method:
    docs/methods/out_of_sample_error.md)."""
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
    arrays: dict[str, NDArray] = {"n_repetitions": np.array(int(n_repetitions)), "models": np.array(sorted(errors))}
    for name, error in errors.items():
        arrays.update(error.arrays(name))
    return save_arrays(directory, FILE_NAME, **arrays)


def load_errors(directory: str | Path, models: Mapping[str, DeviationModel] | None = None) -> tuple[dict[str, OutOfSampleError], int]:
    """(name -> OutOfSampleError, repetitions of the training campaign) from directory/uncertainty.npz.
    A model's error from its posterior (PosteriorError) needs the model (`models`), else it is left out."""
    with np.load(Path(directory) / FILE_NAME, allow_pickle=False) as data:
        errors = {}
        for name in (str(n) for n in data["models"]):
            posterior = bool(data[f"{name}.posterior"]) if f"{name}.posterior" in data else False
            if posterior and (models is None or name not in models):
                continue
            # Files written before the calibration off the lattice have no scale: 1, not calibrated.
            error = OutOfSampleError(
                data[f"{name}.orientations"],
                data[f"{name}.power"],
                float(data[f"{name}.width_deg"]),
                float(data[f"{name}.scale"]) if f"{name}.scale" in data else 1.0,
                int(data[f"{name}.calibration_rings"]) if f"{name}.calibration_rings" in data else 0,
                # Files written before the local calibration hold the campaign's scale alone.
                data[f"{name}.calibration_a_deg"] if f"{name}.calibration_a_deg" in data else None,
                data[f"{name}.calibration_scores"] if f"{name}.calibration_scores" in data else None,
                float(data[f"{name}.calibration_level"]) if f"{name}.calibration_level" in data else 0.95,
                float(data[f"{name}.calibration_width_deg"]) if f"{name}.calibration_width_deg" in data else float("inf"),
            )
            errors[name] = PosteriorError(**vars(error), model=models[name]) if posterior else error  # type: ignore[index]
        return errors, int(data["n_repetitions"])
