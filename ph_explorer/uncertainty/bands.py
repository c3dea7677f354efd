"""Monte Carlo bands with every component, their budget, and how often they hold measurements.

A model's band at an orientation (JCGM 101, adaptive Monte Carlo of
`ph_explorer.uncertainty.montecarlo`): one trial is the model's systematic curve plus three
independent components after the circle fit, in um: repeatability, the model's own error
(`ph_explorer.uncertainty.model_error`, calibrated by `calibrate_model_error`) and, for a hybrid,
its parameters. The "touch" band bounds one touch's deviation, the "mean" band the mean curve of
R repetitions; the budget lists each component's standard uncertainty.

Method: docs/methods/bands.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtri  # the normal quantile, as scipy.stats.norm.ppf gives it, without importing scipy.stats

from ph_explorer.campaign import Campaign
from ph_explorer.models.deviation_model import DeviationModel, as_orientations, draw_repetitions
from ph_explorer.uncertainty.model_error import (
    MIN_CALIBRATION_RINGS,
    OutOfSampleError,
    harmonic_power,
    own_error,
    random_phase_curves,
)
from ph_explorer.uncertainty.montecarlo import MAX_TRIALS, adaptive_monte_carlo
from ph_explorer.uncertainty.parameter_spread import ParameterSpread

COMPONENTS = ("repeatability", "model", "parameters")
MAX_SCALE = 1e6  # the model error's calibration: a variance a million times the cross-validation's is not an estimate
# Order of the quantities of one trial: two bands and the components (repeatability twice: touch, mean).
QUANTITIES = ("touch", "mean", "repeatability", "repeatability_mean", "model", "parameters")


@dataclass(frozen=True)
class Sources:
    """What a model's Monte Carlo draws from at one orientation, beside the model itself."""

    model: DeviationModel
    n_repetitions: int  # R: the mean band bounds the mean of R repetitions
    error: OutOfSampleError | None = None  # None: no model component
    parameters: ParameterSpread | None = None  # None: no parameters component
    # Per (A, B, N): the model component's power and the parameters' root, made once, not per batch.
    _cache: dict[tuple[float, float, int], tuple[Any, Any]] = field(default_factory=dict, repr=False, compare=False)

    def model_power(self, orientation: NDArray[np.float64]) -> NDArray[np.float64] | None:
        """The model component's power per harmonic: the out-of-sample error beyond the parameters."""
        if self.error is None:
            return None
        power = self.error.variance(orientation)[0]
        if self.parameters is not None:
            power = np.maximum(power - self.parameters.power(orientation, self.error.n_points), 0.0)
        return power

    def components(self, orientation: ArrayLike, n_trials: int, n_points: int, rng: np.random.Generator) -> dict[str, NDArray[np.float64]]:
        """Draws (n_trials, n_points) of each component at one orientation, um, after the circle fit."""
        o = as_orientations(orientation)
        sigma = self.model.repetition_sigma(o, n_points=n_points)
        zero = np.zeros((1, n_points))
        key = (float(o[0, 0]), float(o[0, 1]), n_points)
        if key not in self._cache:
            root = None if self.parameters is None else self.parameters.root(o, n_points)
            self._cache[key] = (self.model_power(o), root)
        power, root = self._cache[key]
        return {
            "repeatability": draw_repetitions(zero, sigma, n_trials, rng)[0],
            "repeatability_mean": draw_repetitions(zero, sigma / np.sqrt(self.n_repetitions), n_trials, rng)[0],
            "model": np.zeros((n_trials, n_points)) if power is None else random_phase_curves(power, n_trials, n_points, rng),
            "parameters": np.zeros((n_trials, n_points)) if root is None else rng.standard_normal((n_trials, root.shape[1])) @ root.T,
        }


@dataclass(frozen=True)
class Band:
    """One orientation's band (lower/upper arrays over the points, um), per component and in all."""

    model: str
    orientation: tuple[float, float]
    level: float
    n_repetitions: int
    prediction: NDArray[np.float64]  # (N,)
    lower: dict[str, NDArray[np.float64]]  # QUANTITIES -> (N,): prediction + that draw's lower quantile
    upper: dict[str, NDArray[np.float64]]
    budget_um: dict[str, float]
    trials: int
    converged: bool

    def as_dict(self) -> dict[str, Any]:
        """The JSON of `ph-explorer uncertainty` for this band (issue 17): bounds, R, budget."""
        return {
            "A_deg": self.orientation[0],
            "B_deg": self.orientation[1],
            "model": self.model,
            "touch_lower_um": _rounded(self.lower["touch"]),
            "touch_upper_um": _rounded(self.upper["touch"]),
            "mean_lower_um": _rounded(self.lower["mean"]),
            "mean_upper_um": _rounded(self.upper["mean"]),
            "mean_of_repetitions": self.n_repetitions,
            "budget_um": {k: round(v, 5) for k, v in self.budget_um.items()},
        }


def _rounded(values: NDArray[np.float64]) -> list[float]:
    return [round(float(v), 5) for v in values]


