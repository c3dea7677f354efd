"""An honest "after", and the condition of a claim: the gain of the effects claimed on rings that
played no part in fitting them or in choosing their settings.

The check rings took part in choosing the effects, so their "after" is optimistic. Here the
training rings and the check rings are each split into NESTED_FOLDS folds (seeded); for each, the
claimed effects are fitted again without the fold's rings, each at the setting its own scan there
prefers beside the others, and the hybrid with them (trilinear data part) and the starting model,
fitted on the other training rings, predict them: "before" and "after". Each ring's fall in error
is tested over rings as a claim's gain is (diagnosis.replication). A claim stands only when that
gain replicates and no two folds set it where the whole campaign excludes, beyond a step of the
scan (held_out_claims). Which effects
to claim is the search's choice, at its family null's level. Method: docs/diagnosis.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from ph_explorer import metrics
from ph_explorer.blas import PARTS_AT_ONCE
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import Candidate
from ph_explorer.diagnosis.choice import Choice
from ph_explorer.diagnosis.fitted_bases import FittedBases
from ph_explorer.diagnosis.replication import replication, ring_gains
from ph_explorer.diagnosis.results import NestedAfter
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.telling_apart import rings_prefer
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect, effect_label
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.hybrid import HybridModel

NESTED_FOLDS = 5
MIN_TRAIN_PER_FOLD = 4  # fewer training rings than this a fold make no folds: claims then rest on the search's test
# The data-driven part of the models the folds fit: the interpolator, which refits in milliseconds
# (a network's data part would be retrained twice per fold).
NESTED_DATA_PART = "trilinear"
# A fold's scan sees four fifths of the rings, and a true setting at 1-2x its detection limit is
# moved by one cycle/rev in one fold of five often enough to withdraw whole chains of claims (the
# multi-effect heads, docs/diagnosis.md); no single fold decides, two do.
MAX_FOLDS_EXCLUDED = 1
# Whether the rings as units do not tell claim i from another setting of its effect (unsettled_claims).
Untold = Callable[[int, Effect], bool]


def nested_after(
    campaign: Campaign,
    claimed: Sequence[Effect],
    start: Sequence[Effect] = (),
    seed: int = 0,
    folds: int = NESTED_FOLDS,
    bases: FittedBases | None = None,
) -> NestedAfter | None:
    """The cross-validated before/after of the effects claimed beside `start` (module docstring);
    None with too few rings. bases: the campaign's fitted columns, shared between calls."""
    held_out = campaign.holdout_mask()
    train = np.flatnonzero(~held_out)
    if train.size < MIN_TRAIN_PER_FOLD * folds:
        return None
    rng = np.random.default_rng(seed)
    # Each fold leaves out its share of the training rings and of the check rings: the check rings,
    # where a claim shows, took part in the search's choice and are tested here on settings chosen
    # without them (the folds keep the other check rings as theirs).
    train_parts, check = np.array_split(rng.permutation(train), folds), np.flatnonzero(held_out)
    check_parts = np.array_split(rng.permutation(check), folds) if check.size >= 2 else [check[:0]] * folds
    groups = [np.concatenate(parts) for parts in zip(train_parts, check_parts)]
    # Every fold scans the same effects over subsets of the same touches: columns made once.
    bases = bases if bases is not None else FittedBases(campaign_touches(campaign))

    def one_fold(fold: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
        fold = np.sort(fold)
        keep = np.ones(campaign.n_orientations, dtype=bool)
        keep[fold] = False
        # The check rings kept stay check rings (a campaign without sidecar finds them off its
        # lattice, which a row left out would change).
        sub = replace(campaign.subset(keep), check_orientations=campaign.orientations[held_out & keep])
        sub_train = ~held_out[keep]
        search = CandidateSearch(sub, sub_train, seed, detail=False, bases=bases.subset(np.flatnonzero(keep)), null_draws=0)
        # Each claim at the setting its scan on these rings prefers beside every other claim, as the
        # search's swaps chose it (one pass from the claimed settings): scanned before a claim it
        # was chosen beside, a setting moves for want of it.
        claims = list(claimed)
        for i, effect in enumerate(claimed):
            others = [*start, *claims[:i], *claims[i + 1 :]]
            scan = search.scan(effect, search.design(others) if others else None)
            claims[i] = effect if isinstance(scan, Candidate) else effect.with_settings(**scan.scanned[0][1])
        chain = [*start, *claims]
        touches = campaign_touches(campaign.subset(fold))
        before, after = (HybridModel(list(c), NESTED_DATA_PART).fit(sub, sub_train).predict_touches(touches) for c in (start, chain))
        return fold, before, after, [effect_label(e) for e in chain[len(start) :]]

    # The folds are independent: two at a time (numpy releases the GIL in the heavy parts).
    with ThreadPoolExecutor(max_workers=PARTS_AT_ONCE) as pool:
        results = list(pool.map(one_fold, groups))
    rings = np.concatenate([r[0] for r in results])
    measured = campaign.deviations[rings]
    before_all, after_all = np.concatenate([r[1] for r in results]), np.concatenate([r[2] for r in results])
    # Each predicted ring's fall in squared error over its touches, in its own noise variances: the
    # replication test over rings, on rings that took no part in the fit (issue 55).
    fall = ((measured - before_all) ** 2).sum(axis=(1, 2)) - ((measured - after_all) ** 2).sum(axis=(1, 2))
    gain = fall / np.maximum(ring_sigma(measured) ** 2, 1e-300)
    predicted_check = held_out[rings]
    return NestedAfter(
        folds=folds,
        rings=int(rings.size),
        before_um=metrics.mae(before_all, measured),
        after_um=metrics.mae(after_all, measured),
        noise_floor_um=campaign.noise_floor_um(),
        chosen=tuple(tuple(r[3]) for r in results),
        gain=replication(gain, predicted_check, seed=seed),
        check_rings=int(predicted_check.sum()),
    )


def reproduced_settings(candidate: Candidate, effect: Effect) -> list[dict[str, float]]:
    """The settings at which a fold reproduces a claim (`effect` at the candidate's settings): those
    the whole campaign does not exclude, and a period's neighbours on the scan's grid of whole
    cycles/rev (Effect.neighbour_settings: a head's period need not be whole; between two grid
    points, a fold with fewer rings takes either)."""
    allowed = [candidate.settings, *candidate.settings_not_excluded]
    periods = [s for s in allowed if set(s) == {"cycles_per_rev"}]
    return allowed + [n for s in periods for n in effect.with_settings(**s).neighbour_settings()]


def unsettled_claims(
    found: Sequence[Candidate], claimed: Sequence[Effect], nested: NestedAfter, untold: Untold | None = None
) -> dict[int, list[str]]:
    """The claims (indices into `found`) that more than MAX_FOLDS_EXCLUDED folds set where the whole
    campaign excludes, a grid step beyond (reproduced_settings), with those folds' labels: a setting
    the rings left out do not reproduce. untold(i, other): the rings as units do not tell claim i
    from `other` (the report's "cannot exclude", diagnosis.telling_apart: a setting is excluded only
    when the touches' profile likelihood and the rings both exclude it)."""
    unsettled = {}
    for i, (candidate, effect) in enumerate(zip(found, claimed)):
        allowed = {effect_label(effect.with_settings(**s)) for s in reproduced_settings(candidate, effect)}
        grid = {effect_label(effect.with_settings(**s)): s for s in effect.scan_grid()}
        moved = {fold[i] for fold in nested.chosen if fold[i] not in allowed}
        allowed |= {label for label in moved if untold is not None and label in grid and untold(i, effect.with_settings(**grid[label]))}
        excluded = [fold[i] for fold in nested.chosen if fold[i] not in allowed]
        if len(excluded) > MAX_FOLDS_EXCLUDED:
            unsettled[i] = excluded
    return unsettled


def held_out_claims(choice: Choice, campaign: Campaign, fixed: int, seed: int = 0) -> tuple[Choice, NestedAfter | None]:
    """The search's claims (beyond the chain's first `fixed` effects) kept when no two folds set one
    where the whole campaign excludes and their gain on rings left out is replicated
    (nested_after). Else the first claims the search took, one more at a time, are put to the same
    test while they pass (a fixed sequence: a strong claim does not sink with a weak one taken after
    it); the rest are withdrawn, each a suggestion, with why. A catalog effect that only fits what
    it cannot predict is no claim."""
    claimed, start = choice.chain[fixed:], choice.chain[:fixed]
    if not claimed:
        return choice, None
    bases = FittedBases(campaign_touches(campaign))
    honest = nested_after(campaign, claimed, start, seed, bases=bases)

    def untold(i: int, other: Effect) -> bool:
        # Beside the chain before claim i, as the report asks it; and the fold's setting a gain the
        # rings replicate there: of a claim that explains nothing, no two settings are told apart.
        search, before = choice.search, choice.chain[: fixed + i]
        if rings_prefer(search, claimed[i], other, before, seed).told_apart:
            return False
        noise = ring_sigma(search.campaign.deviations) ** 2
        gain = ring_gains(
            search.residual, search.design(before) if before else None, search.design([*before, other]), search.targets, noise
        )
        return replication(gain, ~search.train, True, seed).replicated

    if honest is None or (why := _not_replicated(choice.found, claimed, honest, untold)) is None:
        return choice, honest
    kept, kept_honest = 0, honest
    for count in range(1, len(claimed)):
        fewer = nested_after(campaign, claimed[:count], start, seed, bases=bases)
        if fewer is None or _not_replicated(choice.found[:count], claimed[:count], fewer, untold) is not None:
            break
        kept, kept_honest = count, fewer
    subject = "the claims chosen together do" if len(claimed) > 1 else "the claim does"
    note = f"{subject} not replicate on rings left out of the choice (nested cross-validation, {honest.folds} folds: {why})"
    if kept:
        note += f"; {', '.join(effect_label(e) for e in claimed[:kept])} {'replicates' if kept == 1 else 'replicate'} without it"
    claims = {_claim_of(c) for c in choice.found[kept:]}

    def withdrawn(candidate: Candidate) -> Candidate:
        if _claim_of(candidate) in claims and not candidate.suggested:
            return replace(candidate, suggested=True, note=note)
        return candidate

    chain = choice.chain[: fixed + kept]
    rankings = [[withdrawn(c) for c in ranking] for ranking in choice.rankings]
    # Claim k was taken from ranking k: its suggestion is that ranking's, asked beside the claims before it.
    taken = [rankings[k][next(j for j, c in enumerate(choice.rankings[k]) if c is choice.found[k])] for k in range(kept, len(choice.found))]
    after = choice.search.within_noise_after(chain, seed) if chain else None
    return replace(choice, found=list(choice.found[:kept]), chain=chain, after=after, rankings=rankings, withdrawn=taken), kept_honest


def _not_replicated(found: Sequence[Candidate], claimed: Sequence[Effect], honest: NestedAfter, untold: Untold) -> str | None:
    """Why the claims do not replicate on rings left out (unsettled settings, else the nested
    gain's reasons); None when they do."""
    unsettled = unsettled_claims(found, claimed, honest, untold)
    if unsettled:
        return "; ".join(_unsettled_text(claimed[i], excluded, honest.folds) for i, excluded in unsettled.items())
    if honest.gain_holds:
        return None
    assert honest.gain is not None  # gain_holds is True without it
    return "; ".join(honest.gain.reasons()) if honest.gain.rings else "no ring left out gains"


def _claim_of(candidate: Candidate) -> tuple[str, str]:
    return candidate.effect, repr(sorted(candidate.settings.items()))


def _unsettled_text(effect: Effect, excluded: list[str], folds: int) -> str:
    """'2 of 5 folds set b_axis_cyclic 9 cycles/rev at 5 cycles/rev, which the whole campaign excludes, beyond a step of its scan'."""
    settings = sorted({f.removeprefix(effect.id).strip() for f in excluded})
    return (
        f"{len(excluded)} of {folds} folds set {effect_label(effect)} at {' or '.join(settings)}, "
        "which the whole campaign excludes, beyond a step of its scan"
    )
