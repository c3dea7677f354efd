"""Do this campaign's rings tell a candidate from a partner it is confounded with?

Two confounded candidates (partners.confounding) have columns that share most of their variance,
yet the share they do not have can still be many noise variances at a ring when the effect is
large. The question is answered as a claim is (diagnosis.replication), with rings as units: each
ring's out-of-sample sum of squares with the partner in the model less that with the candidate,
in the ring's own noise variances, tested over rings by sign flips (Student's t on few rings),
and still significant without the most influential ring. Method: docs/methods/deciding.md#told-apart.
The same question of a claim's own setting against the effect's other scanned settings (a period
two off) bounds what the rings say of its setting (`settings_told_apart`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from ph_explorer.blas import in_parts
from ph_explorer.diagnosis.candidates import Candidate, PairTest, RivalSetting
from ph_explorer.diagnosis.partners import partner_settings
from ph_explorer.diagnosis.replication import replication, ring_gains
from ph_explorer.diagnosis.rival_shapes import untold_shape
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.separation import shared_variance
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect
from ph_explorer.models import least_squares


def rings_prefer(search: CandidateSearch, effect: Effect, partner: Effect, chain: Sequence[Effect], seed: int = 0) -> PairTest:
    """Whether the rings prefer `effect` to `partner`, each added to `chain` (module docstring)."""
    gain = ring_gains(
        search.residual,
        search.design([*chain, partner]),
        search.design([*chain, effect]),
        search.targets,
        ring_sigma(search.campaign.deviations) ** 2,
    )
    test = replication(gain, ~search.train, True, seed)
    return PairTest(test.replicated, round(test.p_value, 5), round(test.p_without_top, 5), test.rings_gaining, test.rings)


def partner_test(
    search: CandidateSearch, effect: Effect, partner: Effect, chain: Sequence[Effect], seed: int = 0
) -> tuple[PairTest, Effect]:
    """The partner at each setting that stands in for the effect (partners.partner_settings), put to
    the rings where they favour it most (rings_prefer, the largest p-value): told apart only from
    every one of them. Returns that test and the partner at that setting."""
    standing_in = partner_settings(effect, partner)
    tests = list(zip(in_parts(lambda o: rings_prefer(search, effect, o, chain, seed), standing_in), standing_in))
    return max(tests, key=lambda t: t[0].p_value)


def tell_apart(
    search: CandidateSearch,
    candidates: Sequence[Candidate],
    claimed: Sequence[str],
    by_id: dict[str, Effect],
    start: Sequence[Effect],
    seed: int = 0,
) -> list[Candidate]:
    """The candidates, each claimed or suggested one with its closest confounded partners' PairTest
    (rings_prefer) and its own setting asked against the effect's others (settings_told_apart), each
    claim with the shape of another variable its rings cannot tell it from (rival_shapes.untold_shape);
    the chain before them is `start`."""
    settings = {c.effect: c.settings for c in candidates}
    out = []
    for candidate in candidates:
        if not (candidate.effect in claimed or candidate.suggested):
            out.append(candidate)
            continue
        effect = by_id[candidate.effect].with_settings(**candidate.settings)
        partners = []
        for p in candidate.confounded_with:
            if p.separated_by is None:  # beyond the closest partners (no separation asked) the rings are not asked either
                partners.append(p)
                continue
            standing_in = by_id[p.effect].with_settings(**(p.settings[0] if p.settings else settings.get(p.effect, {})))
            test, other = partner_test(search, effect, standing_in, start, seed)
            first = (other.settings(), *(s for s in p.settings if s != other.settings()))
            params = {} if test.told_apart else fitted_beside(search, other, start)
            partners.append(replace(p, settings=first, test=test, params=params))
        candidate = replace(candidate, confounded_with=tuple(partners))
        if candidate.effect in claimed:
            candidate = replace(candidate, untold_shape=untold_shape(search, effect, start, seed))
        out.append(settings_told_apart(search, candidate, effect, start, seed) if candidate.settings else candidate)
    return out


def settings_told_apart(search: CandidateSearch, candidate: Candidate, chosen: Effect, start: Sequence[Effect], seed: int = 0) -> Candidate:
    """The candidate with every other scanned setting of its effect (`chosen`: at its own) that the
    rings do not tell from the chosen (rings_prefer, the chosen in the partner's place) in its
    settings_not_excluded, in scan order: a setting is excluded only when the touches' profile
    likelihood and the rings as units both exclude it. The closest of them (the largest p-value)
    with a plausible fit is its rival_setting, fitted, for the rings that would decide (planning.deciding)."""
    others = [s for s in chosen.scan_grid() if s != candidate.settings]
    tests = list(zip(others, in_parts(lambda s: rings_prefer(search, chosen, chosen.with_settings(**s), start, seed), others)))
    kept = [(s, test) for s, test in tests if not test.told_apart]
    if not kept:
        return candidate
    not_excluded = tuple(s for s in others if s in candidate.settings_not_excluded or any(s == k for k, _ in kept))
    # The closest plausible one: an implausible fit is never the explanation (the closest when none is).
    kept.sort(key=lambda item: item[1].p_value, reverse=True)
    closest = None
    for settings, test in kept:
        params = fitted_beside(search, chosen.with_settings(**settings), start)
        closest = closest or (settings, test, params)
        if not chosen.implausible(params):
            break
    else:
        settings, test, params = closest
    rival = chosen.with_settings(**settings)
    shared = shared_variance(search.design([chosen]), search.design([rival]))
    return replace(candidate, settings_not_excluded=not_excluded, rival_setting=RivalSetting(settings, params, round(shared, 3), test))


def fitted_beside(search: CandidateSearch, effect: Effect, start: Sequence[Effect]) -> dict[str, float]:
    """The effect's parameters fitted beside `start` (a rival setting or an untold partner, for the
    rings that would decide: planning.deciding)."""
    own = least_squares.fit(search.design([*start, effect]), search.targets)[0][-search.design([effect]).n_columns :, 0]
    return {k: float(v) for k, v in effect.from_coefficients(own).items()}
