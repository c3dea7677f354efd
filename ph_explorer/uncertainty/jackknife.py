"""Expanded uncertainties of an effect's fitted physical parameters, by the jackknife.

The fit is repeated without each orientation's ring in turn (the ring is the independent unit);
the spread of the physical parameters (`effect.from_coefficients`) over those delete-one fits
gives se^2 = (n - 1) / n * sum_j (theta_j - mean_j theta)^2, and U = k se with k = 2. Parameters
with a `period` are compared modulo it; parameters the fit does not change get U = 0.
`ph_explorer.models.least_squares.jackknife` gives the coefficients `jackknife_parameters` takes.

Method: docs/methods/jackknife.md.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect

COVERAGE_FACTOR = 2.0


def jackknife_parameters(
    effect: Effect,
    coefficients_without: NDArray[np.float64],
    coefficients_all: NDArray[np.float64],
    k: float = COVERAGE_FACTOR,
) -> tuple[dict[str, float], dict[str, float]]:
    """(params, params_u): the physical parameters of the full fit and their expanded uncertainty.

    coefficients_without: (n_groups, c), the basis coefficients fitted without each group (e.g.
    each ring, from models.design.jackknife); coefficients_all: (c,), the fit on every group.
    params = effect.from_coefficients(coefficients_all); params_u[name] = k * the jackknife
    standard error of that parameter over the n_groups delete-one fits, in the parameter's own
    unit (a phase's wraps around its `period`). With fewer than two groups the uncertainty is
    unknown: NaN. A parameter that is NaN in some delete-one fit (e.g. a ratio to an amplitude
    of exactly 0) gets NaN.
    """
    without = np.asarray(coefficients_without, dtype=float)
    if without.ndim != 2:
        raise ValueError(f"coefficients_without must be (n_groups, c), got shape {without.shape}")
    full = {name: float(value) for name, value in effect.from_coefficients(np.asarray(coefficients_all, dtype=float)).items()}
    n = without.shape[0]
    if n < 2:
        return full, {name: float("nan") for name in full}

    fits = [effect.from_coefficients(row) for row in without]
    periods = {p.name: p.period for p in effect.parameters}
    scanned = set(effect.scan)
    uncertainty: dict[str, float] = {}
    for name, value in full.items():
        if name in scanned:
            uncertainty[name] = 0.0  # a chosen setting, not fitted
            continue
        theta = np.array([float(fit.get(name, np.nan)) for fit in fits])
        period = periods.get(name)
        if period is not None and np.isfinite(value):
            # Each delete-one value as its nearest copy to the full fit's value.
            theta = value + (theta - value + 0.5 * period) % period - 0.5 * period
        uncertainty[name] = k * jackknife_standard_error(theta)
    return full, uncertainty


def jackknife_standard_error(theta: NDArray[np.float64]) -> float:
    """sqrt((n - 1) / n * sum (theta_j - mean theta)^2) over delete-one values theta (n,); 0 when
    they are all equal, NaN when any is NaN or n < 2."""
    theta = np.asarray(theta, dtype=float)
    n = theta.size
    if n < 2 or not np.all(np.isfinite(theta)):
        return float("nan")
    if np.ptp(theta) == 0.0:
        return 0.0
    return float(np.sqrt((n - 1) / n * np.sum((theta - theta.mean()) ** 2)))


def jackknife_covariance(theta: NDArray[np.float64]) -> NDArray[np.float64]:
    """(c, c) jackknife covariance (n - 1) / n sum_j (theta_j - mean)(theta_j - mean)^T of delete-one
    values theta (n, c): the matrix whose diagonal is jackknife_standard_error squared."""
    theta = np.asarray(theta, dtype=float)
    n = theta.shape[0]
    centred = theta - theta.mean(axis=0)
    return (n - 1) / n * centred.T @ centred
