"""Does a claim's form hold across the head? A catalog effect has one set of parameters for the
whole head: the same amplitude and phase at every orientation and at every moment of the
campaign. An error that only resembles it (a period that is not an integer or drifts along the
axis, a size that depends on the other axis, a seat that wears) is fitted by it on part of the
rings and by other parameters on the rest.

The test (a Chow test with rings as units): the effect's columns split in two at the median of a
variable of the rings (the orientation's A, its B, the time of the ring's touches when known), each
half with parameters of its own, the other effects of the chain common; the gain of the split over
the common fit is tested over rings as a claim is (diagnosis.replication), at the claim's level
divided among the variables (Bonferroni). Method: docs/methods/replication.md#form.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.replication import REPLICATION_LEVEL, FormBreak, replication, ring_gains
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.within_noise import ring_sigma
from ph_explorer.effects import Effect
from ph_explorer.models.least_squares import Design


def ring_variables(campaign: Campaign) -> dict[str, NDArray[np.float64]]:
    """Each ring's value of the variables a claim's parameters must not depend on."""
    out = {"A": campaign.orientations[:, 0], "B": campaign.orientations[:, 1]}
    if campaign.times_s is not None:
        out["time"] = campaign.times_s.mean(axis=(1, 2))
    return out


def form_breaks(search: CandidateSearch, effect: Effect, others: Sequence[Effect], seed: int = 0) -> FormBreak | None:
    """The first variable over which the effect's parameters differ (module docstring), with its
    test; None when its form holds over every one."""
    variables = ring_variables(search.campaign)
    level = REPLICATION_LEVEL / len(variables)
    raw = search.bases(effect)
    common = search.design([*others, effect])
    noise = ring_sigma(search.campaign.deviations) ** 2
    for name, values in variables.items():
        at = float(np.median(values))
        upper = (values > at)[:, None, None, None]
        if upper.all() or not upper.any():
            continue
        split = Design(np.concatenate([raw * upper, raw * ~upper], axis=-1), search.smoother)
        after = search.design(others).stacked(split) if others else split
        test = replication(ring_gains(search.residual, common, after, search.targets, noise), ~search.train, True, seed)
        if test.p_value < level and test.p_without_top < level:
            return FormBreak(name, at, round(test.p_value, 5), round(test.p_without_top, 5))
    return None
