"""Piecewise linear functions on knots, and the roughness coordinates their fits are penalised in.

A tabulated error function (effects/error_functions.py) is linear between values at its knots
(evenly around a full turn when periodic); its basis columns are hat functions, each touch on the
two knots around it. Its coefficients are the values in roughness coordinates z = L' v, L L' =
D'D + I, so that a ridge |z|^2 penalises the values and their steps from knot to knot (a
P-spline's, Eilers and Marx 1996; docs/methods/shapes.md). A curve known in advance (a shape found,
then added) is refitted in the metric of its own steps (curve_roughness_factor).
"""

from __future__ import annotations

from functools import cache

import numpy as np
from numpy.typing import NDArray

from ph_explorer.geometry import wrap_deg

# A curve known in advance (curve_roughness_factor): its steps penalised this much more than its
# values, and a step below this share of its typical step counted as this share (no step is free).
CURVE_TRUST = 100.0
STEP_FLOOR = 0.05


def hat_neighbours(x: NDArray[np.float64], knots: NDArray[np.float64], periodic: bool) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """((..., 2) knot indices, (..., 2) weights): the two knots around each x and its piecewise
    linear interpolation weights on them (they sum to 1); beyond the knots' range a function holds
    its end value (nothing is known of its trend there: a probe term of time is taken as last
    seen); periodic: the knots span a full turn of an angle (deg), evenly."""
    knots = np.asarray(knots, dtype=float)
    x = np.asarray(x, dtype=float)
    count = knots.size
    if periodic:
        step = 360.0 / count
        first = np.floor((wrap_deg(x) - knots[0]) / step).astype(np.intp) % count
        index = np.stack([first, (first + 1) % count], axis=-1)
        return index, np.maximum(0.0, 1.0 - np.abs(wrap_deg(x[..., None] - knots[index])) / step)
    x = np.clip(x, knots[0], knots[-1])
    first = np.clip(np.searchsorted(knots, x, side="right") - 1, 0, count - 2)
    index = np.stack([first, first + 1], axis=-1)
    gap = (knots[first + 1] - knots[first])[..., None]
    d = x[..., None] - knots[index]
    return index, np.maximum(0.0, 1.0 - np.abs(d) / gap)


def hat_functions(x: NDArray[np.float64], knots: NDArray[np.float64], periodic: bool) -> NDArray[np.float64]:
    """(..., K): the hat functions of the knots at x, each row zero but at hat_neighbours' two knots."""
    index, weight = hat_neighbours(x, knots, periodic)
    hats = np.zeros(index.shape[:-1] + (len(knots),))
    np.put_along_axis(hats, index[..., :1], weight[..., :1], axis=-1)
    np.put_along_axis(hats, index[..., 1:], weight[..., 1:], axis=-1)  # K = 1: both are the one knot, alike
    return hats


def _differences(count: int, periodic: bool) -> NDArray[np.float64]:
    """D: the knot-to-knot steps of K values, (K, K) around the turn when periodic, else (K - 1, K)."""
    eye = np.eye(count)
    return eye - np.roll(eye, 1, axis=1) if periodic else np.diff(eye, axis=0)


@cache
def roughness_factor(count: int, periodic: bool) -> NDArray[np.float64]:
    """L (K, K), lower triangular, with L L' = D'D + I: D the first differences of K knot values
    (around the turn when periodic). Coefficients z = L' v of the values v make a ridge |z|^2 the
    penalty v'v + v'D'Dv: on the values, as before, and on their steps from knot to knot (a
    P-spline's, Eilers and Marx 1996); the columns are X L^-T (docs/methods/shapes.md)."""
    difference = _differences(count, periodic)
    factor = np.linalg.cholesky(difference.T @ difference + np.eye(count))
    factor.flags.writeable = False
    return factor


def curve_roughness_factor(values: NDArray[np.float64], periodic: bool) -> NDArray[np.float64] | None:
    """L with L L' = I + CURVE_TRUST D'WD for a curve known in advance, values (C, K) at its knots
    (None: a flat curve, no steps to weigh). W weighs each knot-to-knot step by the inverse of the
    curve's own step there (all its components together), over their rms: a step the curve takes
    stays sharp and a flat stretch stays flat, where D'D alone would spread a step over the knots
    around it. It is one iteratively reweighted step towards a total-variation penalty (Rudin,
    Osher and Fatemi 1992); docs/methods/shapes.md."""
    count = values.shape[-1]
    difference = _differences(count, periodic)
    step = np.sqrt(((values @ difference.T) ** 2).sum(axis=0))  # (K - 1,) or (K,)
    typical = float(np.sqrt(np.mean(step**2)))
    if not typical > 0:
        return None
    weight = typical / np.maximum(step, STEP_FLOOR * typical)
    factor = np.linalg.cholesky(CURVE_TRUST * difference.T @ (weight[:, None] * difference) + np.eye(count))
    factor.flags.writeable = False
    return factor


def roughness(values: NDArray[np.float64], periodic: bool) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(L, L^-T) for a function whose known values (C, K) are these: their curve's
    (curve_roughness_factor), or the knots' plain one (roughness_factor) for a flat curve."""
    factor = curve_roughness_factor(values, periodic)
    factor = roughness_factor(values.shape[-1], periodic) if factor is None else factor
    inverse_t = np.linalg.inv(factor).T
    inverse_t.flags.writeable = False
    return factor, inverse_t
