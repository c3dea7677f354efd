"""A claimed shape that catalog effects of its own kind explain: the catalog named, on the shape's evidence.

An error of the A joint alone is invisible to a lattice ring left out of a ring-out look (its B
neighbours carry it), so a catalog claim of it rests on the few check rings, while the shape
search sees it with whole A rows left out (shapes.view_of). When a shape is claimed, the catalog
effects of its axis and component groups (its own and those the rings cannot tell from it) are
taken in the shape's look, one at a time, each replicated over rings there as any claim is
(choice.claim_test); they are named in the shape's place only when the shape, refitted beside
them, gains nothing significant over rings (or the model is within noise): the catalog then
holds what the shape showed, with fewer parameters. Method:
docs/methods/shapes.md, "A shape the catalog holds".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

from ph_explorer.diagnosis.candidates import Candidate, Partner
from ph_explorer.diagnosis.choice import Choice, claim_test
from ph_explorer.diagnosis.ranking import rank_candidates
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.separation import shared_variance
from ph_explorer.diagnosis.shapes import Shape, look_at
from ph_explorer.diagnosis.telling_apart import fitted_beside, partner_test
from ph_explorer.effects import Effect
from ph_explorer.effects.error_functions import SHAPE_GROUPS

# At most this many catalog effects stand for one shape (two harmonics of one axis's error, and one more).
MAX_BEHIND = 3


@dataclass(frozen=True)
class Behind:
    """The catalog effects that hold a claimed shape, taken in its look, each with the ranking it
    was taken from (the look's, over the effects of the shape's groups)."""

    claims: list[Candidate]
    effects: list[Effect]
    rankings: list[list[Candidate]]


def of_groups(effects: Sequence[Effect], groups: Sequence[str]) -> list[Effect]:
    """The catalog effects whose axis and kind are those of one of the shape groups."""
    kinds = {(SHAPE_GROUPS[g].axis, SHAPE_GROUPS[g].kind) for g in groups}
    return [e for e in effects if e.axis is not None and (e.axis, e.kind) in kinds]


def catalog_behind(
    search: CandidateSearch, chain: Sequence[Effect], shape: Shape, effects: Sequence[Effect], seed: int = 0
) -> Behind | None:
    """The catalog effects that hold a claimed shape (module docstring), None when none do."""
    look = search if shape.leave_out == "ring" else search.in_rows()
    groups = [shape.group, *(g for g in shape.untold if SHAPE_GROUPS[g].axis is not None)]
    pool = of_groups(effects, groups)
    by_id = {e.id: e for e in pool}
    model, claims, taken, rankings = list(chain), [], [], []
    while pool and len(taken) < MAX_BEHIND:
        ranked = rank_candidates(look, pool, fixed=look.design(model) if model else None)
        taken_now = {(e.id, tuple(e.settings().items())) for e in taken}
        best = next(
            (c for c in ranked if (c.significant or c.beyond_noise) and (c.effect, tuple(c.settings.items())) not in taken_now), None
        )
        if best is None:
            return None
        effect = by_id[best.effect].with_settings(**best.settings)
        # Its size and U from the ring-out look's joint fit (a look with rows left out only chooses).
        params, params_u = search.fitted_u([*model, effect], len(model) + 1)[-1]
        best = replace(best, params=params, params_u=params_u)
        test = claim_test(look, effect, model, best, seed)
        if not test.replicated:
            return None
        model.append(effect)
        taken.append(effect)
        note = (
            f"claimed on the shape of the {shape.words} (p = {shape.family_p:.3g} over rings"
            f"{', A rows left out' if shape.leave_out == 'row' else ''}): beside {'them' if taken[:-1] else 'it'} "
            "that shape gains nothing significant over rings"
        )
        partners = untold_partners(search, look, effect, model[:-1], [c for c in ranked if c.effect != best.effect], by_id, seed)
        claims.append(
            replace(
                best,
                significant=True,
                suggested=False,
                beyond_noise=True,
                replication=test,
                note=note,
                confounded_with=partners,
                on_shape=shape.group,
            )
        )
        rankings.append(ranked)
        after = look.within_noise_after(model, seed)
        if after is None or not after.fails:
            break
        if not look_at(look, model, after, groups, seed, most=1)[0][0].replicated:
            break  # the shape refitted beside them gains nothing significant over rings
    else:
        return None
    return Behind(claims, taken, rankings)


def untold_partners(
    search: CandidateSearch,
    look: CandidateSearch,
    effect: Effect,
    chain: Sequence[Effect],
    others: Sequence[Candidate],
    by_id: dict[str, Effect],
    seed: int = 0,
) -> tuple[Partner, ...]:
    """The other effects of the shape's groups that the rings, in the shape's look, do not tell the
    claim from (telling_apart.partner_test, as a claim's confounded partners are asked): the claim is named with them, a pair the rings cannot tell."""
    out = []
    for other in others:
        test, standing_in = partner_test(look, effect, by_id[other.effect].with_settings(**other.settings), chain, seed)
        if not test.told_apart:
            shared = shared_variance(search.design([effect]), search.design([standing_in]))
            params = fitted_beside(search, standing_in, chain)
            out.append(Partner(other.effect, round(shared, 3), test=test, settings=(standing_in.settings(),), params=params))
    return tuple(out)


def spliced(ranking: Sequence[Candidate], claim: Candidate) -> list[Candidate]:
    """The ranking with the claim in its effect's place, first."""
    return [claim, *(c for c in ranking if c.effect != claim.effect)]


def held_by_catalog(choice: Choice, shapes: Sequence[Shape], effects: Sequence[Effect], seed: int = 0) -> tuple[Choice, list[Shape]]:
    """The choice with the catalog effects that hold its claimed shapes (catalog_behind) claimed, and
    the shapes left; the same choice when none does. The first such claim joins the ranking after
    the chain's last; each next comes with the ranking it was taken from; a last ranking of every
    effect follows with them all in the model."""
    left: list[Shape] = []
    for shape in shapes:
        behind = catalog_behind(choice.search, choice.chain, shape, effects, seed) if shape.claimed else None
        if behind is None:
            left.append(shape)
            continue
        search, chain = choice.search, [*choice.chain, *behind.effects]
        # A suggestion of an effect now claimed is that claim in every ranking (a copy: it was not taken there).
        first = {c.effect: c for c in reversed(behind.claims)}
        rankings = [[replace(first[c.effect]) if c.suggested and c.effect in first else c for c in r] for r in choice.rankings]
        rankings[-1] = spliced(rankings[-1], behind.claims[0])
        rankings += [spliced(r, c) for r, c in zip(behind.rankings[1:], behind.claims[1:])]
        rankings.append(rank_candidates(search, effects, fixed=search.design(chain)))
        choice = replace(
            choice,
            found=[*choice.found, *behind.claims],
            chain=chain,
            rankings=rankings,
            after=search.within_noise_after(chain, seed),
            withdrawn=[c for c in choice.withdrawn if c.effect not in first],
        )
    return choice, left
