"""What the rings can show of an unknown shape at all: an oracle's test, the bound of a shape search.

The head's own hidden shape, its function known exactly and its size free (one column), is fitted
beside the diagnosis's chain on the same out-of-sample residual as the shape search's groups, each
ring left out in turn, and its rings' gains go through the same replication test as a shape's
(diagnosis.replication: over rings, and without its most influential ring). The oracle pays for
no choice among groups, no knots and no materiality: where it fails, no search over these rings
can replicate that shape. A function of the A joint shows only at rings off the lattice's A rows
(docs/physics.md, section 6): lattice rings add no unit there (their gain is zero).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.replication import REPLICATION_LEVEL, replication, ring_residual_squares
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect
from ph_explorer.models.hybrid import fitted_columns
from ph_explorer.models.least_squares import Design


def oracle_record(campaign: Campaign, result: Diagnosis, shape: Effect) -> dict[str, Any]:
    """The oracle's replication test of `shape` (a twin effect of the head) beside the diagnosis's chain."""
    search = CandidateSearch(campaign, ~campaign.holdout_mask(), detail=False)
    fixed = search.design(list(result.chain)) if result.chain else None
    touches = search.touches
    deviations = shape.forward(touches, np.random.default_rng(0))[..., None]
    column = Design(fitted_columns(deviations, touches), search.smoother)
    joint = column if fixed is None else fixed.stacked(column)
    before = ring_residual_squares(search.residual, fixed, search.targets)
    after = ring_residual_squares(search.residual, joint, search.targets)
    gain = (before - after) / np.maximum(ring_sigma(campaign.deviations) ** 2, 1e-300)
    test = replication(gain, ~search.train)
    return {
        "p": round(test.p_value, 5),
        "p_without_top": round(test.p_without_top, 5),
        "units": test.rings,  # rings whose gain is not zero (the others cannot see the shape)
        "passes": bool(test.p_value < REPLICATION_LEVEL and test.p_without_top < REPLICATION_LEVEL),
    }
