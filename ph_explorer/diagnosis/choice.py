"""The search's choice: which catalog effects to add, one at a time, and the tests around it.

`choose_effects` runs on any campaign and training set: the diagnosis runs it on the whole
campaign, and the nested cross-validation (ph_explorer.diagnosis.nested) on each fold's campaign.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import Candidate
from ph_explorer.diagnosis.fitted_bases import FittedBases
from ph_explorer.diagnosis.form import form_breaks
from ph_explorer.diagnosis.ranking import rank_candidates
from ph_explorer.diagnosis.replication import (
    Replication,
    determined_size,
    replication,
    ring_gains,
    ring_residual_squares,
    ring_weights,
)
from ph_explorer.diagnosis.rival_shapes import outpredicting_shape
from ph_explorer.diagnosis.search import MATERIAL_REDUCTION, RINGS_BROUGHT_WITHIN, SHARE_BROUGHT_WITHIN, CandidateSearch
from ph_explorer.diagnosis.telling_apart import rings_prefer
from ph_explorer.diagnosis.within_noise import NoiseTest, ring_sigma
from ph_explorer.effects import Effect
from ph_explorer.models import least_squares


def base_gain(search: CandidateSearch, effect: Effect, beside: Sequence[Effect]) -> float:
    """The rings' weighted out-of-sample gain (ring_gains; check and lattice rings half each) of a
    base effect added beside the others: none (0) within the rounding of the sums it is the fall
    of, as for an effect the others span (on any rings the location errors of two axes share
    directions), whatever the sign the rounding gives it."""
    weights = ring_weights(~search.train) / np.maximum(ring_sigma(search.campaign.deviations) ** 2, 1e-300)
    before = float(weights @ ring_residual_squares(search.residual, search.design(beside) if beside else None, search.targets))
    gain = before - float(weights @ ring_residual_squares(search.residual, search.design([*beside, effect]), search.targets))
    return gain if abs(gain) > 1e-9 * before else 0.0


def implausible_in_fit(search: CandidateSearch, chain: Sequence[Effect]) -> list[bool]:
    """Per effect of the chain, whether its parameters in the chain's joint fit lie outside its
    plausible ranges (Effect.implausible): a size the rings cannot determine, which the data part
    would undo only where rings were measured."""
    coefficients = least_squares.fit(search.design(chain), search.targets)[0][:, 0]
    edges = np.cumsum([0, *(search.design([effect]).n_columns for effect in chain)])
    return [bool(e.implausible(e.from_coefficients(coefficients[a:b]))) for e, a, b in zip(chain, edges[:-1], edges[1:])]


def usable_base(search: CandidateSearch, base: Sequence[Effect], claims: Sequence[Effect] = ()) -> list[Effect]:
    """The base model's effects that predict rings left out better than the model without them, at
    a plausible size (implausible_in_fit). Before the search (no claims): each in turn, kept when
    its gain beside those kept is positive and its fit there plausible; then, while one is
    implausible in the fit of them all, the first such dropped. With the claims: those kept, an
    implausible one, else the one of least gain beside all the rest, dropped while its gain is not
    positive. A location error a few rings cannot determine adds more to what they miss than it
    removes; one that stood in for a claim is not needed beside it."""
    kept: list[Effect] = []
    if not claims:
        for effect in base:
            usable = base_gain(search, effect, kept) > 0.0 and not implausible_in_fit(search, [*kept, effect])[-1]
            kept += [effect] if usable else []
        while any(implausible := implausible_in_fit(search, kept) if kept else []):
            kept.pop(implausible.index(True))  # plausible beside those before it, not beside them all
        return kept
    kept = list(base)
    while kept:
        implausible = implausible_in_fit(search, [*kept, *claims])  # one joint fit for every kept effect
        gains = [
            -math.inf if bad else base_gain(search, e, [*(k for k in kept if k is not e), *claims]) for e, bad in zip(kept, implausible)
        ]
        if min(gains) > 0.0:
            break
        kept.pop(len(gains) - 1 - int(np.argmin(gains[::-1])))  # of equal gains, the last in the base's order
    return kept


def claim_test(search: CandidateSearch, effect: Effect, chain: Sequence[Effect], fitted: Candidate, seed: int = 0) -> Replication:
    """The test a claim passes, the effect added to `chain`: its gain replicated over rings with its
    size determined by `fitted`'s parameters (diagnosis.replication), its form holding over the
    head (diagnosis.form), and no shape of another variable predicting the rings better in its
    place (rival_shapes.outpredicting_shape)."""
    before = search.design(chain) if chain else None
    gain = ring_gains(search.residual, before, search.design([*chain, effect]), search.targets, ring_sigma(search.campaign.deviations) ** 2)
    test = replication(gain, ~search.train, determined_size(fitted.params, fitted.params_u, effect.amplitudes()), seed)
    if test.replicated:
        test = replace(test, form_breaks=form_breaks(search, effect, chain, seed))
    if test.replicated:
        test = replace(test, outpredicted=outpredicting_shape(search, effect, chain, seed))
    return test


def scanned_beside(search: CandidateSearch, effect: Effect, others: Sequence[Effect]) -> Candidate:
    """The effect's scan judged on its own null with `others` in the model: its best setting there."""
    return rank_candidates(search, [effect], fixed=search.design(others) if others else None)[0]


