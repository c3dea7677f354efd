"""The hybrid's data part by stacking: a weighted average of the hybrid with each linear data part,
the weight chosen by the hybrid's own cross-validation.

Beside physical terms, the data part learns what they leave. Two linear data parts stand at the
ends of what a few rings can carry: the trilinear interpolation, which learns an orientation
dependence no catalog term holds but carries the noise of the few rings around each prediction,
and the mean curve of the training rings (models.trilinear.MeanCurveModel), which averages every
ring's noise but learns nothing between them. On a dozen designed rings the rings' own
cross-validation often cannot tell them apart (the paper scenario's 12 designed rings over 10
noise draws: the mean curve's gain within one standard error in 7, -1.0 and -1.6 in two), while
on the check rings one is 3-10 % worse than the other; which one depends on what the head does
between the rings (there the interpolation; beside an uncatalogued error the mean curve, 17-19 %).

So neither is chosen: the hybrid is the weighted average w * (hybrid with the trilinear) + (1 - w)
* (hybrid with the mean curve), each with the terms it carries (models.carried.carried_effects),
and w is the one that minimises the average of the two's out-of-sample predictions' MAE over the
training rings (stacked generalisation: Wolpert 1992, Breiman 1996), on a grid of WEIGHT_STEP.
The out-of-sample predictions are those the terms were chosen with: the weight costs no fit. A
campaign that decides gets an end (w = 1 where only an interpolation learns the error; w = 0 where
the terms carry the orientation dependence), an undecided one a blend. The MAE is convex, so the
blend's error is at most the same average of the ends' errors, and it is below both where they err
in different ways (the paper scenario's 12 designed rings: below both at 10 of 10 noise draws).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from benchmarks.carried import carried_effects, gain_beyond_noise
from ph_explorer import metrics
from ph_explorer.campaign import Campaign
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect, effect_label
from ph_explorer.kinematics import Touches
from ph_explorer.models.deviation_model import DeviationModel, training_mask
from ph_explorer.models.hybrid import HybridModel

# The data parts linear in their data (out-of-sample weights), the default first: the interpolation
# learns what no catalog term holds.
LINEAR_DATA_PARTS = ("trilinear", "mean_curve")
# The weight grid: a tenth, finer than a dozen rings' cross-validation resolves.
WEIGHT_STEP = 0.1
SUBFOLDER = "stacked"


class StackedHybrid(DeviationModel):
    """A weighted average of hybrids, one per data part: curves, touches and spread alike."""

    name = "stacked_hybrid"

    def __init__(self, members: Sequence[HybridModel], weights: Sequence[float]) -> None:
        if len(members) != len(weights) or not members:
            raise ValueError("a stacked hybrid needs one weight per member")
        self.members = list(members)
        self.weights = np.asarray(weights, dtype=float)
        if (self.weights < 0).any() or not np.isclose(self.weights.sum(), 1.0):
            raise ValueError("the weights of a stacked hybrid are non-negative and sum to one")
        self.n_points = self.members[0].n_points

    def weight_of(self, data_part: str) -> float:
        """The weight of the member whose data part is `data_part` (0 when none)."""
        return float(sum(w for w, m in zip(self.weights, self.members) if m.data_model.name == data_part))

    def _average(self, parts: list[NDArray[np.float64]]) -> NDArray[np.float64]:
        return np.tensordot(self.weights, np.stack(parts), axes=(0, 0))

    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        """Refit every member (the weights stay: they come from carried_hybrid)."""
        for member in self.members:
            member.fit(campaign, train)
        self.n_points = campaign.n_points
        return self

    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        return self._average([m.predict(orientations, n_points) for m in self.members])

    def predict_touches(self, touches: Touches) -> NDArray[np.float64]:
        return self._average([m.predict_touches(touches) for m in self.members])

    def predict_held_out(self, campaign: Campaign, rings: NDArray[np.int64]) -> NDArray[np.float64]:
        return self._average([m.predict_held_out(campaign, rings) for m in self.members])

    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        # The members see the same touches: their spreads differ only by how they are interpolated.
        return self._average([m.repetition_sigma(orientations, n_points) for m in self.members])

    def save(self, directory: str | Path) -> Path:
        directory = Path(directory) / SUBFOLDER
        for index, member in enumerate(self.members):
            member.save(directory / str(index))
        path = directory / "stacked.json"
        path.write_text(json.dumps({"weights": self.weights.tolist()}, indent=2))
        return path

    @classmethod
    def load(cls, directory: str | Path, catalog: Catalog = DEFAULT_CATALOG) -> Self:
        directory = Path(directory) / SUBFOLDER
        weights = json.loads((directory / "stacked.json").read_text())["weights"]
        return cls([HybridModel.load(directory / str(i), catalog) for i in range(len(weights))], weights)


def carried_hybrid(campaign: Campaign, effects: Sequence[Effect], train: ArrayLike | None = None) -> tuple[StackedHybrid, dict[str, Any]]:
    """The hybrid a campaign can carry, fitted on its training rings: per linear data part the terms
    kept beside it (carried_effects), averaged with the weight its own cross-validation chooses
    (module docstring). Returns the model and, per data part, the effects kept, the path of sets
    tried, the identifiability report and the cross-validated MAE (um); the weights and the
    cross-validated MAE at each weight; and how far the mean curve alone predicts the rings left
    out better than the interpolation alone, in standard errors of their paired differences."""
    mask = training_mask(campaign, train)
    measured = campaign.deviations[mask]
    ends = {"trilinear": 1.0, "mean_curve": 0.0}  # each data part alone: its weight on the trilinear
    kept: dict[str, list[Effect]] = {}
    curves: dict[str, NDArray[np.float64]] = {}
    details: dict[str, Any] = {}
    for data_model in LINEAR_DATA_PARTS:
        kept[data_model], path, report, curves[data_model] = carried_effects(campaign, effects, data_model, mask)
        details[data_model] = {
            "kept": [effect_label(e) for e in kept[data_model]],
            "cross_validation": path,
            "identifiability": report,
        }
    grid = np.round(np.arange(0.0, 1.0 + WEIGHT_STEP / 2, WEIGHT_STEP), 6)
    ring_errors = {float(w): metrics.ring_mae(w * curves["trilinear"] + (1 - w) * curves["mean_curve"], measured)["mean"] for w in grid}
    cv_mae = {w: float(e.mean()) for w, e in ring_errors.items()}
    weight = min(cv_mae, key=lambda w: (cv_mae[w], -w))  # a tie goes to the interpolation
    for data_model, end in ends.items():
        details[data_model]["cv_mae_um"] = round(cv_mae[end], 5)
    members = [HybridModel(kept[p], p).fit(campaign.subset(mask)) for p in LINEAR_DATA_PARTS]
    model = StackedHybrid(members, [weight, 1.0 - weight])
    details |= {
        "weights": {"trilinear": weight, "mean_curve": round(1.0 - weight, 6)},
        "cv_mae_um_by_trilinear_weight": {f"{w:g}": round(v, 5) for w, v in cv_mae.items()},
        "mean_curve_gain_in_standard_errors": round(gain_beyond_noise(ring_errors[ends["trilinear"]], ring_errors[ends["mean_curve"]]), 2),
    }
    return model, details
