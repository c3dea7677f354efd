"""How far a predicted deviation curve is from the measurements, and the floor no model can beat.

The one place for the figures the paper's Table 3, the diagnosis, the app and the benchmarks
report: the mean absolute error (MAE) against the repetition mean and against single
repetitions, the pooled repetition sigma, and the noise floors.

Noise floor. A perfect model predicts the systematic curve exactly; what remains against a
reference is the reference's own touch noise, Gaussian with the campaign's pooled repetition
sigma (per touch, after the circle fit). For e ~ N(0, s^2), E|e| = sqrt(2/pi) s ~ 0.80 s, so no
model can beat, on average, 0.80 sigma against single repetitions, nor 0.80 sigma / sqrt(n)
against the mean of n repetitions.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

# E|e| / sigma for a zero-mean Gaussian error e.
MEAN_ABS_PER_SIGMA = math.sqrt(2.0 / math.pi)
REFERENCES = ("mean", "single")


def pooled_sigma(deviations: ArrayLike) -> float:
    """Pooled repetition standard deviation per touch (um) of (n_o, n_rep, n_pt) deviations; NaN for one repetition."""
    d = np.asarray(deviations, dtype=float)
    if d.shape[1] < 2:
        return float("nan")
    return float(np.sqrt(np.mean(d.var(axis=1, ddof=1))))


def noise_floor(sigma_um: float, n_repetitions: int, neighbour_weights_sq: ArrayLike | None = None) -> dict[str, Any]:
    """The lowest MAE (um) a perfect model can reach against the mean of n repetitions and a single one.

    neighbour_weights_sq: for a prediction made of other rings' means (an out-of-sample one), the
    sum of its squared weights per ring: the prediction carries their noise too, so the floor is
    E|e| of both together (arrays per ring then).
    """
    single = MEAN_ABS_PER_SIGMA * float(sigma_um)
    n = max(int(n_repetitions), 1)
    if neighbour_weights_sq is None:
        return {"mean": single / math.sqrt(n), "single": single}
    w = np.asarray(neighbour_weights_sq, dtype=float)
    return {"mean": single * np.sqrt((1 + w) / n), "single": single * np.sqrt(1 + w / n)}


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