def replicated(
    search: CandidateSearch, candidate: Candidate, chain: Sequence[Effect], by_id: dict[str, Effect], seed: int = 0
) -> Candidate:
    """The candidate with its gain's test over rings (diagnosis.replication); when it is not
    replicated, marked suggested, with why and the rings that carry it."""
    test = claim_test(search, by_id[candidate.effect].with_settings(**candidate.settings), chain, candidate, seed)
    if test.replicated:
        return replace(candidate, replication=test)
    o = search.campaign.orientations
    carried = ", ".join(f"A{o[i, 0]:g} B{o[i, 1]:g}" for i in test.carried_by)
    note = f"not replicated over rings: {'; '.join(test.reasons())}" + (f"; the rings that gain most: {carried}" if carried else "")
    return replace(candidate, replication=test, suggested=True, note=note)


def next_found(
    ranked: Sequence[Candidate],
    current: NoiseTest | None,
    search: CandidateSearch,
    campaign: Campaign,
    chain: Sequence[Effect],
    by_id: dict[str, Effect],
    seed: int = 0,
) -> tuple[list[Candidate], tuple[Candidate, NoiseTest | None] | None]:
    """The ranking with what the search learnt of its candidates, and the next effect the search
    takes, best ranked first, with the within-noise test of the chain with it; None when none is
    (docs/diagnosis.md, step 2).

    Only while the model fails the within-noise test (one yardstick; a campaign of one repetition
    has no test). Taken: a significant candidate, or one beyond noise and plausible that brings
    at least RINGS_BROUGHT_WITHIN, and SHARE_BROUGHT_WITHIN, of the exceeding rings within noise
    (a failure the check rings do not see); either replicated over rings (`replicated`), else
    suggested and the next tried.
    """
    ranked = list(ranked)
    if current is not None and not current.fails:
        note = "lowers the check rings' error, but the model is within noise without it"
        return [replace(c, not_needed=True, note=c.note or note) if c.significant else c for c in ranked], None
    for index, candidate in enumerate(ranked):
        if not candidate.significant and not (candidate.beyond_noise and current is not None and current.fails):
            continue
        test = search.within_noise_after([*chain, by_id[candidate.effect].with_settings(**candidate.settings)], seed)
        if not candidate.significant:
            brought = max(RINGS_BROUGHT_WITHIN, math.ceil(SHARE_BROUGHT_WITHIN * current.failing_rings))
            if test is None or test.failing_rings > current.failing_rings - brought:
                continue
            note = f"brings {current.failing_rings - test.failing_rings} of the {current.failing_rings} rings that exceed their noise within it (the check rings alone do not show it)"
            candidate = replace(candidate, significant=True, note=note)
        ranked[index] = candidate = replicated(search, candidate, chain, by_id, seed)
        if not candidate.suggested:
            return ranked, (candidate, test)
    return ranked, None


