"""Touch outliers: single touches that read far off their point's other repetitions (debris, a sticking trigger).

Each touch is compared with the median of its point's repetitions on its ring, in robust sigmas of
the whole campaign (1.4826 times the median absolute difference). Heavy-tailed touch noise makes
some touches read far off too, so the campaign's share of touches beyond OUTLIER_Z is judged
against OUTLIER_SHARE, above the most that healthy heads of the population's noise laws gave.
Named beside the verdict; when named, the fit and the tests read each of them at its point's
repetition median (at_repetition_median). Method: docs/methods/suspect_rings.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign

OUTLIER_Z = 8.0  # robust sigmas off the point's repetition median
# Calibrated on 300 healthy heads (seeds 910000-910299; Gaussian and Student-t 3-5 dof touch noise):
# at most 0.53 % of a campaign's touches beyond OUTLIER_Z (docs/methods/suspect_rings.md).
OUTLIER_SHARE = 0.006
MIN_REPETITIONS = 3  # a median of fewer repetitions is no reference
RINGS_NAMED = 3  # the rings that hold most of them, named


@dataclass(frozen=True)
class TouchOutliers:
    """The campaign's touches beyond OUTLIER_Z robust sigmas, and the rings that hold most."""

    count: int
    touches: int
    largest_um: float  # the largest distance of a touch from its point's repetition median
    rings: tuple[tuple[float, float, int], ...]  # (A, B, touches beyond) of the rings that hold most

    @property
    def share(self) -> float:
        return self.count / self.touches if self.touches else 0.0

    @property
    def named(self) -> bool:
        """More of them than healthy touch noise gives (OUTLIER_SHARE)."""
        return self.share > OUTLIER_SHARE

    def to_json(self) -> dict[str, Any]:
        return {
            "count": self.count,
            "touches": self.touches,
            "share": round(self.share, 6),
            "named": self.named,
            "z": OUTLIER_Z,
            "share_limit": OUTLIER_SHARE,
            "largest_um": round(self.largest_um, 5),
            "rings": [{"A_deg": a, "B_deg": b, "count": n} for a, b, n in self.rings],
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> TouchOutliers:
        rings = tuple((float(r["A_deg"]), float(r["B_deg"]), int(r["count"])) for r in data["rings"])
        return cls(int(data["count"]), int(data["touches"]), float(data["largest_um"]), rings)


def _beyond(deviations: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Each point's repetition median, each touch's distance from it (um), and whether that is
    beyond OUTLIER_Z robust sigmas."""
    median = np.median(deviations, axis=1, keepdims=True)
    off = np.abs(deviations - median)
    scale = 1.4826 * float(np.median(off))
    return median, off, (off > OUTLIER_Z * scale if scale > 0 else np.zeros(off.shape, dtype=bool))


def touch_outliers(campaign: Campaign) -> TouchOutliers | None:
    """The campaign's touch outliers (module docstring); None with fewer than MIN_REPETITIONS repetitions."""
    if campaign.n_repetitions < MIN_REPETITIONS:
        return None
    _, off, beyond = _beyond(campaign.deviations)
    per_ring = beyond.sum(axis=(1, 2))
    most = [int(i) for i in np.argsort(-per_ring, kind="stable")[:RINGS_NAMED] if per_ring[i] > 0]
    o = campaign.orientations
    return TouchOutliers(
        int(beyond.sum()),
        int(off.size),
        float(off.max(initial=0.0)),
        tuple((float(o[i, 0]), float(o[i, 1]), int(per_ring[i])) for i in most),
    )


def at_repetition_median(campaign: Campaign, outliers: TouchOutliers | None) -> Campaign:
    """The campaign with its touch outliers, when named, read at their point's repetition median:
    a touch 8 robust sigmas off is no measurement of the head, and left in it would inflate the
    noise floor every test reads (1.5 % of the touches 2 um off: 1.5 times it, tests/test_suspect.py)."""
    if outliers is None or not outliers.named:
        return campaign
    median, _, beyond = _beyond(campaign.deviations)
    return replace(campaign, deviations=np.where(beyond, median, campaign.deviations))
