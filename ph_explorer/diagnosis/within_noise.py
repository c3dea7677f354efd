"""Is a model within noise? One stated, Monte Carlo-calibrated test on every ring's out-of-sample residual.

Null: what the model cannot predict of each ring out of sample is touch noise. Each ring gives two
statistics: the mean square of its repetition-mean residual (against MEAN_TOLERANCE times noise,
the null put through the same smoother W) and the share of its within-ring scatter in harmonics
2-8 (an exact Beta p-value). A ring exceeds when its smaller p-value, doubled, is below RING_LEVEL;
the campaign fails when its summed excess, worst ring left out, is above what pure noise gives
with probability FALSE_ALARM.

Method: docs/methods/within_noise.md.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from ph_explorer.models.crossval import weighted, weights_operator
from ph_explorer.models.deviation_model import draw_repetitions

# Pure-noise draws of every ring's mean residual (the campaign-level null) ...
MEAN_DRAWS = 399
# ... and of the campaign's statistic (see within_noise).
STATISTIC_DRAWS = 20000
NULL_CHUNK = 50  # mean draws put through the smoother at a time
WITHIN_HARMONICS = (2, 8)  # the low harmonics where systematic repetition differences show
MEAN_TOLERANCE = 2.0  # a ring's mean residual may hold as much systematic error as noise
RING_LEVEL = 0.01  # a ring exceeds below this p-value
FALSE_ALARM = 0.02  # the campaign fails with at most this probability on pure noise (see below)
# The check rings as a group (docs/methods/within_noise.md, "The check rings as a group"): their
# pooled mean statistic, the worst left out, against CHECK_TOLERANCE times what noise gives, at
# CHECK_LEVEL; at least CHECK_MIN_RINGS of them.
CHECK_TOLERANCE = 1.5
CHECK_LEVEL = 0.01
CHECK_MIN_RINGS = 3


@dataclass
class NoiseTest:
    """The outcome of the within-noise test of one model on one campaign."""

    ring_p_value: NDArray[np.float64]  # (n_o,) each ring's combined p-value
    failing_rings: int  # rings whose p-value is below RING_LEVEL (they exceed their noise)
    statistic: float  # how far the rings but the worst exceed their noise, summed (see within_noise)
    critical: float  # the statistic pure noise exceeds with probability FALSE_ALARM
    p_value: float  # chance that pure noise gives at least this statistic
    rings_fail: bool  # the statistic is above the critical value
    tolerance: float = MEAN_TOLERANCE  # the systematic error a ring's mean may hold, times its noise
    # Each ring's p-value of its repetition mean (against the tolerance) and of the scatter between
    # its repetitions (harmonics WITHIN_HARMONICS): which of the two makes a ring exceed.
    ring_p_mean: NDArray[np.float64] | None = None
    ring_p_within: NDArray[np.float64] | None = None
    # The check rings as a group: their pooled statistic (the worst left out) and the level pure
    # noise exceeds with probability CHECK_LEVEL; None without enough check rings.
    check_statistic: float | None = None
    check_noise_level: float | None = None

    @property
    def check_rings_fail(self) -> bool:
        """The check rings fail together: their pooled statistic is above CHECK_TOLERANCE times its noise level."""
        exceedance = self.check_exceedance
        return exceedance is not None and exceedance > CHECK_TOLERANCE

    @property
    def fails(self) -> bool:
        """The model fails the test: the rings (the worst left out) or the check rings as a group
        exceed their noise. A crowd of lattice rings within noise does not outvote check rings
        that fail together."""
        return self.rings_fail or self.check_rings_fail

    @property
    def check_exceedance(self) -> float | None:
        """The check rings' pooled statistic over what noise gives at CHECK_LEVEL: the group fails above CHECK_TOLERANCE."""
        if self.check_statistic is None or not self.check_noise_level:
            return None
        return self.check_statistic / self.check_noise_level

    @property
    def ring_exceeds(self) -> NDArray[np.bool_]:
        return self.ring_p_value < RING_LEVEL

    @property
    def ring_by_scatter(self) -> NDArray[np.bool_]:
        """Rings whose scatter between repetitions, not their mean, gives the smaller p-value: such a
        ring can exceed its noise with a repetition-mean MAE under its floor."""
        if self.ring_p_mean is None or self.ring_p_within is None:
            return np.zeros(len(self.ring_p_value), dtype=bool)
        return self.ring_p_within < self.ring_p_mean

    @property
    def rings(self) -> int:
        """How many rings were tested."""
        return len(self.ring_p_value)

    def as_dict(self) -> dict[str, Any]:
        """The test as JSON: its figures, and each ring's p-values (from_json reads them back)."""
        return {
            "fails": self.fails,
            "rings_fail": self.rings_fail,
            "check_rings_fail": self.check_rings_fail,
            "check_tolerance": CHECK_TOLERANCE,
            "failing_rings": self.failing_rings,
            "statistic": round(self.statistic, 4),
            "critical": round(self.critical, 4),
            "p_value": round(self.p_value, 5),
            "ring_level": RING_LEVEL,
            "mean_tolerance": self.tolerance,
            "false_alarm_rate": FALSE_ALARM,
            "rings": self.rings,
            "check_statistic": None if self.check_statistic is None else round(self.check_statistic, 4),
            "check_noise_level": None if self.check_noise_level is None else round(self.check_noise_level, 4),
        } | {key: None if (values := getattr(self, key)) is None else [float(v) for v in values] for key in RING_P_VALUES}

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> NoiseTest:
        rings = {key: None if data.get(key) is None else np.array(data[key], dtype=float) for key in RING_P_VALUES}
        figures = (data["failing_rings"], data["statistic"], data["critical"], data["p_value"], data["rings_fail"], data["mean_tolerance"])
        check = (data.get("check_statistic"), data.get("check_noise_level"))
        return cls(rings["ring_p_value"], *figures, rings["ring_p_mean"], rings["ring_p_within"], *check)