# Candidates tried in turn as a pair's first: the best beyond noise may be one the rings cannot
# tell from the effect the head holds (radial motion for tilt motion of the same period), whose
# form breaks beside any second.
PAIR_FIRSTS = 3


def claimed_together(
    ranked: Sequence[Candidate],
    current: NoiseTest | None,
    search: CandidateSearch,
    campaign: Campaign,
    chain: Sequence[Effect],
    by_id: dict[str, Effect],
    seed: int = 0,
) -> tuple[list[Candidate], list[Candidate], list[Candidate], NoiseTest | None] | None:
    """Two effects that only replicate together (two harmonics of one axis's error: a beat), taken
    where one at a time stalls (docs/diagnosis.md, step 2): a candidate beyond noise (the best,
    else the next, at most PAIR_FIRSTS), the best beyond noise with it in the model, and the first
    again with the second in it (its setting refitted). Taken when each is beyond noise beside the
    other, their gain together is replicated over rings and material (the check rings' error, or
    rings brought within noise), and each one's own gain beside the other is replicated too, so
    that no passenger rides on its partner.
    Returns (the ranking it started from, the ranking with the first in the model, both holding
    the claims; the two claims; the test with both), None when none is taken."""
    if current is None or not current.fails:
        return None
    seen = [c for c in ranked if c.beyond_noise or c.significant]
    for first in seen[:PAIR_FIRSTS]:
        taken = _pair_from(first, ranked, current, search, campaign, chain, by_id, seed)
        if taken is not None:
            return taken
    return None


def _pair_from(
    first: Candidate,
    ranked: Sequence[Candidate],
    current: NoiseTest,
    search: CandidateSearch,
    campaign: Campaign,
    chain: Sequence[Effect],
    by_id: dict[str, Effect],
    seed: int,
) -> tuple[list[Candidate], list[Candidate], list[Candidate], NoiseTest | None] | None:
    """claimed_together's pair with `first` as its first, or None."""
    start = list(chain)
    beside = search.design([*start, by_id[first.effect].with_settings(**first.settings)])
    step = rank_candidates(search, list(by_id.values()), fixed=beside, beyond_only=True)  # the whole ranking only for a pair taken
    same = (first.effect, first.settings)
    second = next((c for c in step if (c.beyond_noise or c.significant) and (c.effect, c.settings) != same), None)
    if second is None:
        return None
    # The first refitted beside the second, and the second beside that (one pass of backfitting).
    first = scanned_beside(search, by_id[first.effect], [*start, by_id[second.effect].with_settings(**second.settings)])
    pair = [by_id[first.effect].with_settings(**first.settings)]
    second = scanned_beside(search, by_id[second.effect], [*start, *pair])
    pair.append(by_id[second.effect].with_settings(**second.settings))
    if (
        not all(c.beyond_noise or c.significant for c in (first, second))
        or pair[0].settings() == pair[1].settings()
        and pair[0].id == pair[1].id
    ):
        return None
    test = search.within_noise_after([*start, *pair], seed)
    before = search.design(start) if start else None
    both = search.design([*start, *pair])
    reduction = search.check_reduction(both, search.check_residual(before))
    brought = max(RINGS_BROUGHT_WITHIN, math.ceil(SHARE_BROUGHT_WITHIN * current.failing_rings))
    if reduction < MATERIAL_REDUCTION and (test is None or test.failing_rings > current.failing_rings - brought):
        return None
    noise = ring_sigma(campaign.deviations) ** 2
    determined = all(determined_size(c.params, c.params_u, by_id[c.effect].amplitudes()) for c in (first, second))
    together = replication(ring_gains(search.residual, before, both, search.targets, noise), ~search.train, determined, seed)
    if not together.replicated:
        return None
    # Each one a claim beside the other: its own gain replicated, its form holding.
    if not all(claim_test(search, pair[i], [*start, pair[1 - i]], c, seed).replicated for i, c in enumerate((first, second))):
        return None
    names = [first.name, second.name]
    claims = [
        replace(
            c,
            significant=True,
            suggested=False,
            replication=together,
            note=f"claimed together with {names[1 - i]}: one at a time, the search took neither",
        )
        for i, c in enumerate((first, second))
    ]
    ranked = [claims[0] if c.effect == claims[0].effect else c for c in ranked]
    step = [claims[1] if c.effect == claims[1].effect else c for c in rank_candidates(search, list(by_id.values()), fixed=beside)]
    return ranked, step, claims, test


