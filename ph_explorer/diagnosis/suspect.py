"""Rings measured badly: a ring that fails alone, or whose repetitions disagree.

A head's errors are functions of its joint angles, shared by neighbouring orientations; a form
error in every repetition of one ring (a chipped contact, a dirty gauge) is not. A lattice ring
that does is named and left out of the fit and the claims; a check ring that fails alone while the
rings predicting it are quiet is named to measure again and kept in every test (nothing vouches
that it is not the head's). More than SUSPECT_MAX are a pattern of the head. Method:
docs/methods/suspect_rings.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ph_explorer import metrics
from ph_explorer.campaign import Campaign, orientation_match
from ph_explorer.diagnosis.touch_outliers import TouchOutliers, at_repetition_median
from ph_explorer.diagnosis.within_noise import kept_null, low_harmonic_share, ring_sigma, within_p_value
from ph_explorer.kinematics import campaign_touches, near_pole
from ph_explorer.models.crossval import OutOfSampleSmoother

# Calibrated on 300 healthy heads (seeds 910000-910299) and 100 heads with one badly measured ring
# (920000-920099) of the population's designs and noise laws (docs/methods/suspect_rings.md).
SUSPECT_EXCESS = 3.0  # the ring's mean statistic over what noise gives it on average
SUSPECT_ALONE = 4.0  # ... and over the most a ring predicting it exceeds, its share undone
SUSPECT_QUIET = 4.0  # ... while no ring predicting it exceeds more than this, its share undone
SUSPECT_LEVEL = 1e-3  # the scatter test, family-wise over the campaign's rings (Bonferroni)
SUSPECT_MAX = 2  # more rings standing out alone are a pattern of the head
MIN_TRAINING_KEPT = 4  # never leave fewer training rings than a diagnosis needs

SuspectReason = Literal["fails alone", "repetitions disagree"]


@dataclass(frozen=True)
class SuspectRing:
    """A ring the diagnosis left out as measured badly, and why."""

    a_deg: float
    b_deg: float
    ratio: float  # its out-of-sample MAE (repetition mean) over its own floor
    reason: SuspectReason
    excess: float  # its mean statistic over noise's average
    neighbours_excess: float  # the most a ring predicting it exceeds, its share undone
    p_scatter: float  # the scatter test's p-value of its repetitions
    check_ring: bool = False  # a check ring: named to measure again, kept in every test

    @property
    def left_out(self) -> bool:
        """Left out of the fit, the tests and the claims: a ring of the training set."""
        return not self.check_ring

    def to_json(self) -> dict[str, Any]:
        return {
            "A_deg": self.a_deg,
            "B_deg": self.b_deg,
            "ratio": round(self.ratio, 3),
            "reason": self.reason,
            "excess": round(self.excess, 3),
            "neighbours_excess": round(self.neighbours_excess, 3),
            "p_scatter": float(f"{self.p_scatter:.4g}"),
            "check_ring": self.check_ring,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> SuspectRing:
        return cls(
            float(data["A_deg"]),
            float(data["B_deg"]),
            float(data["ratio"]),
            data["reason"],
            float(data["excess"]),
            float(data["neighbours_excess"]),
            float(data["p_scatter"]),
            bool(data.get("check_ring", False)),
        )


@dataclass(frozen=True)
class RingStanding:
    """How each ring stands against its noise and its neighbours: the figures the suspect test reads."""

    excess: NDArray[np.float64]  # (n_o,) each ring's mean statistic over noise's average
    neighbours: NDArray[np.float64]  # (n_o,) the most a ring predicting it exceeds, its share undone
    p_scatter: NDArray[np.float64]  # (n_o,) the scatter test's p-value of its repetitions
    ratio: NDArray[np.float64]  # (n_o,) its out-of-sample MAE (repetition mean) over its own floor
    judged: NDArray[np.bool_]  # (n_o,) a training ring on the lattice: judged alone and by its scatter
    check: NDArray[np.bool_]  # (n_o,) a check ring away from the pole: judged alone only
    training_rings: int  # all training rings, on the lattice or off it

    def suspect(self, excess: float = SUSPECT_EXCESS, alone: float = SUSPECT_ALONE, level: float = SUSPECT_LEVEL) -> NDArray[np.bool_]:
        """The suspect rings at these thresholds; none when more than SUSPECT_MAX stand out or too few training rings would be left."""
        fails_alone = self.fails_alone(excess, alone)
        suspect = fails_alone | (self.judged & (self.p_scatter < level / len(self.judged)))
        if suspect.sum() > SUSPECT_MAX or self.training_rings - (suspect & self.judged).sum() < MIN_TRAINING_KEPT:
            return np.zeros_like(suspect)
        return suspect

    def fails_alone(self, excess: float = SUSPECT_EXCESS, alone: float = SUSPECT_ALONE) -> NDArray[np.bool_]:
        quiet = self.neighbours <= SUSPECT_QUIET
        return (self.judged | self.check) & quiet & (self.excess > excess) & (self.excess > alone * np.maximum(self.neighbours, 1.0))


def ring_standing(campaign: Campaign, seed: int = 0) -> RingStanding | None:
    """Each ring's standing (RingStanding); None with one repetition (no noise to judge by)."""
    n_o, n_rep, n_pt = campaign.deviations.shape
    train = ~campaign.holdout_mask()
    if n_rep < 2 or train.sum() <= MIN_TRAINING_KEPT:
        return None
    # Only a ring on the lattice has neighbours that vouch for it: an off-grid ring samples joint
    # angles no lattice ring does (an aliased period shows there alone).
    judged = train & ~campaign.off_grid_mask()
    smoother = OutOfSampleSmoother(campaign.orientations, train)
    residual = smoother.residual(campaign.deviations)
    weights = smoother.weights
    # The within-noise test's own null (kept: the diagnosis draws the same one next).
    expected = kept_null(weights, ring_sigma(campaign.deviations), n_rep, n_pt, seed).null_stat.mean(axis=1)
    mean = residual.mean(axis=1)
    # For every ring i and each ring j predicting it: j's residual with i's share in j's own
    # prediction undone (j's prediction took W[j, i] of i's error).
    i, j = np.nonzero((weights != 0) & ~np.eye(n_o, dtype=bool))
    undone = ((mean[j] + weights[j, i][:, None] * mean[i]) ** 2).mean(axis=-1) / expected[j]
    neighbours = np.zeros(n_o)
    np.maximum.at(neighbours, i, undone)
    # A check ring takes no part in any prediction: its neighbours are the rings predicting it and
    # the other check rings (rings it was never fitted to that fail with it are the head's).
    excess = (mean**2).mean(axis=-1) / expected
    check = ~train & ~near_pole(campaign_touches(campaign))  # the lattice rings predicting it sweep B otherwise
    k, m = np.nonzero((weights != 0) & check[:, None])
    np.maximum.at(neighbours, k, excess[m])
    others = np.where(check, excess, 0.0)
    second, first = np.sort(others)[-2:]
    neighbours[check] = np.maximum(neighbours[check], np.where(others[check] >= first, second, first))
    ratio = (
        metrics.ring_mae(campaign.deviations - residual, campaign.deviations)["mean"]
        / smoother.noise_floor(campaign.noise_sigma_um(), n_rep)["mean"]
    )
    return RingStanding(
        excess,
        neighbours,
        within_p_value(low_harmonic_share(residual - mean[:, None]), n_rep, n_pt),
        ratio,
        judged,
        check,
        int(train.sum()),
    )


