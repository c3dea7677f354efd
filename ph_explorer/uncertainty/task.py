"""A measurement task's uncertainty (ISO/TS 15530-4 spirit): a circle measured by head touches.

The ring at orientation (A, B) measured once with N touches: each Monte Carlo trial is the model's
systematic curve plus one draw of every component of its band (`bands.Sources`), put through the
circle fit; its RONt and harmonics 2..K are the outputs, each with estimate y, standard
uncertainty u, coverage interval and U = k u, k = 2. Validated on measured rings by the normalised
error E_n = |y_sim - y_meas| / sqrt(U_sim^2 + U_meas^2) (E_n <= 1: agreement).

Method: docs/methods/task_uncertainty.md.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.harmonics import harmonic_spectrum, ron_t
from ph_explorer.models.deviation_model import as_orientations
from ph_explorer.uncertainty.bands import Sources
from ph_explorer.uncertainty.montecarlo import MAX_TRIALS, adaptive_monte_carlo

COVERAGE_FACTOR = 2.0
MAX_HARMONIC = 15


def task_outputs(curves: NDArray[np.float64], max_harmonic: int = MAX_HARMONIC) -> NDArray[np.float64]:
    """(..., 1 + K - 1): RONt and the amplitudes of harmonics 2..K of measured circles (..., N), um."""
    amplitude, _ = harmonic_spectrum(curves)
    k = min(max_harmonic, curves.shape[-1] // 2)
    return np.concatenate([ron_t(curves)[..., None], amplitude[..., 2 : k + 1]], axis=-1)


def task_uncertainty(
    sources: Sources,
    orientation: ArrayLike,
    n_points: int | None = None,
    level: float = 0.95,
    k: float = COVERAGE_FACTOR,
    max_harmonic: int = MAX_HARMONIC,
    rng: np.random.Generator | None = None,
    ndig: int = 2,
    max_trials: int = MAX_TRIALS,
) -> dict[str, Any]:
    """RONt and harmonics 2..K of one N-touch measurement at the orientation: value, U (k = 2), interval."""
    o = as_orientations(orientation)
    n = sources.model.n_points if n_points is None else int(n_points)
    prediction = sources.model.predict(o, n_points=n)

    def draw(n_trials: int, generator: np.random.Generator) -> NDArray[np.float64]:
        c = sources.components(o, n_trials, n, generator)
        return task_outputs(prediction + c["repeatability"] + c["model"] + c["parameters"], max_harmonic)

    result = adaptive_monte_carlo(draw, level, rng, ndig, max_trials=max_trials)

    def entry(i: int) -> dict[str, float]:
        return {
            "value": round(float(result.mean[i]), 5),
            "U": round(float(k * result.sd[i]), 5),
            "lower": round(float(result.lower[i]), 5),
            "upper": round(float(result.upper[i]), 5),
        }

    return {
        "A_deg": float(o[0, 0]),
        "B_deg": float(o[0, 1]),
        "points": n,
        "ront_um": entry(0),
        "harmonics_um": {str(h): entry(i + 1) for i, h in enumerate(range(2, 2 + result.mean.size - 1))},
        "k": k,
        "trials": result.trials,
        "converged": result.converged,
    }


def measured_task(deviations: ArrayLike, k: float = COVERAGE_FACTOR, max_harmonic: int = MAX_HARMONIC) -> dict[str, NDArray[np.float64]]:
    """Measured rings (m, R, N): each output's mean over the repetitions and its U = k s / sqrt(R), (m, q)."""
    d = np.asarray(deviations, dtype=float)
    outputs = task_outputs(d, max_harmonic)  # (m, R, q)
    r = d.shape[1]
    spread = outputs.std(axis=1, ddof=1) if r > 1 else np.full(outputs.shape[::2], np.nan)
    return {"value": outputs.mean(axis=1), "U": k * spread / np.sqrt(r), "single": outputs}


def normalised_error(simulated: ArrayLike, u_simulated: ArrayLike, measured: ArrayLike, u_measured: ArrayLike) -> NDArray[np.float64]:
    """E_n = |y_sim - y_meas| / sqrt(U_sim^2 + U_meas^2), elementwise."""
    diff = np.abs(np.asarray(simulated, dtype=float) - np.asarray(measured, dtype=float))
    return diff / np.sqrt(np.asarray(u_simulated, dtype=float) ** 2 + np.asarray(u_measured, dtype=float) ** 2)