def chosen_beside(
    search: CandidateSearch, claim: Candidate, others: Sequence[Effect], by_id: dict[str, Effect], seed: int = 0
) -> Candidate:
    """What the search takes in a claim's place with `others` in the model: the best significant
    effect of the whole ranking there when it is another effect than the claim's and the rings
    prefer it to the claim (telling_apart.rings_prefer: an effect taken while a later one was still
    missing may have stood in for it; a hair's better fit is no reason), else the claim's own
    effect at its best setting, scanned on its own null."""
    ranked = rank_candidates(search, list(by_id.values()), fixed=search.design(others))
    free = (c for c in ranked if not any(e.id == c.effect and e.settings() == c.settings for e in others))
    best = next(free, None)
    if best is not None and best.significant and best.effect != claim.effect:
        effect, was = (by_id[c.effect].with_settings(**c.settings) for c in (best, claim))
        if rings_prefer(search, effect, was, others, seed).told_apart:
            return best
    return scanned_beside(search, by_id[claim.effect], others)


def refitted(
    search: CandidateSearch,
    chain: list[Effect],
    found: list[Candidate],
    rankings: list[list[Candidate]],
    by_id: dict[str, Effect],
    seed: int = 0,
    last_settled: bool = False,
) -> bool:
    """Each effect taken, chosen again with every other effect of the chain in the model (a
    selection with refits and swaps, docs/diagnosis.md, step 2): a setting chosen while a later
    effect was still missing (a period between two harmonics, one off beside another axis's
    error) moves to the best one beside the others, and an effect that stood in for another
    gives way to the effect the ranking puts first there (chosen_beside), when the claim at it is
    replicated over rings and of its form beside them. chain, found and the ranking each came
    from are changed in place; True when any moved. last_settled: the last effect was taken alone
    from the ranking beside all the others (next_found), so it stays unless one before it moved."""
    moved = False
    first = len(chain) - len(found)  # the effects the search started from are not refitted
    for j, claim in enumerate(found):
        if last_settled and not moved and j == len(found) - 1:
            break  # that ranking was made, and its claim chosen, beside these very others
        k = first + j
        others = chain[:k] + chain[k + 1 :]
        again = chosen_beside(search, claim, others, by_id, seed)
        taken = any(e.id == again.effect and e.settings() == again.settings for e in others)
        same = (again.effect, again.settings) == (claim.effect, claim.settings)
        if same or not again.beyond_noise or taken or not swappable(rankings, claim, again, found):
            continue
        effect = by_id[again.effect].with_settings(**again.settings)
        test = claim_test(search, effect, others, again, seed)
        if not test.replicated:
            continue
        was = ", ".join(f"{v:g}" for v in claim.settings.values())
        note = f"its setting refitted beside the other effects (was {was})"
        if again.effect != claim.effect:
            note = f"taken in place of {claim.name} {was} beside the other effects"
        new = replace(again, significant=True, suggested=False, replication=test, note=note)
        gave_way = replace(claim, not_needed=True, note=f"{again.name} explains more in its place beside the other effects")
        for ranking in rankings:
            if any(c is claim for c in ranking):
                ranking[:] = [new if c is claim else gave_way if c.effect == again.effect != claim.effect else c for c in ranking]
        found[j], chain[k], moved = new, effect, True
    return moved


def swappable(rankings: list[list[Candidate]], claim: Candidate, again: Candidate, found: list[Candidate]) -> bool:
    """Whether `again` can take the claim's place in the ranking the claim came from: its own
    effect's entry there is no other claim (two claims of one effect come from two rankings)."""
    return not any(
        c.effect == again.effect and c is not claim and any(c is f for f in found)
        for r in rankings
        if any(x is claim for x in r)
        for c in r
    )


