"""The partners a candidate cannot be told from on this campaign: the other candidates whose columns
share most of its own (squared canonical correlation over every touch, through the smoother), each
at the settings that share the most, and what measurement would separate the closest. A partner is
tried at its own best setting and, when it scans what the candidate scans on the same axis, one scan
step around the candidate's: an n/rev error seen through a lever that turns once a revolution reads
as n - 1 and n + 1 (an A-axis axial motion at 20/rev is, at the ball, a tilt motion at 19 or 21/rev).
Method: docs/methods/deciding.md.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ph_explorer.diagnosis.candidates import Candidate, Partner, Separation
from ph_explorer.diagnosis.fitted_bases import settings_key
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.separation import CONFOUNDED, Separations, span_share, touch_span
from ph_explorer.effects import Effect

SEPARATIONS = 3  # the closest partners of each candidate told what would separate them
# A partner's settings whose share is within this of its largest stand in for the candidate as well.
SHARE_TIE = 0.01


def partner_settings(effect: Effect, other: Effect) -> list[Effect]:
    """`other` at its own settings and, when it scans what `effect` scans on the same axis, at those
    one scan step around `effect`'s (Effect.neighbour_settings): where the two can share all."""
    tried = {settings_key(other): other}
    if other.axis is not None and other.axis == effect.axis and other.scan and set(other.scan) == set(effect.scan):
        around = other.with_settings(**effect.settings())
        tried |= {settings_key(o): o for o in (other.with_settings(**s) for s in around.neighbour_settings())}
    return list(tried.values())


def standing_in_order(tried: Sequence[tuple[float, Effect]]) -> list[tuple[float, Effect]]:
    """The (share, partner) tried that share within SHARE_TIE of the best, the closest first;
    shares equal but for rounding (a span shared whole: 1.0 each) keep the order tried, the same on
    every machine whatever its arithmetic's last digits."""
    best = max(share for share, _ in tried)
    return sorted((t for t in tried if t[0] >= best - SHARE_TIE), key=lambda t: -round(t[0], 9))


def confounding(search: CandidateSearch, candidates: Sequence[Candidate], by_id: dict[str, Effect]) -> list[Candidate]:
    """The candidates, each beyond noise or significant with the others it cannot be told from on
    this campaign (their columns share more than CONFOUNDED at some settings of the partner,
    partner_settings), the closest first, and what would separate it from its closest SEPARATIONS."""
    # Each effect once in the ranking: its columns at the settings it was scored at.
    at = {c.effect: by_id[c.effect].with_settings(**c.settings) for c in candidates if c.evidence.get("x")}
    spans: dict[tuple, tuple[NDArray[np.float64], NDArray[np.float64] | None]] = {}  # each design's, made once
    separations: Separations | None = None  # made when a first pair asks, for every pair after it

    def span(effect: Effect) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        key = settings_key(effect)
        if key not in spans:
            spans[key] = touch_span(search.design([effect]))
        return spans[key]

    out = []
    for candidate in candidates:
        if not (candidate.beyond_noise or candidate.significant) or candidate.effect not in at:
            out.append(candidate)
            continue
        own = at[candidate.effect]
        partners, standing_in = [], {}
        for other_id, other in at.items():
            if other_id == candidate.effect:
                continue
            tried = [(span_share(span(own), span(o)), o) for o in partner_settings(own, other)]
            best = max(share for share, _ in tried)
            if best > CONFOUNDED:
                closest = standing_in_order(tried)
                partners.append(Partner(other_id, round(best, 3), settings=tuple(o.settings() for _, o in closest)))
                standing_in[other_id] = closest[0][1]
        partners.sort(key=lambda p: -p.shared)  # the closest first
        # ... and what would tell it from its closest partners, each at the settings that stand in for it.
        closest_partners = partners[:SEPARATIONS]
        if closest_partners and separations is None:
            separations = Separations(search.campaign)
        pairs = [(own, standing_in[p.effect]) for p in closest_partners]
        separated = [Separation(**s) for s in separations(pairs)] if pairs and separations is not None else []
        partners[: len(closest_partners)] = [replace(p, separated_by=s) for p, s in zip(closest_partners, separated)]
        out.append(replace(candidate, confounded_with=tuple(partners)))
    return out
