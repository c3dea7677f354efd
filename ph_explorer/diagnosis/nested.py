"""An honest "after", and the condition of a claim: the gain of the effects found on rings that
played no part in finding them.

The check rings took part in choosing the effects, so their "after" is optimistic. Here the
choice is cross-validated: the training rings and the check rings are each split into
NESTED_FOLDS folds (seeded); for each, the whole search (choose_effects) runs without the fold's
rings, and the hybrid with its chain (trilinear data part, NESTED_DATA_PART) and the starting
model, fitted on the other training rings, predict them: "before" and "after". Each ring's fall
in error is tested over rings as a claim's gain is (diagnosis.replication), and a claim stands
only when it is replicated (held_out_claims). Method: docs/diagnosis.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from ph_explorer import metrics
from ph_explorer.blas import PARTS_AT_ONCE
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import Candidate
from ph_explorer.diagnosis.choice import Choice, choose_effects
from ph_explorer.diagnosis.fitted_bases import FittedBases
from ph_explorer.diagnosis.replication import replication
from ph_explorer.diagnosis.results import NestedAfter
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect, effect_label
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.hybrid import HybridModel

NESTED_FOLDS = 5
MIN_TRAIN_PER_FOLD = 4  # fewer training rings than this a fold make no folds: claims then rest on the search's test
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
    if train.size < MIN_TRAIN_PER_FOLD * folds:
        return None
    rng = np.random.default_rng(seed)
    # Each fold leaves out its share of the training rings and of the check rings: the check rings,
    # where a claim shows, took part in the search's choice and are tested here on a choice made
    # without them (the folds' searches keep the other check rings as theirs).
    train_parts, check = np.array_split(rng.permutation(train), folds), np.flatnonzero(held_out)
    check_parts = np.array_split(rng.permutation(check), folds) if check.size >= 2 else [check[:0]] * folds
    groups = [np.concatenate(parts) for parts in zip(train_parts, check_parts)]
    # Every fold searches the same effects over subsets of the same touches: columns made once.
    bases = FittedBases(campaign_touches(campaign))

    def one_fold(fold: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        fold = np.sort(fold)
        keep = np.ones(campaign.n_orientations, dtype=bool)
        keep[fold] = False
        # The check rings kept stay check rings (a campaign without sidecar finds them off its
        # lattice, which a row left out would change).
        sub = replace(campaign.subset(keep), check_orientations=campaign.orientations[held_out & keep])
        sub_train = ~held_out[keep]
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
        results = list(pool.map(one_fold, groups))
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
    predicted_check = held_out[rings]
    return NestedAfter(
        folds=folds,
        rings=int(rings.size),
        before_um=metrics.mae(before_all, measured),
        after_um=metrics.mae(after_all, measured),
        noise_floor_um=metrics.noise_floor(campaign.noise_sigma_um(), campaign.n_repetitions),
        chosen=tuple(tuple(fold) for fold in chosen),
        gain=replication(gain, predicted_check, seed=seed),
        check_rings=int(predicted_check.sum()),
    )


def held_out_claims(
    choice: Choice, campaign: Campaign, effects: Sequence[Effect], fixed: int, max_steps: int = 3, seed: int = 0
) -> tuple[Choice, NestedAfter | None]:
    """The search's claims (beyond the chain's first `fixed` effects) kept when their gain survives
    the choice made inside the folds (nested_after's gain replicated), else withdrawn: each a
    suggestion, with why. A catalog effect that only fits what it cannot predict is no claim."""
    if not choice.chain[fixed:]:
        return choice, None
    honest = nested_after(campaign, effects, choice.chain[:fixed], max_steps, seed)
    if honest is None or honest.gain_holds:
        return choice, honest
    assert honest.gain is not None  # gain_holds is True without it
    why = "; ".join(honest.gain.reasons()) if honest.gain.rings else "no fold's search chose an effect"
    note = f"its gain does not replicate on rings left out of the choice (nested cross-validation, {honest.folds} folds: {why})"

    def claim_of(candidate: Candidate) -> tuple[str, str]:
        return candidate.effect, repr(sorted(candidate.settings.items()))

    claimed = {claim_of(c) for c in choice.found}

    def withdrawn(candidate: Candidate) -> Candidate:
        if claim_of(candidate) in claimed and not candidate.suggested:
            return replace(candidate, suggested=True, note=note)
        return candidate

    chain = choice.chain[:fixed]
    rankings = [[withdrawn(c) for c in ranking] for ranking in choice.rankings]
    after = choice.search.within_noise_after(chain, seed) if chain else None
    return replace(choice, found=[], chain=chain, after=after, rankings=rankings), honest
