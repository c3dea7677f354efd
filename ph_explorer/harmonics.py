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


IN_PLACE_BLOCK_BYTES = 32 * 2**20  # what the fit in place holds at once beside the array it overwrites


def remove_size_and_centre(radial_um: ArrayLike, axis: int = -1, in_place: bool = False) -> NDArray[np.float64]:
    """What the least-squares circle fit leaves of radial deviations of equally spaced points.

    For radial deviations that are small against the radius (um against mm), the LS circle fit is
    linear in them and removes exactly harmonics 0 (size) and 1 (centre): this projects them out
    along the points' axis, the last (-1) or the one before (-2: basis columns last, as effects give them).
    in_place (axis -2, a writable float64 array of 3 axes or more): overwrites it, a block of
    orientations at a time, instead of making an array as large (a dense campaign's scan library).
    """
    r = np.asarray(radial_um, dtype=float)
    n = r.shape[axis]
    basis = fourier_basis(n, 1)
    norms = np.array([n, n / 2, n / 2])  # the columns are orthogonal for equally spaced points
    if in_place:
        if r is not radial_um or not r.flags.writeable or r.ndim < 3 or axis not in (-2, r.ndim - 2):
            raise ValueError("in place needs a writable float64 array of 3 axes or more, its points the axis before the last")
        # The same products as below, ring by ring (the stacked matmul works ring by ring too).
        step = max(1, IN_PLACE_BLOCK_BYTES // max(1, r[:1].nbytes))
        for start in range(0, r.shape[0], step):
            block = r[start : start + step]
            block -= basis @ (np.matmul(basis.T, block) / norms[:, None])
        return r
    if axis in (-1, r.ndim - 1):
        out = r @ basis / norms @ basis.T
    elif axis in (-2, r.ndim - 2):  # no transposed copy of a large stack of columns
        out = basis @ (np.matmul(basis.T, r) / norms[:, None])
    else:
        raise ValueError(f"the points' axis must be the last or the one before, got {axis}")
    return np.subtract(r, out, out=out)


# -- least-squares circles -------------------------------------------------------------------


def _solve_batched(normal: NDArray[np.float64], rhs: NDArray[np.float64]) -> NDArray[np.float64]:
    """Solve a stack of small linear systems; singular ones (degenerate point sets) give NaN."""
    with np.errstate(all="ignore"):
        scale = np.abs(normal).max(axis=(-1, -2), keepdims=True)
        scale = np.where(scale > 0.0, scale, 1.0)
        singular = ~(np.abs(np.linalg.det(normal / scale)) >= 1e-13)  # NaN counts as singular
    safe = np.where(singular[..., None, None], np.eye(normal.shape[-1]), normal)
    out = np.linalg.solve(safe, rhs[..., None])[..., 0]
    return np.where(singular[..., None], np.nan, out)


def _kasa_circles(x: NDArray[np.float64], y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Algebraic (Kasa) circle fit over the last axis: (..., 3) centre x, centre y, radius.

    Solves x^2 + y^2 = 2 a x + 2 b y + c by linear least squares; a good start for the geometric fit.
    """
    design = np.stack([2.0 * x, 2.0 * y, np.ones_like(x)], axis=-1)  # (..., N, 3)
    target = x * x + y * y
    normal = np.swapaxes(design, -1, -2) @ design
    rhs = np.einsum("...ni,...n->...i", design, target)
    a, b, c = np.moveaxis(_solve_batched(normal, rhs), -1, 0)
    return np.stack([a, b, np.sqrt(np.maximum(c + a * a + b * b, 0.0))], axis=-1)


def fit_circles(x: ArrayLike, y: ArrayLike, iterations: int = 50, tol: float = 1e-13) -> NDArray[np.float64]:
    """Geometric least-squares circles of many point sets at once.

    x, y: (..., N) point coordinates (any length unit). Returns (..., 3): centre x, centre y and
    radius minimising sum (|p_i - c| - r)^2 for each set. Batched Gauss-Newton in numpy from the
    algebraic Kasa fit; for roundness data (deviations um against radii mm) it converges in 2-3
    steps. Each set is centred on its mean first so the normal equations stay well conditioned.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    x, y = np.broadcast_arrays(x, y)
    if x.shape[-1] < 3:
        raise ValueError("a circle fit needs at least 3 points")
    mx, my = x.mean(axis=-1, keepdims=True), y.mean(axis=-1, keepdims=True)
    xs, ys = x - mx, y - my
    p = _kasa_circles(xs, ys)
    for _ in range(iterations):
        dx, dy = xs - p[..., :1], ys - p[..., 1:2]
        dist = np.hypot(dx, dy)
        dist = np.where(dist == 0.0, np.finfo(float).tiny, dist)
        res = dist - p[..., 2:3]
        jac = np.stack([-dx / dist, -dy / dist, -np.ones_like(dist)], axis=-1)  # (..., N, 3)
        normal = np.swapaxes(jac, -1, -2) @ jac
        rhs = -np.einsum("...ni,...n->...i", jac, res)
        step = _solve_batched(normal, rhs)
        p = p + step
        if np.all((np.abs(step) <= tol * np.maximum(1.0, np.abs(p[..., 2:3]))) | np.isnan(step)):
            break
    return np.stack([p[..., 0] + mx[..., 0], p[..., 1] + my[..., 0], p[..., 2]], axis=-1)


def circle_deviations_um(x_mm: ArrayLike, y_mm: ArrayLike) -> NDArray[np.float64]:
    """Signed radial distance (um, positive outward) of each point from the LS circle of its own set.

    x_mm, y_mm: (..., N) in mm; returns (..., N) in um.
    """
    x = np.asarray(x_mm, dtype=float)
    y = np.asarray(y_mm, dtype=float)
    circle = fit_circles(x, y)
    dist = np.hypot(x - circle[..., :1], y - circle[..., 1:2])
    return 1000.0 * (dist - circle[..., 2:3])


# -- harmonic analysis -----------------------------------------------------------------------


def harmonic_spectrum(curves: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Amplitude (um) and phase (deg) of every harmonic 0..N//2 of curves sampled at theta_n = 360 n / N.

    curves: (..., N). Harmonic k of the curve is amplitude_k cos(k theta - phase_k), so a pure
    A cos(k (theta - theta_peak)) gives amplitude A and phase k theta_peak (wrapped to (-180, 180]).
    Harmonic 0 is the mean (phase 0 or 180 for a negative mean); the Nyquist harmonic of even N has
    no sine part.
    """
    c = np.asarray(curves, dtype=float)
    n = c.shape[-1]
    spectrum = np.fft.rfft(c, axis=-1)  # sum_n d_n exp(-i k theta_n) = N/2 (a_k - i b_k) for 0 < k < N/2
    scale = np.full(spectrum.shape[-1], 2.0 / n)
    scale[0] = 1.0 / n
    if n % 2 == 0:
        scale[-1] = 1.0 / n
    amplitude = np.abs(spectrum) * scale
    # a_k - i b_k = A (cos phi - i sin phi)  ->  phi = -angle(spectrum)
    phase = -np.degrees(np.angle(spectrum))
    phase = np.where(phase <= -180.0, phase + 360.0, phase)
    phase = np.where(amplitude > 1e-12 * np.maximum(1.0, amplitude.max(initial=0.0)), phase, 0.0)
    return amplitude, phase


def paper_fourier_fit(curves: ArrayLike, k_max: int) -> NDArray[np.float64]:
    """Least-squares coefficients (a0, a1, b1, ..., aK, bK) of the paper's 1 + 2K basis, (..., 1 + 2K).

    Works for any K and N (1 + 2K may exceed N/2; lstsq then returns the minimum-norm solution).
    """
    c = np.asarray(curves, dtype=float)
    basis = fourier_basis(c.shape[-1], k_max)
    flat = c.reshape(-1, c.shape[-1]).T
    coef, *_ = np.linalg.lstsq(basis, flat, rcond=None)
    return coef.T.reshape(*c.shape[:-1], basis.shape[1])


def fourier_curve(coefficients: ArrayLike, n_points: int) -> NDArray[np.float64]:
    """The N-point curve of paper-basis coefficients (..., 1 + 2K) -> (..., N)."""
    coef = np.asarray(coefficients, dtype=float)
    k_max = (coef.shape[-1] - 1) // 2
    return coef @ fourier_basis(n_points, k_max).T


# -- roundness (ISO 12181, least-squares reference circle) -----------------------------------


def ron_t(deviations_um: ArrayLike) -> NDArray[np.float64]:
    """RONt: peak-to-valley of the deviations from the LS circle, over the last axis (um).

    The deviations are first referred to their own LS circle (harmonics 0 and 1 removed, exact for
    equally spaced points and small deviations), so raw radial deviations may be given too.
    """
    d = remove_size_and_centre(deviations_um)
    return np.ptp(d, axis=-1)


def ron_q(deviations_um: ArrayLike) -> NDArray[np.float64]:
    """RONq: root mean square of the deviations from the LS circle, over the last axis (um)."""
    d = remove_size_and_centre(deviations_um)
    return np.sqrt(np.mean(d * d, axis=-1))
