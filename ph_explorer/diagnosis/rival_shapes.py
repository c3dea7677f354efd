"""A claim against the shapes of the variables it is not a function of: another axis's error
functions, or the probe's lobes in time for an axis's effect (diagnosis.shapes), each fitted in
the claim's place. A rival that predicts the rings better and leaves the claim nothing to add
outpredicts it (the claim is suggested); one the claim does not beat is named beside it, as an
untold pair. Method: docs/methods/replication.md#outpredicted.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ph_explorer.diagnosis.candidates import PairTest, UntoldShape
from ph_explorer.diagnosis.fitted_bases import settings_key
from ph_explorer.diagnosis.replication import REPLICATION_LEVEL, RivalShape, family_test, replication, ring_residual_squares
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.shapes import fit_group, fit_groups
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect
from ph_explorer.effects.error_functions import SHAPE_GROUPS


@dataclass
class _Rivals:
    """The shapes of the variables an effect is not a function of (a group of another axis, or the
    probe's lobes in time for an axis's effect), each fitted in the effect's place beside a chain:
    each ring's gain and left-out sum of squares with each."""

    keys: list[str]
    gains: NDArray[np.float64]  # (rivals, n_o) in noise variances
    squares: NDArray[np.float64]  # (rivals, n_o)
    gain: NDArray[np.float64]  # (n_o,) each ring's gain with the effect itself in that place
    noise: NDArray[np.float64]
    check: NDArray[np.bool_]


def _rivals(search: CandidateSearch, effect: Effect, chain: Sequence[Effect]) -> _Rivals | None:
    key = (settings_key(effect), tuple(settings_key(e) for e in chain))
    if key in search.rival_shapes:
        return search.rival_shapes[key]
    keys = [group for group, spec in SHAPE_GROUPS.items() if spec.axis != effect.axis]
    out = None
    if keys:
        fixed = search.design(list(chain)) if chain else None
        noise = ring_sigma(search.campaign.deviations) ** 2
        before = ring_residual_squares(search.residual, fixed, search.targets)
        with_effect = ring_residual_squares(search.residual, search.design([*chain, effect]), search.targets)
        fits = list(fit_groups(search, fixed, before, keys, noise).values())
        gains, squares = np.stack([f.gain for f in fits]), np.stack([f.squares for f in fits])
        out = _Rivals(keys, gains, squares, (before - with_effect) / np.maximum(noise, 1e-300), noise, ~search.train)
    search.rival_shapes[key] = out
    return out


def outpredicting_shape(search: CandidateSearch, effect: Effect, chain: Sequence[Effect], seed: int = 0) -> RivalShape | None:
    """The shape of a variable other than the effect's own that predicts the rings better than the
    effect in its place (added to `chain`) and leaves it nothing to add, None when none does. The
    best rival's gain over the effect's is tested over rings as the best of the rivals (family_test)
    and without its most influential ring; and the effect's own gain beside it must not replicate
    (a rival that gains more on another error, not yet claimed, leaves the effect its own gain)
    (docs/methods/replication.md#outpredicted)."""
    rivals = _rivals(search, effect, chain)
    if rivals is None:
        return None
    over = rivals.gains - rivals.gain[None]
    statistics, family_p = family_test(over, rivals.check, seed, standardise=True)
    best = int(np.argmax(statistics))
    without_top = replication(over[best], rivals.check, True, seed).p_without_top
    if family_p >= REPLICATION_LEVEL or without_top >= REPLICATION_LEVEL:
        return None
    claimed = search.design([*chain, effect])
    key = rivals.keys[best]
    beside = fit_group(search, claimed, ring_residual_squares(search.residual, claimed, search.targets), key, rivals.noise)
    if replication((rivals.squares[best] - beside.squares) / np.maximum(rivals.noise, 1e-300), rivals.check, True, seed).replicated:
        return None
    return RivalShape(key, SHAPE_GROUPS[key].words, round(family_p, 5), round(without_top, 5))


def untold_shape(search: CandidateSearch, effect: Effect, chain: Sequence[Effect], seed: int = 0) -> UntoldShape | None:
    """The shape of a variable other than a claim's own that its rings cannot tell it from: a rival
    (as outpredicting_shape's) whose gain in its place the claim's does not beat over rings (the
    replication test, and without its most influential ring); the closest (largest p-value) of
    them, None when the claim beats every one (docs/methods/replication.md#outpredicted)."""
    rivals = _rivals(search, effect, chain)
    if rivals is None:
        return None
    tests = [(key, replication(rivals.gain - gain, rivals.check, True, seed)) for key, gain in zip(rivals.keys, rivals.gains)]
    untold = [(key, t) for key, t in tests if not (t.p_value < REPLICATION_LEVEL and t.p_without_top < REPLICATION_LEVEL)]
    if not untold:
        return None
    key, test = max(untold, key=lambda item: item[1].p_value)
    return UntoldShape(
        key, SHAPE_GROUPS[key].words, PairTest(False, round(test.p_value, 5), round(test.p_without_top, 5), test.rings_gaining, test.rings)
    )
