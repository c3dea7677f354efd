"""Is a model within noise? One stated, Monte Carlo-calibrated test on every ring's out-of-sample residual.

The hypothesis tested is "what the model cannot predict of each ring out of sample is touch
noise": independent Gaussian errors per touch, with each ring's own repetition spread, put through
the same circle fit and the same out-of-sample prediction as the data. Each ring gives two
statistics:

- mean: the mean square of its repetition-mean residual, against MEAN_TOLERANCE times what noise
  alone gives: the ring exceeds when the model's own error is significantly larger than the
  noise it is compared with (systematic mean square > noise mean square). A prediction made of
  neighbours carries their noise too, so the null draws put every ring's own noise through the
  same smoother W. Why a tolerance: leave-one-out doubles the lattice spacing, so even the usual
  smooth background of a head (seat lobing, low-order axis errors) leaves an interpolation error
  at many lattice rings (mean square up to ~2x noise on the twin's paper campaign); a test of
  "exactly noise" would call every real lattice model failing and say nothing about an effect.
- within: the share of its within-ring scatter (each repetition minus the ring's mean) in
  harmonics 2-8. Pure touch noise spreads evenly over the harmonics; repetitions that differ
  systematically (a scan direction that alternates, drift in time) put their difference into
  the low harmonics. The share does not depend on sigma, so its null is the same for every ring.
  No tolerance here: no model indexed by orientation predicts differences between repetitions,
  so interpolation leaves nothing in this statistic.

A ring "exceeds" when the smaller of its two Monte Carlo p-values, doubled (Bonferroni over the
two statistics), is below RING_LEVEL. No single ring decides: the campaign fails when the number
of exceeding rings reaches the count that pure noise reaches with probability at most
FALSE_ALARM (the look-elsewhere correction over all rings, calibrated on the same null draws),
and at least MIN_FAILING_RINGS, and when, with the worst ring's influence on its neighbours'
predictions undone and that ring left out, at least one ring fewer still exceeds (a single wrong
ring spoils the rings it is interpolated into, which is not a failure several rings share).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.harmonics import remove_size_and_centre

# Pure-noise draws of every ring's mean residual (the campaign-level null) ...
MEAN_DRAWS = 399
# ... and of one ring's within-ring scatter (the same null for every ring).
WITHIN_DRAWS = 2000
WITHIN_HARMONICS = (2, 8)  # the low harmonics where systematic repetition differences show
MEAN_TOLERANCE = 2.0  # a ring's mean residual may hold as much systematic error as noise
RING_LEVEL = 0.01  # a ring exceeds below this p-value
FALSE_ALARM = 0.05  # the campaign fails with at most this probability on pure noise
MIN_FAILING_RINGS = 2  # no single ring decides


@dataclass
class NoiseTest:
    """The outcome of the within-noise test of one model on one campaign."""

    ring_p_value: NDArray[np.float64]  # (n_o,) each ring's combined p-value
    failing_rings: int  # rings whose p-value is below RING_LEVEL
    critical_rings: int  # the count at which the campaign fails
    p_value: float  # chance that pure noise gives at least as many exceeding rings
    fails: bool

    @property
    def ring_exceeds(self) -> NDArray[np.bool_]:
        return self.ring_p_value < RING_LEVEL

    def as_dict(self) -> dict[str, Any]:
        return {
            "fails": self.fails,
            "failing_rings": self.failing_rings,
            "critical_rings": self.critical_rings,
            "p_value": round(self.p_value, 5),
            "ring_level": RING_LEVEL,
            "mean_tolerance": MEAN_TOLERANCE,
            "false_alarm_rate": FALSE_ALARM,
        }


def ring_sigma(deviations: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each ring's pooled repetition sigma per touch (um), (n_o,)."""
    return np.sqrt(deviations.var(axis=1, ddof=1).mean(axis=1))


def low_harmonic_share(within: NDArray[np.float64]) -> NDArray[np.float64]:
    """Share of the scatter (..., n_rep, n_pt) in harmonics WITHIN_HARMONICS of all harmonics >= 2, (...,)."""
    power = np.abs(np.fft.rfft(within, axis=-1)) ** 2
    low, high = WITHIN_HARMONICS
    total = power[..., 2:].sum(axis=(-1, -2))
    return power[..., low : high + 1].sum(axis=(-1, -2)) / np.maximum(total, 1e-300)


