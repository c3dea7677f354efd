"""Fourier description of deviation curves around the ring.

The paper's network outputs 1 + 2K Fourier coefficients (a0, a1, b1, ..., aK, bK) that a basis
matrix turns into the N-point deviation curve d'(n) = a0 + sum_k a_k cos(k theta_n) + b_k sin(k theta_n).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.geometry import point_angles_deg


def fourier_basis(n_points: int, k_max: int) -> NDArray[np.float64]:
    """(n_points, 1 + 2K) matrix with columns 1, cos(theta), sin(theta), ..., cos(K theta), sin(K theta)."""
    theta = np.radians(point_angles_deg(n_points))
    k = np.arange(1, k_max + 1)
    cols = np.empty((n_points, 1 + 2 * k_max))
    cols[:, 0] = 1.0
    cols[:, 1::2] = np.cos(np.outer(theta, k))
    cols[:, 2::2] = np.sin(np.outer(theta, k))
    return cols


def remove_size_and_centre(radial_um: ArrayLike) -> NDArray[np.float64]:
    """What the least-squares circle fit leaves of radial deviations of equally spaced points.

    For radial deviations that are small against the radius (um against mm), the LS circle fit is
    linear in them and removes exactly harmonics 0 (size) and 1 (centre): this projects them out
    along the last axis.
    """
    r = np.asarray(radial_um, dtype=float)
    basis = fourier_basis(r.shape[-1], 1)
    # Columns are orthogonal with norms N, N/2, N/2 for equally spaced points.
    coef = r @ basis / np.array([r.shape[-1], r.shape[-1] / 2, r.shape[-1] / 2])
    return r - coef @ basis.T
