"""Rings that decide: where to measure next when the diagnosis cannot tell a claim from a confounded
partner (diagnosis.telling_apart), or cannot confirm a suggested candidate.

A ring's evidence is what the test over rings would add up there, in touch noise variances: the
candidate's term (confirm), or what each candidate cannot follow of the other's prediction when
refitted without that ring (separate); both after the ring's circle fit and less what the data
model predicts there. Each question takes rings until the diagnosis's own test over rings, run on
those expectations with their scatter, would pass with DECIDING_POWER (at least DECIDING_RINGS
rings). Method: docs/methods/deciding.md.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import Candidate, Partner, RivalSetting
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects import Catalog, Effect
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.planning.ring_design import candidate_orientations, distinct_rings, on_measured_side
from ph_explorer.planning.ring_evidence import Evidence, Question, decision_power, residual_spectrum, scatter_ratio


@dataclass
class Decision:
    """The rings that decide, in measuring order, and what they are expected to do."""

    rings: list[dict[str, Any]]  # {"A_deg", "B_deg", "order", "question", "reason", "expected_gain"}
    # per question: decided_by_rings, power, expected_gain and without_top_ring (noise variances), shared_now (a pair)
    expected: dict[str, dict[str, Any]]
    minutes: float | None  # estimated CMM time from the campaign's own touch and move times; None without times
    questions: list[str] = field(default_factory=list)
    note: str = ""
    budget: int = 0  # the most rings it could propose

    def as_dict(self) -> dict[str, Any]:
        return {
            "rings": self.rings,
            "expected": self.expected,
            "minutes": None if self.minutes is None else round(self.minutes, 1),
            "questions": self.questions,
            "note": self.note,
        }


def questions_of(result: Diagnosis, catalog: Catalog) -> list[Question]:
    """Every question the diagnosis leaves: each claimed or suggested candidate against each
    confounded partner its rings do not tell it from, each claim against its rival setting (the
    closest one its rings do not tell from its own), and each suggested candidate to confirm."""
    ranked: dict[str, Candidate] = {}
    for ranking in result.rankings or [result.candidates]:
        for c in ranking:
            ranked.setdefault(c.effect, c)
    out: list[Question] = []
    asked: set[frozenset[str]] = set()  # a pair once, whichever of the two asks
    for candidate in [*result.found, *result.open_suggestions]:
        effect = fitted_effect(candidate, catalog)
        for partner in candidate.untold:
            other = ranked.get(partner.effect)
            pair = frozenset((candidate.effect, partner.effect))
            if other is not None and other.params and pair not in asked:
                asked.add(pair)
                measurement = partner.separated_by.measurement if partner.separated_by is not None else ""
                out.append(Question(effect, partner_effect(partner, other, catalog), float(partner.shared), measurement))
        rival = candidate.rival_setting
        if rival is not None and not candidate.suggested:  # a suggestion is confirmed first, its setting after
            out.append(Question(effect, fitted_effect(candidate, catalog, rival), float(rival.shared)))
        if candidate.suggested:
            out.append(Question(effect))
    return out


def fitted_effect(candidate: Candidate, catalog: Catalog, at: RivalSetting | None = None) -> Effect:
    """The candidate's effect at its fitted parameters and settings, or at those of `at` (its rival_setting)."""
    fit = at if at is not None else candidate
    return effect_at(catalog, candidate.effect, fit.params, fit.settings)


def partner_effect(partner: Partner, ranked: Candidate, catalog: Catalog) -> Effect:
    """An untold partner at the settings that stand in for the claim, fitted there beside the chain
    (telling_apart.tell_apart); a record without that fit: at its own ranking's fit."""
    if not partner.params:
        return fitted_effect(ranked, catalog)
    return effect_at(catalog, partner.effect, partner.params, partner.settings[0] if partner.settings else {})