def orientation_band(
    sources: Sources,
    orientation: ArrayLike,
    level: float = 0.95,
    n_points: int | None = None,
    rng: np.random.Generator | None = None,
    ndig: int = 2,
    max_trials: int = MAX_TRIALS,
) -> Band:
    """The band at one orientation, by adaptive Monte Carlo over every quantity of QUANTITIES."""
    o = as_orientations(orientation)
    n = sources.model.n_points if n_points is None else int(n_points)
    prediction = sources.model.predict(o, n_points=n)[0]

    def draw(n_trials: int, generator: np.random.Generator) -> NDArray[np.float64]:
        c = sources.components(o, n_trials, n, generator)
        shared = c["model"] + c["parameters"]
        totals = [c["repeatability"] + shared, c["repeatability_mean"] + shared]
        return np.concatenate(totals + [c[q] for q in QUANTITIES[2:]], axis=1)

    result = adaptive_monte_carlo(draw, level, rng, ndig, max_trials=max_trials)
    lower = {q: prediction + result.lower[i * n : (i + 1) * n] for i, q in enumerate(QUANTITIES)}
    upper = {q: prediction + result.upper[i * n : (i + 1) * n] for i, q in enumerate(QUANTITIES)}
    # Standard uncertainty of each quantity: the rms over the points of its standard deviation.
    u = {q: float(np.sqrt(np.mean(result.sd[i * n : (i + 1) * n] ** 2))) for i, q in enumerate(QUANTITIES)}
    budget = {
        "repeatability": u["repeatability"],
        "repeatability_mean": u["repeatability_mean"],
        "model": u["model"],
        "parameters": u["parameters"],
        "combined_touch": u["touch"],
        "combined_mean": u["mean"],
    }
    return Band(
        sources.model.name,
        (float(o[0, 0]), float(o[0, 1])),
        level,
        sources.n_repetitions,
        prediction,
        lower,
        upper,
        budget,
        result.trials,
        result.converged,
    )


def model_bands(
    sources: Sources,
    orientations: ArrayLike,
    level: float = 0.95,
    n_points: int | None = None,
    rng: np.random.Generator | None = None,
    ndig: int = 2,
    max_trials: int = MAX_TRIALS,
) -> list[Band]:
    """The band at every orientation (a loop over orientations: each has its own stopping rule)."""
    rng = np.random.default_rng() if rng is None else rng
    return [orientation_band(sources, o, level, n_points, rng, ndig, max_trials) for o in as_orientations(orientations)]


def band_coverage(bands: list[Band], deviations: ArrayLike, band: str = "touch") -> dict[str, float]:
    """Fractions of measured single touches and of measured mean-curve points inside the bands.

    deviations: (m, R, N) the measurements at the bands' orientations. band: "touch" for the full
    band (its mean counterpart "mean"), "repeatability" for the noise-only band of today.
    """
    d = np.asarray(deviations, dtype=float)
    mean_key = "mean" if band == "touch" else f"{band}_mean"
    lo_t = np.stack([b.lower[band] for b in bands])[:, None, :]
    hi_t = np.stack([b.upper[band] for b in bands])[:, None, :]
    lo_m = np.stack([b.lower[mean_key] for b in bands])
    hi_m = np.stack([b.upper[mean_key] for b in bands])
    mean = d.mean(axis=1)
    return {
        "touch": float(np.mean((d >= lo_t) & (d <= hi_t))),
        "mean": float(np.mean((mean >= lo_m) & (mean <= hi_m))),
    }


def band_variance(
    sources: Sources,
    orientations: ArrayLike,
    n_points: int,
    band: str = "touch",
    components: tuple[str, ...] = COMPONENTS,
    scale: float | None = None,
) -> NDArray[np.float64]:
    """(m, N) per-point variance (um^2) of a band's draw: "touch" (one touch) or "mean" (of R).

    The components are Gaussian and independent, so the variances add: repeatability sigma^2
    (sigma^2 / R for the mean; sigma is the post-fit spread), the model's random-phase curve
    sum_k max(s P_k - Q_k, 0) at every point (s the error's scale at the orientation, or `scale`; Q_k the parameters'
    power, which the hybrid's cross-validated error holds), the parameters' per-point variance.
    The Monte Carlo band's quantiles of these components are +-z sqrt(variance) (tested).
    """
    o = as_orientations(orientations)
    fixed, power, q = _variance_parts(sources, o, n_points, band, components)
    if power is None:
        return fixed
    return fixed + _model_variance(power, q, sources.error.scale_at(o) if scale is None else scale)  # type: ignore[union-attr]