def _upper_p(values: NDArray[np.float64], null: NDArray[np.float64]) -> NDArray[np.float64]:
    """Monte Carlo p-values P(null >= value) along the last axis of null, (1 + count) / (draws + 1)."""
    return (1.0 + (null >= values[..., None]).sum(axis=-1)) / (null.shape[-1] + 1.0)


def within_noise(
    residual: NDArray[np.float64],
    weights: NDArray[np.float64],
    spread: NDArray[np.float64],
    seed: int = 0,
) -> NoiseTest | None:
    """The test (see the module docstring) of an out-of-sample residual (n_o, n_rep, n_pt).

    weights: the smoother W (n_o x n_o) that made the residual; spread: deviations whose
    repetition scatter is each ring's noise (what the model's terms that change between
    repetitions leave). None for a campaign of one repetition: without a repetition spread there
    is no noise to compare with.
    """
    n_o, n_rep, n_pt = residual.shape
    if n_rep < 2:
        return None
    rng = np.random.default_rng(seed)
    sigma = ring_sigma(spread)
    inflate = math.sqrt(n_pt / max(n_pt - 3, 1))  # the circle fit's shrinkage, undone

    # mean: each ring's repetition-mean noise through the circle fit and the smoother.
    draws = rng.standard_normal((n_o, MEAN_DRAWS, n_pt)) * (sigma * inflate / math.sqrt(n_rep))[:, None, None]
    draws = remove_size_and_centre(draws)
    null_mean = draws - np.tensordot(weights, draws, axes=(1, 0))
    null_stat = (null_mean**2).mean(axis=-1)  # (n_o, draws)
    mean_stat = (residual.mean(axis=1) ** 2).mean(axis=-1)
    p_mean = _upper_p(mean_stat, MEAN_TOLERANCE * null_stat)

    # within: one pooled null of the low-harmonic share of iid scatter.
    pool = remove_size_and_centre(rng.standard_normal((WITHIN_DRAWS, n_rep, n_pt)))
    null_share = np.sort(low_harmonic_share(pool - pool.mean(axis=1, keepdims=True)))
    share = low_harmonic_share(residual - residual.mean(axis=1, keepdims=True))
    p_within = _upper_p(share, null_share)

    ring_p = np.minimum(1.0, 2.0 * np.minimum(p_mean, p_within))
    failing = int((ring_p < RING_LEVEL).sum())
    # No single ring decides: a wrong ring also spoils the predictions of the neighbours it is
    # interpolated into. Undo the worst ring's share in them (its residual times its weight) and
    # leave it out: a failure that several rings share still counts at least critical - 1 rings.
    worst = int(np.argmax(mean_stat / null_stat.mean(axis=1)))  # p-values tie at the extreme
    mean_residual = residual.mean(axis=1)
    undone = mean_residual + weights[:, worst, None] * mean_residual[worst]
    p_undone = _upper_p((undone**2).mean(axis=-1), MEAN_TOLERANCE * null_stat)
    others = np.arange(n_o) != worst
    shared = int((np.minimum(1.0, 2.0 * np.minimum(p_undone, p_within)) < RING_LEVEL)[others].sum())

    # The campaign-level null: each mean draw judged against the other draws, each ring's within
    # share drawn from the pool (rings' scatters are independent).
    p_mean_null = _upper_p(null_stat, MEAN_TOLERANCE * null_stat[:, None, :])  # each draw against all
    picked = null_share[rng.integers(0, WITHIN_DRAWS, size=(n_o, MEAN_DRAWS))]
    p_within_null = (1.0 + (WITHIN_DRAWS - np.searchsorted(null_share, picked, side="left"))) / (WITHIN_DRAWS + 1.0)
    null_counts = (np.minimum(1.0, 2.0 * np.minimum(p_mean_null, p_within_null)) < RING_LEVEL).sum(axis=0)
    critical = MIN_FAILING_RINGS
    while np.mean(null_counts >= critical) > FALSE_ALARM:
        critical += 1
    p_value = float((1.0 + (null_counts >= failing).sum()) / (MEAN_DRAWS + 1.0))
    return NoiseTest(ring_p, failing, critical, p_value, failing >= critical and shared >= critical - 1)
