"""How far a predicted deviation curve is from the measurements, and the floor no model can beat.

The one place for the figures the paper's Table 3, the diagnosis, the app and the benchmarks
report: the mean absolute error (MAE) against the repetition mean and against single
repetitions, the pooled repetition sigma, and the noise floors: E|e| of the touch noise a
perfect model still meets, 0.80 sigma for Gaussian noise (0.80 sigma / sqrt(n) against the mean
of n), less for heavier tails (0.64 sigma for Student-t of 3 degrees of freedom), so the floor
reads the noise's law from the repetitions. Method: docs/methods/noise_floor.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special

# E|e| / sigma for a zero-mean Gaussian error e.
MEAN_ABS_PER_SIGMA = math.sqrt(2.0 / math.pi)
REFERENCES = ("mean", "single")
LAW_QUANTILES = 1000  # the touch noise's law, kept as this many quantiles of its residuals
MEAN_DRAWS = 20000  # means of n draws of the law: its repetition mean's law (noise_floor)
SPREAD_STEPS = 17  # spreads at which expected_abs computes, interpolated between


def pooled_sigma(deviations: ArrayLike) -> float:
    """Pooled repetition standard deviation per touch (um) of (n_o, n_rep, n_pt) deviations; NaN for one repetition."""
    d = np.asarray(deviations, dtype=float)
    if d.shape[1] < 2:
        return float("nan")
    return float(np.sqrt(np.mean(d.var(axis=1, ddof=1))))


def noise_law(deviations: ArrayLike) -> NDArray[np.float64] | None:
    """The touch noise's law: LAW_QUANTILES quantiles of every touch's residual about its
    repetition mean, over their rms (None: one repetition, no spread). A residual is partly the
    other repetitions' mean, near Gaussian: with few repetitions the law reads a little nearer the
    Gaussian than it is (a heavy tail's floor a little high, never low)."""
    d = np.asarray(deviations, dtype=float)
    if d.shape[1] < 2:
        return None
    residual = (d - d.mean(axis=1, keepdims=True)).ravel()
    rms = float(np.sqrt(np.mean(residual**2)))
    if not rms > 0:
        return None
    return np.quantile(residual / rms, (np.arange(LAW_QUANTILES) + 0.5) / LAW_QUANTILES)


def expected_abs(draws: NDArray[np.float64], spread: ArrayLike) -> NDArray[np.float64]:
    """E|e + g| for e of these draws and g ~ N(0, spread^2), per spread: the folded normal's mean
    about each draw, averaged; computed at SPREAD_STEPS spreads and interpolated in spread^2 (it
    is smooth there), so that many rings cost no more than a few."""
    s = np.asarray(spread, dtype=float)
    grid = np.sqrt(np.linspace(0.0, float(np.max(s, initial=0.0)) ** 2, SPREAD_STEPS))
    x, at = draws[:, None], np.maximum(grid[None, :], 1e-12)
    folded = at * MEAN_ABS_PER_SIGMA * np.exp(-0.5 * (x / at) ** 2) + x * special.erf(x / (at * math.sqrt(2.0)))
    return np.interp(s**2, grid**2, folded.mean(axis=0))


def noise_floor(
    sigma_um: float, n_repetitions: int, neighbour_weights_sq: ArrayLike | None = None, law: NDArray[np.float64] | None = None
) -> dict[str, Any]:
    """The lowest MAE (um) a perfect model can reach against the mean of n repetitions and a single one.

    neighbour_weights_sq: for a prediction made of other rings' means (an out-of-sample one), the
    sum of its squared weights per ring: the prediction carries their noise too (near Gaussian), so
    the floor is E|e| of both together (arrays per ring then). law: the touch noise's (noise_law;
    None: Gaussian); the mean of n repetitions is then read from MEAN_DRAWS means of n of its draws.
    """
    sigma, n = float(sigma_um), max(int(n_repetitions), 1)
    w = 0.0 if neighbour_weights_sq is None else np.asarray(neighbour_weights_sq, dtype=float)
    mean, single = MEAN_ABS_PER_SIGMA * sigma * np.sqrt((1 + w) / n), MEAN_ABS_PER_SIGMA * sigma * np.sqrt(1 + w / n)
    if law is not None:
        spread = np.sqrt(w / n)  # the prediction's noise, in sigmas
        # The same means drawn of the Gaussian's quantiles take the draws' own scatter out of the
        # mean's floor (a control variate): a Gaussian law gives the Gaussian's floor.
        gaussian = special.ndtri((np.arange(law.size) + 0.5) / law.size)
        drawn = np.random.default_rng(0).integers(0, law.size, (MEAN_DRAWS, n))
        means = [(q[drawn] / np.sqrt(np.mean(q**2))).mean(axis=1) for q in (law, gaussian)]
        mean = mean + sigma * (expected_abs(means[0], spread) - expected_abs(means[1], spread))
        single = sigma * expected_abs(law, spread)
    if neighbour_weights_sq is None:
        return {"mean": float(mean), "single": float(single)}
    return {"mean": mean, "single": single}


def ring_mae(predicted: ArrayLike, measured: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """Each ring's MAE (um) against the repetition mean and against single repetitions (averaged over them).

    predicted: (n_o, n_pt) one curve per ring, or (n_o, n_rep, n_pt) touch by touch (a model whose
    terms change between repetitions); measured: (n_o, n_rep, n_pt).
    """
    m = np.asarray(measured, dtype=float)
    p = np.asarray(predicted, dtype=float)
    if p.ndim == 2:
        p = p[:, None, :]
    return {
        "mean": np.abs(p.mean(axis=1) - m.mean(axis=1)).mean(axis=1),
        "single": np.abs(p - m).mean(axis=(1, 2)),
    }


def mae(predicted: ArrayLike, measured: ArrayLike) -> dict[str, float]:
    """The MAE (um) over all the given rings against both references (see ring_mae)."""
    return {k: float(v.mean()) for k, v in ring_mae(predicted, measured).items()}