def effect_at(catalog: Catalog, effect_id: str, params: Mapping[str, float], settings: Mapping[str, Any]) -> Effect:
    """The catalog's effect at these fitted parameters and settings (names it does not know are left out)."""
    cls = catalog[effect_id]
    known = {p.name for p in cls.parameters}
    return cls(**{k: v for k, v in {**params, **settings}.items() if k in known})


def ring_minutes(campaign: Campaign) -> float | None:
    """Minutes one more ring takes on this CMM: the campaign's median ring (all its repetitions)
    plus its median move to the next ring, from the touch times (None without them)."""
    if campaign.times_s is None or campaign.n_orientations < 2:
        return None
    first, last = campaign.times_s.min(axis=(1, 2)), campaign.times_s.max(axis=(1, 2))
    order = np.argsort(first)
    moves = first[order][1:] - last[order][:-1]
    return float(np.median(last - first) + np.median(np.maximum(moves, 0.0))) / 60.0


DECIDE_BUDGET = 6  # rings proposed when no budget is given (the command and the explorer)
DECIDE_A_STEP_DEG = 5.0  # the pool of new rings: finer in A than a lattice
# The rings of a question decide when the test the diagnosis runs over rings (replication: sign
# flips, significant at 5 % and without the ring that adds most) would pass with this probability,
# its rings' gains scattering about their expectations (ring_evidence.decision_power).
DECIDING_POWER = 0.95  # the level expanded uncertainties are stated at (k = 2)
DECIDING_RINGS = 3
BEYOND_BUDGET = 3  # an undecided question is said how many rings would decide it, up to this many budgets
TIE = 1e-6  # relative: evidence closer than this to the best ring's is a tie (rings_for)


def next_ring(evidence: Evidence, rings: list[int], free: NDArray[np.bool_]) -> tuple[int, list[float]]:
    """The pool ring that joins `rings` next (one of `free`): the one whose set leaves most without
    its strongest ring, so that no single ring decides; with each ring's evidence in that set."""
    candidates = np.flatnonzero(free)
    each = evidence.per_ring(rings, candidates)  # (n_candidates, len(rings) + 1)
    robust = each.sum(axis=1) - each.max(axis=1)
    score = robust + 1e-9 * each.sum(axis=1)
    # Rings equal to rounding (turns of B an A-axis term does not see) go to the first in the
    # pool's order, so the choice does not hang on the BLAS's last digits.
    pick = int(np.flatnonzero(score >= score.max() - TIE * abs(score.max()))[0])
    return int(candidates[pick]), [float(v) for v in each[pick]]


def rings_for(evidence: Evidence, free: NDArray[np.bool_], budget: int) -> tuple[list[int], list[float], float]:
    """The question's rings, best first (next_ring), until the test over rings would pass with
    DECIDING_POWER or the budget ends: (rings, each one's evidence, the power); no rings when the
    budget ends first."""
    rings: list[int] = []
    each_ring: list[float] = []
    power = decision_power(*evidence.every_ring([]))
    free = free.copy()
    while len(rings) < budget and free.any():
        ring, each_ring = next_ring(evidence, rings, free)
        rings.append(ring)
        free[ring] = False
        if len(rings) >= DECIDING_RINGS:
            power = decision_power(*evidence.every_ring(rings))
            if power >= DECIDING_POWER:
                return rings, each_ring, power
    return [], each_ring, power


def rings_needed(evidence: Evidence, free: NDArray[np.bool_], most: int) -> int | None:
    """How many rings, in rings_for's order, would decide the question: the fewest whose test would
    pass with DECIDING_POWER, found by bisection (the power grows as rings join), None when not even
    `most` would. A number to weigh against a budget, not a proposal."""
    rings: list[int] = []
    free = free.copy()
    while len(rings) < most and free.any():
        rings.append(next_ring(evidence, rings, free)[0])
        free[rings[-1]] = False
    if len(rings) < DECIDING_RINGS or decision_power(*evidence.every_ring(rings)) < DECIDING_POWER:
        return None
    low, high = DECIDING_RINGS, len(rings)
    while low < high:
        middle = (low + high) // 2
        low, high = (low, middle) if decision_power(*evidence.every_ring(rings[:middle])) >= DECIDING_POWER else (middle + 1, high)
    return low