RING_P_VALUES = ("ring_p_value", "ring_p_mean", "ring_p_within")  # each ring's, in the JSON


def ring_sigma(deviations: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each ring's pooled repetition sigma per touch (um), (n_o,); NaN with one repetition (no spread)."""
    if deviations.shape[1] < 2:
        return np.full(deviations.shape[0], np.nan)
    return np.sqrt(deviations.var(axis=1, ddof=1).mean(axis=1))


def _harmonics(n_points: int) -> tuple[int, int, int]:
    """(low, high, top): the low band WITHIN_HARMONICS and the highest harmonic below Nyquist.

    The Nyquist harmonic of an even N is left out: its power has twice the variance per degree
    of freedom, and the share below must be a ratio of equal-variance terms.
    """
    top = (n_points - 1) // 2
    low, high = WITHIN_HARMONICS
    return low, min(high, top - 1), top


def low_harmonic_share(within: NDArray[np.float64]) -> NDArray[np.float64]:
    """Share of the scatter (..., n_rep, n_pt) in the low harmonics of all harmonics 2..top, (...,)."""
    low, total = _band_powers(np.abs(np.fft.rfft(within, axis=-1)) ** 2, within.shape[-1])
    return low / np.maximum(total, 1e-300)


def _band_powers(power: NDArray[np.float64], n_points: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(low band, all of harmonics 2..top): powers (..., n_rep, harmonics) summed over the
    repetitions and each band's harmonics."""
    low, high, top = _harmonics(n_points)
    return power[..., low : high + 1].sum(axis=(-1, -2)), power[..., 2 : top + 1].sum(axis=(-1, -2))


def within_p_value(share: NDArray[np.float64], n_repetitions: int, n_points: int) -> NDArray[np.float64]:
    """P(share >= observed) for iid Gaussian touch noise, exactly.

    After each repetition's circle fit, harmonics 2..top of iid noise are independent Gaussians of
    equal variance, two per harmonic; taking out the ring's mean over repetitions leaves n_rep - 1
    of each. The low band's power over the whole is then X / (X + Y) with X, Y chi-square, a Beta
    variable: Beta(a / 2, b / 2) with a and b their degrees of freedom.
    """
    low, high, top = _harmonics(n_points)
    a = 2 * (high - low + 1) * (n_repetitions - 1)
    b = 2 * (top - high) * (n_repetitions - 1)
    return special.betaincc(a / 2.0, b / 2.0, share)  # the Beta survival function (scipy.stats is slow to import)


def _upper_p(values: NDArray[np.float64], null: NDArray[np.float64]) -> NDArray[np.float64]:
    """Monte Carlo p-values P(null >= value) along the last axis of null, (1 + count) / (draws + 1)."""
    return (1.0 + (null >= values[..., None]).sum(axis=-1)) / (null.shape[-1] + 1.0)


@dataclass
class NoiseNull:
    """What pure noise gives on one campaign and smoother: the test's null, drawn once (within_noise).

    It depends on the rings' noise, the smoother and the seed, not on the residual tested, so one
    null serves every residual of the campaign (e.g. a detection limit's scan of strengths).
    """

    null_stat: NDArray[np.float64]  # (n_o, MEAN_DRAWS) each ring's mean statistic in pure-noise draws
    null_statistic: NDArray[np.float64]  # (STATISTIC_DRAWS,) the campaign statistic in pure-noise draws
    critical: float  # the statistic pure noise exceeds with probability FALSE_ALARM
    tolerance: float = MEAN_TOLERANCE  # the systematic error a ring's mean may hold, times its noise


def noise_null(
    weights: NDArray[np.float64], sigma: NDArray[np.float64], n_rep: int, n_pt: int, seed: int = 0, tolerance: float = MEAN_TOLERANCE
) -> NoiseNull:
    """The null of within_noise for rings of noise sigma (n_o,) per touch, n_rep x n_pt touches each."""
    n_o = len(sigma)
    rng = np.random.default_rng(seed)
    # mean: each ring's repetition-mean noise through the circle fit and the smoother.
    draws = draw_repetitions(np.zeros((n_o, n_pt)), (sigma / math.sqrt(n_rep))[:, None], MEAN_DRAWS, rng)
    null_stat = np.empty((n_o, MEAN_DRAWS))  # (n_o, draws)
    operator = weights_operator(weights)
    for start in range(0, MEAN_DRAWS, NULL_CHUNK):  # a few draws at a time: a large campaign's draws are big
        part = draws[:, start : start + NULL_CHUNK]
        null_stat[:, start : start + NULL_CHUNK] = ((part - weighted(operator, part)) ** 2).mean(axis=-1)
    del draws
    # The campaign-level null, from the same draws: each mean draw judged against the others (the
    # count includes the draw itself, which stands in for the +1 of a p-value); each ring's within
    # p-value is uniform under the null (exact), and rings' scatters are independent.
    # The within p-values cost nothing to draw, so the null statistic takes STATISTIC_DRAWS draws,
    # each pairing a mean draw (a whole column: rings share neighbours' noise) with fresh uniforms:
    # its 95th percentile is then known to well under a percent.
    p_mean_null = _count_at_least(tolerance * null_stat, null_stat) / MEAN_DRAWS
    columns = np.arange(STATISTIC_DRAWS) % MEAN_DRAWS
    excess_null = _excess(_combined(p_mean_null[:, columns], rng.uniform(size=(n_o, STATISTIC_DRAWS))))
    null_statistic = excess_null.sum(axis=0) - excess_null.max(axis=0)  # the worst ring left out
    critical = float(np.quantile(null_statistic, 1.0 - FALSE_ALARM, method="higher"))
    return NoiseNull(null_stat, null_statistic, critical, tolerance)


# The last few nulls drawn: a diagnosis tests the baseline and what the effects found leave on the
# same rings, smoother and noise (the null depends on nothing else), and its chain step by step.
_NULLS: dict[tuple, NoiseNull] = {}
NULLS_KEPT = 8
_NULLS_LOCK = threading.Lock()  # the explorer's sessions diagnose in threads


def kept_null(
    weights: NDArray[np.float64], sigma: NDArray[np.float64], n_rep: int, n_pt: int, seed: int = 0, tolerance: float = MEAN_TOLERANCE
) -> NoiseNull:
    """noise_null, drawn once for the same weights, sigma, shape, seed and tolerance."""
    key = (weights.shape, weights.tobytes(), np.asarray(sigma, dtype=float).tobytes(), n_rep, n_pt, seed, tolerance)
    null = _NULLS.get(key)
    if null is None:
        null = noise_null(weights, sigma, n_rep, n_pt, seed, tolerance)
        null.null_stat.flags.writeable = null.null_statistic.flags.writeable = False  # shared: read-only
        with _NULLS_LOCK:
            while len(_NULLS) >= NULLS_KEPT:
                _NULLS.pop(next(iter(_NULLS)))  # the oldest first
            _NULLS[key] = null
    return null


def within_noise(
    residual: NDArray[np.float64],
    weights: NDArray[np.float64],
    spread: NDArray[np.float64],
    seed: int = 0,
    null: NoiseNull | None = None,
    tolerance: float = MEAN_TOLERANCE,
    held_out: NDArray[np.bool_] | None = None,
) -> NoiseTest | None:
    """The test (docs/methods/within_noise.md) of an out-of-sample residual (n_o, n_rep, n_pt).

    weights: the smoother W (n_o x n_o) that made the residual; spread: deviations whose
    repetition scatter is each ring's noise (what the model's terms that change between
    repetitions leave). None for a campaign of one repetition: without a repetition spread there
    is no noise to compare with. null: noise_null of the same rings and smoother, when it is
    already drawn (its tolerance is then the test's); tolerance: MEAN_TOLERANCE unless a
    calibration tries another; held_out: the check rings, also judged as a group.
    """
    n_o, n_rep, n_pt = residual.shape
    if n_rep < 2:
        return None
    if null is None:
        null = kept_null(weights, ring_sigma(spread), n_rep, n_pt, seed, tolerance)
    mean_residual = residual.mean(axis=1)
    # within: the low-harmonic share of each ring's scatter, against its exact null.
    share = low_harmonic_share(residual - mean_residual[:, None])
    return _judged(mean_residual, within_p_value(share, n_rep, n_pt), weights, null, held_out)


def check_group(
    mean_stat: NDArray[np.float64], null_stat: NDArray[np.float64], held_out: NDArray[np.bool_] | None
) -> tuple[float | None, float | None]:
    """The check rings as a group: their mean statistics, each over its mean under noise, summed
    with the worst left out (no single ring decides), and the same sum's (1 - CHECK_LEVEL) quantile
    over the null's draws; (None, None) without CHECK_MIN_RINGS check rings."""
    if held_out is None or int(np.sum(held_out)) < CHECK_MIN_RINGS:
        return None, None
    scale = np.maximum(null_stat[held_out].mean(axis=1), 1e-300)
    observed = mean_stat[held_out] / scale
    drawn = null_stat[held_out] / scale[:, None]
    noise = drawn.sum(axis=0) - drawn.max(axis=0)
    return float(observed.sum() - observed.max()), float(np.quantile(noise, 1.0 - CHECK_LEVEL, method="higher"))


def _judged(
    mean_residual: NDArray[np.float64],
    p_within: NDArray[np.float64],
    weights: NDArray[np.float64],
    null: NoiseNull,
    held_out: NDArray[np.bool_] | None = None,
) -> NoiseTest:
    """The test from each ring's repetition-mean residual (n_o, n_pt) and scatter p-value (n_o,)."""
    null_stat, tolerance = null.null_stat, null.tolerance
    tolerated = tolerance * null_stat
    mean_stat = (mean_residual**2).mean(axis=-1)
    p_mean = _upper_p(mean_stat, tolerated)
    ring_p = _combined(p_mean, p_within)
    failing = int((ring_p < RING_LEVEL).sum())
    # No single ring decides: the worst ring is left out, and the share of its error that it put
    # into the predictions of the neighbours it is interpolated into (its residual times its
    # weight there) is undone; what the other rings exceed by is the campaign's statistic.
    worst = int(np.lexsort((-mean_stat / null_stat.mean(axis=1), ring_p))[0])
    undone = mean_residual + weights[:, worst, None] * mean_residual[worst]
    p_undone = _upper_p((undone**2).mean(axis=-1), tolerated)
    statistic = float(np.delete(_excess(_combined(p_undone, p_within)), worst).sum())
    p_value = float((1.0 + (null.null_statistic >= statistic).sum()) / (STATISTIC_DRAWS + 1.0))
    check = check_group(mean_stat, null_stat, held_out)
    return NoiseTest(ring_p, failing, statistic, null.critical, p_value, statistic > null.critical, tolerance, p_mean, p_within, *check)


class ScaledWithinNoise:
    """within_noise of residual + factor * added (n_o, n_rep, n_pt) at any factor, each without a
    Fourier transform: a ring's band powers are quadratic in the factor, their three terms made once
    (a detection limit's search for the factor at which a model starts to fail)."""

    def __init__(
        self,
        residual: NDArray[np.float64],
        added_mean: NDArray[np.float64],
        added_within: NDArray[np.float64] | None,
        weights: NDArray[np.float64],
        null: NoiseNull,
        held_out: NDArray[np.bool_] | None = None,
    ) -> None:
        """added_mean (n_o, n_pt): the part the same in every repetition; added_within (n_o, n_rep, n_pt) or None: the part that changes;
        held_out: the check rings, judged as a group too."""
        _, self.n_rep, self.n_pt = residual.shape
        self.weights, self.null, self.held_out = weights, null, held_out
        self.mean_residual = residual.mean(axis=1)
        self.added_mean = added_mean if added_within is None else added_mean + added_within.mean(axis=1)
        scatter = residual - self.mean_residual[:, None]
        # What is added the same in every repetition leaves the scatter, and its p-values, as they are.
        self.p_within = within_p_value(low_harmonic_share(scatter), self.n_rep, self.n_pt) if added_within is None else None
        if added_within is not None:  # |FR + f FW|^2 = |FR|^2 + 2 f Re(FR conj FW) + f^2 |FW|^2, summed over each band
            spectra = np.fft.rfft(scatter, axis=-1), np.fft.rfft(added_within - added_within.mean(axis=1, keepdims=True), axis=-1)
            terms = np.stack([np.abs(spectra[0]) ** 2, 2.0 * (spectra[0] * spectra[1].conj()).real, np.abs(spectra[1]) ** 2])
            self.low_power, self.all_power = _band_powers(terms, self.n_pt)  # each (3, n_o)

    def __call__(self, factor: float) -> NoiseTest:
        p_within = self.p_within
        if p_within is None:
            powers = np.array([1.0, factor, factor**2])
            share = (powers @ self.low_power) / np.maximum(powers @ self.all_power, 1e-300)
            p_within = within_p_value(share, self.n_rep, self.n_pt)
        return _judged(self.mean_residual + factor * self.added_mean, p_within, self.weights, self.null, self.held_out)


def _count_at_least(reference: NDArray[np.float64], values: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n, m): how many of each row's reference values (n, d) are >= each of its values (n, m), from
    one stable sort of each row (the values first, so that a tie counts), not an (n, m, d) comparison."""
    if np.isnan(reference).any() or np.isnan(values).any():  # NaN compares false: count as numpy does
        return (reference[:, None, :] >= values[..., None]).sum(axis=-1).astype(float)
    m = values.shape[1]
    order = np.argsort(np.concatenate([values, reference], axis=1), axis=1, kind="stable")
    below = np.cumsum(order >= m, axis=1)  # reference values sorted before each position
    is_value = order < m  # each row's m values, in sorted order
    counts = np.empty(values.shape)
    np.put_along_axis(counts, order[is_value].reshape(-1, m), reference.shape[1] - below[is_value].reshape(-1, m), axis=1)
    return counts


def _combined(p_mean: NDArray[np.float64], p_within: NDArray[np.float64]) -> NDArray[np.float64]:
    """A ring's p-value from its two statistics (Bonferroni)."""
    out = np.minimum(p_mean, p_within)
    out *= 2.0  # in place: a null's arrays are (rings, 20 000 draws)
    return np.minimum(1.0, out, out=out)


def _excess(ring_p: NDArray[np.float64]) -> NDArray[np.float64]:
    """How far each ring is beyond RING_LEVEL, log(RING_LEVEL / p), zero for a ring within it."""
    ratio = np.maximum(ring_p, 1e-300)
    np.divide(RING_LEVEL, ratio, out=ratio)
    # The log only where it is positive: a few per cent of a null's 20 000 draws per ring (NaN stays NaN).
    return np.log(ratio, out=np.zeros(ratio.shape), where=~(ratio <= 1.0))