def suspect_rings(campaign: Campaign, seed: int = 0) -> tuple[SuspectRing, ...]:
    """The campaign's suspect rings (module docstring)."""
    standing = ring_standing(campaign, seed)
    if standing is None:
        return ()
    alone = standing.fails_alone()
    return tuple(
        SuspectRing(
            float(campaign.orientations[k, 0]),
            float(campaign.orientations[k, 1]),
            float(standing.ratio[k]),
            "fails alone" if alone[k] else "repetitions disagree",
            float(standing.excess[k]),
            float(standing.neighbours[k]),
            float(standing.p_scatter[k]),
            bool(standing.check[k]),
        )
        for k in np.flatnonzero(standing.suspect())
    )


def without_suspects(campaign: Campaign, suspects: Sequence[SuspectRing]) -> Campaign:
    """The campaign without its suspect training rings (the diagnosis's fit and claims leave them out)."""
    left_out = [(s.a_deg, s.b_deg) for s in suspects if s.left_out]
    if not left_out:
        return campaign
    return campaign.subset(~orientation_match(campaign.orientations, left_out).any(axis=1))


def judged_campaign(campaign: Campaign, suspects: Sequence[SuspectRing], outliers: TouchOutliers | None) -> Campaign:
    """The campaign as a diagnosis judges it: its named touch outliers at their point's repetition
    median (the suspect rings are found on that), then without its suspect training rings."""
    return without_suspects(at_repetition_median(campaign, outliers), suspects)
