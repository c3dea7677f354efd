"""An honest "after": the error of the effects found, on rings that played no part in finding them.

The check rings choose an effect and its period (an effect is taken only when it lowers their
error materially), so the check-ring error after a step is optimistic: it is the figure the choice
was made on. Here the choice itself is cross-validated. The training rings are split into
NESTED_FOLDS folds at random (seeded); for each fold the whole search (choose_effects: baseline,
ranking, within-noise tests, the chain) runs on the campaign without that fold's rings, the hybrid
with the chain it chose is fitted on the remaining training rings, and the fold's rings are
predicted. Beside it, the model the step started from, fitted on the same rings, predicts the
same rings: "before" and "after" on rings that neither the fit nor the choice saw, and each ring's
gain tested over rings as a claim is (diagnosis.replication). The folds' models take the
trilinear data part whatever the diagnosis's (NESTED_DATA_PART).
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ph_explorer import metrics
from ph_explorer.blas import PARTS_AT_ONCE
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.choice import choose_effects
from ph_explorer.diagnosis.fitted_bases import FittedBases
from ph_explorer.diagnosis.replication import replication
from ph_explorer.diagnosis.results import NestedAfter
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect, effect_label
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.hybrid import HybridModel

NESTED_FOLDS = 5
# The data-driven part of the models the folds fit: the interpolator, which refits in milliseconds
# (a network's data part would be retrained twice per fold).
NESTED_DATA_PART = "trilinear"


def nested_after(
    campaign: Campaign,
    effects: Sequence[Effect],
    start: Sequence[Effect] = (),
    max_steps: int = 3,
    seed: int = 0,
    folds: int = NESTED_FOLDS,
) -> NestedAfter | None:
    """The cross-validated before/after of the search (module docstring); None with too few rings."""
    held_out = campaign.holdout_mask()
    train = np.flatnonzero(~held_out)
    if train.size < 4 * folds:
        return None
    rng = np.random.default_rng(seed)
    # Every fold searches the same effects over subsets of the same touches: columns made once.
    bases = FittedBases(campaign_touches(campaign))

    def one_fold(fold: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        fold = np.sort(fold)
        keep = np.ones(campaign.n_orientations, dtype=bool)
        keep[fold] = False
        sub = campaign.subset(keep)
        sub_train = ~sub.holdout_mask()
        choice = choose_effects(
            sub, sub_train, effects, max_steps, seed, start=start, detail=False, bases=bases.subset(np.flatnonzero(keep))
        )
        touches = campaign_touches(campaign.subset(fold))
        before, after = (
            HybridModel(list(chain), NESTED_DATA_PART).fit(sub, sub_train).predict_touches(touches) for chain in (start, choice.chain)
        )
        return fold, before, after, [effect_label(e) for e in choice.chain[len(start) :]]

    # The folds are independent: two at a time (numpy releases the GIL in the heavy parts).
    with ThreadPoolExecutor(max_workers=PARTS_AT_ONCE) as pool:
        results = list(pool.map(one_fold, np.array_split(rng.permutation(train), folds)))
    predicted = [r[0] for r in results]
    before = [r[1] for r in results]
    after = [r[2] for r in results]
    chosen = [r[3] for r in results]
    rings = np.concatenate(predicted)
    measured = campaign.deviations[rings]
    before_all, after_all = np.concatenate(before), np.concatenate(after)
    # Each predicted ring's fall in squared error over its touches, in its own noise variances: the
    # replication test over rings, on rings that took no part in the choice (issue 55).
    fall = ((measured - before_all) ** 2).sum(axis=(1, 2)) - ((measured - after_all) ** 2).sum(axis=(1, 2))
    gain = fall / np.maximum(ring_sigma(measured) ** 2, 1e-300)
    return NestedAfter(
        folds=folds,
        rings=int(rings.size),
        before_um=metrics.mae(before_all, measured),
        after_um=metrics.mae(after_all, measured),
        noise_floor_um=metrics.noise_floor(campaign.noise_sigma_um(), campaign.n_repetitions),
        chosen=tuple(tuple(fold) for fold in chosen),
        gain=replication(gain, np.zeros(gain.size, dtype=bool), seed=seed),
    )
