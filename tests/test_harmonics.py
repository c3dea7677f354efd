"""Circle fits, harmonic spectrum, the paper's Fourier basis and roundness, on analytic cases."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.optimize import least_squares

from ph_explorer.geometry import point_angles_deg
from ph_explorer.harmonics import (
    circle_deviations_um,
    fit_circles,
    fourier_basis,
    fourier_curve,
    harmonic_spectrum,
    paper_fourier_fit,
    remove_size_and_centre,
    ron_q,
    ron_t,
)

THETA64 = np.radians(point_angles_deg(64))


def scipy_circle(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """The oracle: scipy's Levenberg-Marquardt geometric circle fit of one point set (centre x, y, radius).

    Independent of the code under test: it starts from the centroid and the mean distance to it
    (coordinates taken from the centroid, and an analytic Jacobian, keep it exact to ~1e-12).
    """
    mx, my = x.mean(), y.mean()
    xs, ys = x - mx, y - my

    def residual(p: np.ndarray) -> np.ndarray:
        return np.hypot(xs - p[0], ys - p[1]) - p[2]

    def jacobian(p: np.ndarray) -> np.ndarray:
        dx, dy = xs - p[0], ys - p[1]
        d = np.hypot(dx, dy)
        return np.stack([-dx / d, -dy / d, -np.ones_like(d)], axis=-1)

    start = np.array([0.0, 0.0, np.hypot(xs, ys).mean()])
    fit = least_squares(residual, start, jac=jacobian, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return float(fit.x[0] + mx), float(fit.x[1] + my), float(fit.x[2])


def test_fit_circles_recovers_an_exact_circle() -> None:
    x = 3.0 + 9.0 * np.cos(THETA64)
    y = -2.5 + 9.0 * np.sin(THETA64)
    np.testing.assert_allclose(fit_circles(x, y), (3.0, -2.5, 9.0), atol=1e-12)


def test_fit_circles_on_an_arc() -> None:
    """A 60 deg arc: the algebraic start is biased, the geometric fit is not."""
    t = np.radians(np.linspace(0, 60, 20))
    np.testing.assert_allclose(fit_circles(1 + 5 * np.cos(t), 2 + 5 * np.sin(t)), (1, 2, 5), atol=1e-10)


def test_batched_fit_matches_scipy_on_noisy_circles() -> None:
    rng = np.random.default_rng(4)
    centre = rng.normal(0, 2, (6, 5, 2))
    radius = 9.0 + rng.normal(0, 0.01, (6, 5, 1))
    r = radius + rng.normal(0, 0.3, (6, 5, 64))  # strongly out of round, still a circle fit problem
    x = centre[..., :1] + r * np.cos(THETA64)
    y = centre[..., 1:] + r * np.sin(THETA64)
    batched = fit_circles(x, y)
    assert batched.shape == (6, 5, 3)
    for i in range(6):
        for j in range(5):
            np.testing.assert_allclose(batched[i, j], scipy_circle(x[i, j], y[i, j]), atol=1e-9)


def test_fitted_deviations_are_the_form_left_by_the_circle() -> None:
    """Form with harmonics 2.. survives the fit; size and centre are removed; sign is outward."""
    form_um = 0.8 * np.cos(2 * THETA64) + 0.3 * np.sin(7 * THETA64 + 0.4)
    r = 10.0 + 1e-3 * (form_um + 5.0)  # +5 um of size
    x = 0.7 + r * np.cos(THETA64)
    y = -0.2 + r * np.sin(THETA64)
    np.testing.assert_allclose(circle_deviations_um(x, y), form_um, atol=1e-4)
    # A bump outward at point 0 is positive.
    r = np.full(64, 10.0)
    r[0] += 1e-3
    dev = circle_deviations_um(r * np.cos(THETA64), r * np.sin(THETA64))
    assert dev[0] > 0.9 and np.abs(dev[1:]).max() < 0.05


def test_remove_size_and_centre_matches_the_exact_fit_for_small_deviations() -> None:
    rng = np.random.default_rng(0)
    radial_um = rng.normal(0, 0.5, 64) + 3.0 * np.cos(THETA64 - 1.0) + 2.0
    r = 10.0 + 1e-3 * radial_um
    exact = circle_deviations_um(r * np.cos(THETA64), r * np.sin(THETA64))
    np.testing.assert_allclose(remove_size_and_centre(radial_um), exact, atol=1e-3)


def test_the_circle_fit_in_place_gives_the_copys_values_in_the_array_given() -> None:
    # A scan library's columns (n_o, n_rep, n_pt, c) are fitted in place, a block of rings at a time.
    columns = np.random.default_rng(1).normal(size=(7, 3, 64, 5))
    copy = remove_size_and_centre(columns, axis=-2)
    given = columns.copy()
    assert remove_size_and_centre(given, axis=-2, in_place=True) is given
    np.testing.assert_array_equal(given, copy)
    with pytest.raises(ValueError):
        remove_size_and_centre(np.broadcast_to(columns[:, :1], columns.shape), axis=-2, in_place=True)  # read-only


def test_degenerate_point_sets_give_nan() -> None:
    t = np.arange(8.0)
    out = fit_circles(np.stack([t, np.cos(t)]), np.stack([2 * t, np.sin(t)]))
    assert np.isnan(out[0]).all()
    np.testing.assert_allclose(out[1], [0, 0, 1], atol=1e-12)


def test_harmonic_spectrum_of_pure_harmonics() -> None:
    curve = 0.5 + 2.0 * np.cos(3 * THETA64 - np.radians(40)) + 0.7 * np.sin(5 * THETA64) + 0.1 * np.cos(32 * THETA64)
    amplitude, phase = harmonic_spectrum(curve)
    assert amplitude.shape == phase.shape == (33,)
    expected = np.zeros(33)
    expected[[0, 3, 5, 32]] = [0.5, 2.0, 0.7, 0.1]
    np.testing.assert_allclose(amplitude, expected, atol=1e-12)
    assert phase[3] == pytest.approx(40.0)
    assert phase[5] == pytest.approx(90.0)  # sin(5 theta) = cos(5 theta - 90 deg)
    # Batched over leading axes.
    amp2, _ = harmonic_spectrum(np.stack([curve, 2 * curve]))
    np.testing.assert_allclose(amp2[1], 2 * amplitude)


@given(k=st.integers(1, 31), amp=st.floats(0.01, 10), peak=st.floats(-179, 179))
@settings(max_examples=60, deadline=None)
def test_spectrum_phase_locates_the_peak(k: int, amp: float, peak: float) -> None:
    curve = amp * np.cos(k * THETA64 - np.radians(peak))
    amplitude, phase = harmonic_spectrum(curve)
    assert amplitude[k] == pytest.approx(amp, rel=1e-9)
    assert np.cos(np.radians(phase[k] - peak)) == pytest.approx(1.0, abs=1e-9)


@pytest.mark.parametrize("n_points,k_max", [(64, 8), (64, 20), (36, 3), (17, 8)])
def test_paper_fourier_fit_recovers_coefficients(n_points: int, k_max: int) -> None:
    rng = np.random.default_rng(n_points + k_max)
    coef = rng.normal(0, 1, (4, 1 + 2 * k_max))
    curves = fourier_curve(coef, n_points)
    assert curves.shape == (4, n_points)
    np.testing.assert_allclose(paper_fourier_fit(curves, k_max), coef, atol=1e-10)
    np.testing.assert_allclose(curves, coef @ fourier_basis(n_points, k_max).T)


def test_paper_fourier_fit_is_a_low_pass() -> None:
    curve = np.cos(2 * THETA64) + 0.5 * np.sin(12 * THETA64)
    coef = paper_fourier_fit(curve, 8)
    np.testing.assert_allclose(fourier_curve(coef, 64), np.cos(2 * THETA64), atol=1e-12)


def test_ron_of_a_sinusoid() -> None:
    curve = 1.5 * np.cos(4 * THETA64) + 7.0 + 2.0 * np.cos(THETA64)  # size and centre do not count
    assert ron_t(curve) == pytest.approx(3.0, abs=1e-12)
    assert ron_q(curve) == pytest.approx(1.5 / np.sqrt(2), abs=1e-12)
    both = ron_t(np.stack([curve, 2 * curve]))
    np.testing.assert_allclose(both, [3.0, 6.0], atol=1e-12)


def test_the_circle_fit_acts_along_the_points_axis_before_the_columns() -> None:
    # Basis columns come (..., points, columns): the same projection as along the last axis, moved.
    columns = np.random.default_rng(4).normal(size=(3, 2, 64, 5))
    along_last = np.moveaxis(remove_size_and_centre(np.moveaxis(columns, -1, -2)), -2, -1)
    np.testing.assert_allclose(remove_size_and_centre(columns, axis=-2), along_last, atol=1e-14)
    np.testing.assert_allclose(
        harmonic_spectrum(np.moveaxis(remove_size_and_centre(columns, axis=-2), -1, -2))[0][..., :2], 0.0, atol=1e-12
    )
    with pytest.raises(ValueError, match="points' axis"):
        remove_size_and_centre(columns, axis=0)
