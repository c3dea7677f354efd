"""What the rings can show of an unknown shape at all: an oracle's test, the bound of a shape search.

The head's own hidden shape, its function known exactly and its size free (one column), is fitted
beside the diagnosis's chain on the same out-of-sample residual as the shape search's groups, each
ring left out in turn, and its rings' gains go through the same replication test as a shape's
(diagnosis.replication: over rings, and without its most influential ring). The oracle pays for
no choice among groups, no knots and no materiality: where it fails, no search over these rings
can replicate that shape. A function of the A joint shows only at rings off the lattice's A rows
(docs/physics.md, section 6): by ring, lattice rings add no unit there. The shapes' second look
(whole inner A rows left out) is the oracle's too: where the shape's column is unseen at more than
least_squares.UNSEEN_SHARE of training rings, it passes if either view passes (a bound: no Bonferroni).
The heads with several catalog effects have theirs (effects_oracle): each effect at its own
settings, beside the others, by ring. right_group_ratio is what a shape of the truth's own group
brings once added: it pays for no choice among groups, and keeps the search's knots and penalty.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from benchmarks.calibration import over_floor
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.loop import add_effects
from ph_explorer.diagnosis.replication import REPLICATION_LEVEL, replication, ring_residual_squares
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.shapes import knots
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect
from ph_explorer.effects.error_functions import error_function
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.hybrid import fitted_columns
from ph_explorer.models.least_squares import Design


def oracle_record(campaign: Campaign, result: Diagnosis, shape: Effect) -> dict[str, Any]:
    """The oracle's replication test of `shape` (a twin effect of the head) beside the diagnosis's
    chain, by ring and, where the search would give it a second look, with whole A rows left out."""
    search = CandidateSearch(campaign, ~campaign.holdout_mask(), detail=False)
    deviations = shape.forward(search.touches, np.random.default_rng(0))[..., None]
    fitted = fitted_columns(deviations, search.touches)
    record = _beside_chain(search, result, fitted)
    if Design(fitted, search.smoother).unseen_at_most(search.train):
        by_row = _beside_chain(search.in_rows(), result, fitted)
        record = record | {"by_row": by_row, "passes": record["passes"] or by_row["passes"]}
    return record


def right_group_ratio(campaign: Campaign, result: Diagnosis, group: str) -> float:
    """The check rings' MAE over their floor (against the mean) once the truth's own group of error
    functions, at the knots the shape search gives it, is added beside the diagnosis's chain as the
    diagnosis adds a shape (diagnosis.loop.add_effects): what a shape of the right group brings,
    whatever the search claims. Where it stays far above the head's own error without the shape,
    the rings do not determine the shape's values where the check rings need them."""
    grid, periodic, *_ = knots(group, campaign_touches(campaign), ~campaign.holdout_mask())
    _, step = add_effects(campaign, [*result.chain, error_function(group, grid, periodic)()])
    return over_floor(step)


def effects_oracle(campaign: Campaign, effects: list[Effect]) -> list[dict[str, Any]]:
    """A head's several catalog effects (benchmarks/multi_effects.py), each at its own settings
    beside the others, through the same replication test by ring: where one fails, no search can
    claim it replicated, whatever it chooses (a bound, as the shape's: it pays for no choice)."""
    search = CandidateSearch(campaign, ~campaign.holdout_mask(), detail=False)
    out = []
    for i, effect in enumerate(effects):
        others = [*effects[:i], *effects[i + 1 :]]
        out.append(_tested(search, search.design(others) if others else None, search.design([*others, effect])))
    return out


def _beside_chain(search: CandidateSearch, result: Diagnosis, fitted: Any) -> dict[str, Any]:
    """The replication test of the fitted column beside the chain, in the search's view."""
    fixed = search.design(list(result.chain)) if result.chain else None
    column = Design(fitted, search.smoother)
    return _tested(search, fixed, column if fixed is None else fixed.stacked(column))


def _tested(search: CandidateSearch, fixed: Design | None, joint: Design) -> dict[str, Any]:
    """The replication test of what `joint` adds to `fixed` (None: the baseline), by ring."""
    before = ring_residual_squares(search.residual, fixed, search.targets)
    after = ring_residual_squares(search.residual, joint, search.targets)
    gain = (before - after) / np.maximum(ring_sigma(search.campaign.deviations) ** 2, 1e-300)
    test = replication(gain, ~search.train)
    return {
        "p": round(test.p_value, 5),
        "p_without_top": round(test.p_without_top, 5),
        "units": test.rings,  # rings whose gain is not zero (the others cannot see the shape)
        "passes": bool(test.p_value < REPLICATION_LEVEL and test.p_without_top < REPLICATION_LEVEL),
    }