def rings_that_decide(campaign: Campaign, result: Diagnosis, catalog: Catalog, budget: int, skip: Collection[str] = ()) -> Decision:
    """Up to `budget` new rings that decide the diagnosis's questions (module docstring), but those
    labelled in `skip` (asked before, their rings measured: an adaptive campaign asks once)."""
    asked = [q for q in questions_of(result, catalog) if q.label not in skip]
    if not asked:
        note = "nothing to decide: every claimed candidate is told from its partners, none is only suggested"
        return Decision([], {}, 0.0, note=note, budget=budget)
    if not result.tested:  # evidence is counted in touch-noise variances, and one repetition shows no noise
        note = "one repetition per ring: no repetition spread to weigh a ring's evidence against; measure each ring again first"
        return Decision([], {}, None, [q.label for q in asked], note=note, budget=budget)
    spectrum = residual_spectrum(campaign, result, catalog)
    campaign = result.judged(campaign)  # the rings the diagnosis judged
    candidates = on_measured_side(candidate_orientations(campaign.geometry, a_step_deg=DECIDE_A_STEP_DEG), campaign.orientations)
    pool = distinct_rings(candidates, campaign.orientations)
    if not len(pool):
        note = "no ring is left to measure within the campaign's A0 range: every candidate there is measured"
        return Decision([], {}, None, [q.label for q in asked], note=note, budget=budget)
    # The smoother over the measured rings and the pool's, these held out as check rings are.
    train = np.concatenate([~campaign.holdout_mask(), np.zeros(len(pool), dtype=bool)])
    weights = OutOfSampleSmoother(np.concatenate([campaign.orientations, pool]), train).weights
    free = np.ones(len(pool), dtype=bool)
    taken: list[tuple[int, int]] = []
    evidence_of: dict[int, float] = {}  # each proposed ring's evidence within its question's set
    expected: dict[str, dict[str, Any]] = {}
    for q, question in enumerate(asked):
        evidence = Evidence(question, campaign, pool, weights, spectrum)
        rings, each_ring, power = rings_for(evidence, free, budget - len(taken))
        total = sum(each_ring)
        without_top = total - max(each_ring, default=0.0)
        evidence_of.update(zip(rings, each_ring))
        free[rings] = False
        taken += [(q, i) for i in rings]
        expected[question.label] = {
            "words": question.words,
            "pair": question.other is not None,
            "decided_by_rings": bool(rings),
            "power": round(power, 2),
            "expected_gain": round(total, 1),
            "without_top_ring": round(without_top, 1),
            "scatter": round(scatter_ratio(*evidence.every_ring(rings)[::2]), 1),
        }
        if question.other is not None:
            expected[question.label]["shared_now"] = question.shared
        if not rings:  # how many would, beyond the budget
            expected[question.label]["rings_needed"] = rings_needed(evidence, free, BEYOND_BUDGET * max(budget, DECIDING_RINGS))
        if not rings and question.separated_by:
            expected[question.label]["separated_by"] = question.separated_by
    entries = []
    for order, (q, i) in enumerate(taken, start=1):
        entries.append(
            {
                "A_deg": float(pool[i, 0]),
                "B_deg": float(pool[i, 1]),
                "order": order,
                "question": asked[q].label,
                "reason": asked[q].reason(evidence_of[i], expected[asked[q].label]["expected_gain"]),
                "expected_gain": round(evidence_of[i], 1),
            }
        )
    per_ring = ring_minutes(campaign)
    return Decision(
        entries,
        expected,
        None if per_ring is None else per_ring * len(entries),
        [q.label for q in asked],
        "" if per_ring is not None else "no touch times in the campaign: the CMM time cannot be estimated",
        budget,
    )