@dataclass
class Choice:
    """What the search chose on one campaign: the tests before and after, and every ranking."""

    search: CandidateSearch
    before: NoiseTest | None  # the baseline's within-noise test
    found: list[Candidate]  # the effects taken, in order
    chain: list[Effect]  # base + start + the effects taken, at their chosen settings
    after: NoiseTest | None  # the test with the chain in the model (None: nothing in it)
    rankings: list[list[Candidate]]  # the ranking before every step and after the last
    based: NoiseTest | None = None  # with the base model in it (before when there is none): what the verdict judges
    base: list[Effect] = field(default_factory=list)  # the base model's effects kept (usable_base), first in the chain
    # Claims the folds withdrew (nested.held_out_claims), each the ranking's own candidate it was taken from.
    withdrawn: list[Candidate] = field(default_factory=list)

    @property
    def candidates(self) -> list[Candidate]:
        """The first ranking."""
        return self.rankings[0]

    @property
    def remaining(self) -> list[Candidate]:
        return self.rankings[-1]


def choose_effects(
    campaign: Campaign,
    train: NDArray[np.bool_],
    effects: Sequence[Effect],
    max_steps: int = 3,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
    start: Sequence[Effect] = (),
    detail: bool = True,
    bases: FittedBases | None = None,
    base: Sequence[Effect] = (),
    on_stall: Callable[[CandidateSearch, list[Effect], NoiseTest], Callable[[], None]] | None = None,
) -> Choice:
    """The search's chain on the training rings: the best candidate taken (next_found), the search
    again with it in the model, ... at most max_steps effects beyond `start` (effects already in
    the model, e.g. a resumed study's); detail: the candidates' uncertainties and evidence (a
    search that only chooses needs neither); bases: fitted columns shared with other searches on
    subsets of the same touches (CandidateSearch); base: effects in the model before the search,
    never claimed, those the rings can use (usable_base; `based` tests the model with them);
    on_stall: given the search, the chain and its failing test when one at a time stalls, before
    the pair search (diagnosis.loop.ShapesAhead looks for the shapes from there); what it returns
    is called when a pair is taken and the chain moves on (the look is dropped)."""
    by_id = {e.id: e for e in effects}
    # Where it fails: leave-one-out residuals at training rings, the training fit at check rings.
    search = CandidateSearch(campaign, train, seed, detail, bases)
    before = search.within_noise_after([], seed)
    base = usable_base(search, base)
    chain = [*base, *start]
    based = search.within_noise_after(base, seed) if base else before
    current = search.within_noise_after(chain, seed) if start else based
    after = current if chain else None
    rankings = [rank_candidates(search, effects, fixed=search.design(chain) if chain else None, progress=progress)]
    found: list[Candidate] = []
    while rankings[-1] and len(found) < max_steps:
        rankings[-1], taken = next_found(rankings[-1], current, search, campaign, chain, by_id, seed)
        if taken is None:
            stalled = on_stall(search, list(chain), current) if on_stall is not None and current is not None and current.fails else None
            together = (
                claimed_together(rankings[-1], current, search, campaign, chain, by_id, seed) if len(found) + 2 <= max_steps else None
            )
            if together is None:
                break
            if stalled is not None:
                stalled()
            rankings[-1], step, pair, current = together
            found += pair
            chain += [by_id[c.effect].with_settings(**c.settings) for c in pair]
            rankings.append(step)
        else:
            pick, current = taken
            found.append(pick)
            chain.append(by_id[pick.effect].with_settings(**pick.settings))
        if len(found) > 1 and refitted(search, chain, found, rankings, by_id, seed, last_settled=taken is not None):
            current = search.within_noise_after(chain, seed)
        after = current
        # Search again with the chain in the model; an effect found may be found again at another
        # setting (a second period of the same axis error).
        rankings.append(rank_candidates(search, effects, fixed=search.design(chain), progress=progress))
    if base and found:  # the base beside the claims: what a claim now explains needs no location error
        kept = usable_base(search, base, chain[len(base) :])
        if len(kept) < len(base):
            base, chain = kept, [*kept, *chain[len(base) :]]
            after = search.within_noise_after(chain, seed)
            rankings[-1] = rank_candidates(search, effects, fixed=search.design(chain), progress=progress)
    return Choice(search, before, found, chain, after, rankings, based, base)