def _variance_parts(
    sources: Sources, o: NDArray[np.float64], n_points: int, band: str, components: tuple[str, ...]
) -> tuple[NDArray[np.float64], NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """What band_variance adds up, made once (a calibration varies only the scale): the variance that
    does not scale (m, N), the model error's unscaled power per harmonic 2..N/2 (m, K) or None, and
    the parameters' power there (m, K) or None."""
    sigma = np.broadcast_to(np.asarray(sources.model.repetition_sigma(o, n_points=n_points), dtype=float), (len(o), n_points))
    fixed = np.zeros((len(o), n_points))
    if "repeatability" in components:
        fixed += sigma**2 / (sources.n_repetitions if band == "mean" else 1)
    roots = None
    if sources.parameters is not None:
        roots = np.stack([sources.parameters.root(o[i : i + 1], n_points) for i in range(len(o))])  # (m, N, q)
        if "parameters" in components:
            fixed += np.sum(roots**2, axis=2)
    if sources.error is None or "model" not in components:
        return fixed, None, None
    harmonics = slice(2, n_points // 2 + 1)
    power = sources.error.base_power(o)[:, harmonics]
    q = None if roots is None else harmonic_power(np.swapaxes(roots, 1, 2)).sum(axis=1)[:, harmonics]
    return fixed, power, q


def _model_variance(power: NDArray[np.float64], q: NDArray[np.float64] | None, scale: ArrayLike) -> NDArray[np.float64]:
    """The model's random-phase curve's variance at every point, sum_k max(s P_k - Q_k, 0), for one
    scale s (a number: (m, 1)), one per orientation ((m,): (m, 1)) or one per point ((m, N): (m, N))."""
    s = np.asarray(scale, dtype=float)
    s = np.full((power.shape[0], 1), float(s)) if s.ndim == 0 else s.reshape(power.shape[0], -1)
    scaled = s[..., None] * power[:, None, :]
    if q is not None:
        scaled = np.maximum(scaled - q[:, None, :], 0.0)
    return scaled.sum(axis=2)


def gaussian_band(
    sources: Sources,
    orientation: ArrayLike,
    level: float = 0.95,
    n_points: int | None = None,
    band: str = "touch",
    components: tuple[str, ...] = COMPONENTS,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(lower, upper) over the points, um: the band of `orientation_band` without its Monte Carlo
    (prediction +- z sqrt(band_variance)): instant, for the explorer's slider."""
    o = as_orientations(orientation)[:1]
    n = sources.model.n_points if n_points is None else int(n_points)
    prediction = sources.model.predict(o, n_points=n)[0]
    half = float(ndtri(0.5 + level / 2.0)) * np.sqrt(band_variance(sources, o, n, band, components)[0])
    return prediction - half, prediction + half


def calibrate_model_error(sources: Sources, orientations: ArrayLike, mean_curves: ArrayLike, level: float = 0.95) -> Sources:
    """The sources with the model error's size calibrated on held-out rings (split-conformal).

    orientations (m, 2), mean_curves (m, N): rings the model was not fitted on, measured off its
    lattice. Each mean-curve point scores the smallest scale of the model error's variance with which
    it lies inside the mean band (MAX_SCALE when none up to it does); the `level` quantile of the
    scores is the scale (`scale`, and weighted by the kernel in A, `OutOfSampleError.scale_at`). Rings
    used here must not be those a coverage is then measured on. With fewer than MIN_CALIBRATION_RINGS
    rings the sources are returned as they are (`calibration_rings` 0).

    Method: docs/methods/bands.md.
    """
    o = as_orientations(orientations)
    if sources.error is None or len(o) < MIN_CALIBRATION_RINGS:
        return sources
    curves = np.asarray(mean_curves, dtype=float)
    n = curves.shape[-1]
    residual = np.abs(curves - sources.model.predict(o, n_points=n))
    z = float(ndtri(0.5 + level / 2.0))
    fixed, power, q = _variance_parts(sources, o, n, "mean", COMPONENTS)
    needed = (residual / z) ** 2 - fixed  # (m, N) what the model error must add at each point
    # The model's variance grows with s (piecewise linearly): bisect every point at once.
    low, high = np.zeros_like(needed), np.full_like(needed, MAX_SCALE)
    for _ in range(80):  # to ~1e-18 of MAX_SCALE: far below any scale that matters
        middle = 0.5 * (low + high)
        short = _model_variance(power, q, middle) < needed  # type: ignore[arg-type]
        low, high = np.where(short, middle, low), np.where(short, high, middle)
    scores = np.where(needed <= 0.0, 0.0, high)  # a point no scale holds ends at MAX_SCALE
    error = sources.error.calibrated(o[:, 0], scores, level)
    return replace(sources, error=error, _cache={})


def calibrated_model_error(
    make_model: Callable[[], DeviationModel], model: DeviationModel, campaign: Campaign, train: ArrayLike, level: float = 0.95
) -> OutOfSampleError:
    """A model's own error (`model_error.own_error`: its posterior's, or out of sample on the training
    rings), its size calibrated on the campaign's rings left out of training (`calibrate_model_error`;
    with fewer than MIN_CALIBRATION_RINGS of them, the size before calibration). `model` is the one
    fitted on `train`, `make_model` makes an unfitted one for the cross-validation."""
    error = own_error(make_model, model, campaign, train)
    held = ~np.asarray(train, dtype=bool)
    sources = Sources(model, campaign.n_repetitions, error)
    return calibrate_model_error(sources, campaign.orientations[held], campaign.mean_curves()[held], level).error  # type: ignore[return-value]
