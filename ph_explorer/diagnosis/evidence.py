"""A candidate's evidence: the out-of-sample residual and its fitted terms, binned against the
variable the effect says its signature is read against (Effect.evidence)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.diagnosis.candidates import DIGITS
from ph_explorer.effects import Evidence

DEFAULT_BINS = 48


def binned_evidence(evidence: Evidence, residual: NDArray[np.float64], fitted: NDArray[np.float64]) -> dict[str, Any]:
    """{x_label, y_label, x, residual, fitted}: bin centres and each bin's value of both arrays.

    residual and fitted are shaped like the touches (n_o, n_rep, n_pt). Without a weight a bin's
    value is its mean (um); with one (um of deviation per unit of the plotted quantity) it is the
    weighted least squares of the radial values in that quantity.
    """
    shape = residual.shape
    x = np.broadcast_to(evidence.x, shape).ravel()
    edges = evidence.edges
    if edges is None:
        edges = np.linspace(x.min(), x.max() + 1e-9, DEFAULT_BINS + 1)
    which = np.clip(np.digitize(x, edges) - 1, 0, len(edges) - 2)
    w = np.ones_like(x) if evidence.weight is None else np.broadcast_to(evidence.weight, shape).ravel()
    norm = np.bincount(which, w * w, minlength=len(edges) - 1)
    used = norm > 1e-12 * max(norm.max(), 1e-300)

    def binned(values: NDArray[np.float64]) -> list[float]:
        sums = np.bincount(which, w * np.ravel(values), minlength=len(edges) - 1)
        return np.round(sums[used] / norm[used], DIGITS).tolist()

    centre = 0.5 * (edges[:-1] + edges[1:])
    curve = binned(np.broadcast_to(fitted, shape))
    return {
        "x_label": evidence.x_label,
        "y_label": evidence.y_label,
        "x": np.round(centre[used], 3).tolist(),
        "residual": binned(residual),
        "fitted": curve,
        # What the plot's curve reaches: the circle fit removes part of any term, so it may be less
        # than the amplitude the parameters state (which is the term before the fit).
        "fitted_peak": float(np.max(np.abs(curve), initial=0.0)),
    }
