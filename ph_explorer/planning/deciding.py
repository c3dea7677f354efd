"""Rings that decide: where to measure next when the diagnosis cannot tell candidates apart, or
cannot confirm one.

Two kinds of question come from a diagnosis: **separate** a found or suggested candidate from a
partner it is confounded with (they explain the measured rings alike), and **confirm or refute**
a suggested candidate (its gain rests on a few rings). Each candidate is taken at its fitted
parameters; its term at a ring that is not yet measured, after the ring's circle fit and less
what the data model (the trilinear interpolator over the measured training rings) would predict
there from the measured rings, is what that ring would show of it. The ring's score is the rms
over its points of the two candidates' difference (separate) or of the candidate's term (confirm),
over the noise floor of a new ring's mean curve predicted out of sample. Rings are taken best
first, in turn for each question. Method: docs/methods/deciding.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.diagnosis.results import Candidate, Diagnosis
from ph_explorer.effects import Catalog, Effect
from ph_explorer.kinematics import Touches, campaign_touches, touch_kinematics
from ph_explorer.models.crossval import unit_campaign
from ph_explorer.models.hybrid import fitted_basis
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.planning.ring_design import candidate_orientations, distinct_rings


@dataclass
class Question:
    """What a few rings should decide: separate `effect` from `other`, or confirm `effect` (other None)."""

    effect: Effect
    other: Effect | None = None
    separated_by: str = ""  # what the diagnosis found would separate the pair, when not rings (diagnosis.separation)

    @property
    def label(self) -> str:
        return f"{self.effect.id} vs {self.other.id}" if self.other is not None else self.effect.id

    def reason(self, ratio: float) -> str:
        if self.other is not None:
            return f"separates {self.effect.id} from {self.other.id}: predicted difference {ratio:.1f}x floor"
        return f"confirms or refutes {self.effect.id}: predicted term {ratio:.1f}x floor"


@dataclass
class Decision:
    """The rings that decide, in measuring order, and what they are expected to do."""

    rings: list[dict[str, Any]]  # {"A_deg", "B_deg", "order", "question", "reason", "over_floor"}
    expected: dict[str, dict[str, float]]  # per question: shared fraction now and after (separate), or the best ring's ratio
    minutes: float | None  # estimated CMM time from the campaign's own touch and move times; None without times
    questions: list[str] = field(default_factory=list)
    note: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {
            "rings": self.rings,
            "expected": self.expected,
            "minutes": None if self.minutes is None else round(self.minutes, 1),
            "questions": self.questions,
            "note": self.note,
        }


def questions_of(result: Diagnosis, catalog: Catalog) -> list[Question]:
    """Every question the diagnosis leaves: each found or suggested candidate against each partner
    it is confounded with, and each suggested candidate to confirm."""
    ranked: dict[str, Candidate] = {}
    for ranking in [result.candidates, *result.rankings]:
        for c in ranking:
            ranked.setdefault(c.effect, c)
    out: list[Question] = []
    for candidate in [*result.found, *result.suggested]:
        effect = fitted_effect(candidate, catalog)
        for partner in candidate.confounded_with:
            other = ranked.get(partner["effect"])
            if other is not None and other.params:
                measurement = (partner.get("separated_by") or {}).get("measurement", "")
                out.append(Question(effect, fitted_effect(other, catalog), measurement))
        if candidate.suggested:
            out.append(Question(effect))
    return out


def fitted_effect(candidate: Candidate, catalog: Catalog) -> Effect:
    """The candidate's effect at its fitted parameters (and settings)."""
    cls = catalog[candidate.effect]
    known = {p.name for p in cls.parameters}
    return cls(**{k: v for k, v in {**candidate.params, **candidate.settings}.items() if k in known})


def seen_at(effect: Effect, campaign: Campaign, rings: NDArray[np.float64], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """What each new ring would show of the effect's term: at the ring, after its circle fit, less
    the data model's prediction there from the measured rings (weights: (n_new, n_o)), (n_new, n_pt)."""
    new = touch_kinematics(rings, campaign.geometry, 1)
    own = campaign_touches(campaign)
    if effect.unmet_needs(new) or effect.unmet_needs(own):
        return np.zeros((len(rings), campaign.n_points))
    coef = effect.coefficients()
    at_new = fitted_basis(effect, new)[0][:, 0] @ coef
    at_measured = (fitted_basis(effect, own)[0] @ coef).mean(axis=1)
    return at_new - weights @ at_measured


def ring_minutes(campaign: Campaign) -> float | None:
    """Minutes one more ring takes on this CMM: the campaign's median ring (all its repetitions)
    plus its median move to the next ring, from the touch times (None without them)."""
    if campaign.times_s is None or campaign.n_orientations < 2:
        return None
    first, last = campaign.times_s.min(axis=(1, 2)), campaign.times_s.max(axis=(1, 2))
    order = np.argsort(first)
    moves = first[order][1:] - last[order][:-1]
    return float(np.median(last - first) + np.median(np.maximum(moves, 0.0))) / 60.0


DECIDE_A_STEP_DEG = 5.0  # the pool of new rings: finer in A than a lattice (near-vertical rings separate B's location errors)
# A ring separates a pair only when it lowers their shared fraction by this much (a parameter-free
# criterion: two fits that span the same columns predict the same everywhere); it confirms or
# refutes a suggested candidate when its term there is beyond the floor of the ring's mean curve.
LOWERS_SHARED = 0.02
BEYOND_FLOOR = 1.0


def ring_grams(effect: Effect, other: Effect, touches: Touches, weight: float = 1.0) -> tuple[NDArray, NDArray, NDArray]:
    """Per ring, the Gram blocks (X'X, Y'Y, X'Y) of two effects' columns after each ring's circle
    fit, over its first repetition's touches times `weight` (its repetitions), (n_o, k, k) each."""
    x, y = fitted_basis(effect, touches)[0][:, 0], fitted_basis(other, touches)[0][:, 0]  # (n_o, n_pt, k)
    x, y = np.nan_to_num(x), np.nan_to_num(y)
    return (
        weight * np.einsum("opi,opj->oij", x, x),
        weight * np.einsum("opi,opj->oij", y, y),
        weight * np.einsum("opi,opj->oij", x, y),
    )


def shared_from_grams(gx: NDArray, gy: NDArray, gxy: NDArray) -> NDArray[np.float64]:
    """The largest squared canonical correlation from Gram blocks, stacked over the leading axes."""
    product = np.linalg.pinv(gx, rcond=1e-10, hermitian=True) @ gxy @ np.linalg.pinv(gy, rcond=1e-10, hermitian=True)
    values = np.linalg.eigvals(product @ np.swapaxes(gxy, -1, -2))
    return np.clip(values.real.max(axis=-1), 0.0, 1.0)


def rings_that_decide(campaign: Campaign, result: Diagnosis, catalog: Catalog, budget: int) -> Decision:
    """Up to `budget` new rings that decide the diagnosis's questions (module docstring)."""
    asked = questions_of(result, catalog)
    if not asked:
        return Decision([], {}, 0.0, note="nothing to decide: no found or suggested candidate is confounded or unconfirmed")
    pool = distinct_rings(candidate_orientations(campaign.geometry, a_step_deg=DECIDE_A_STEP_DEG), campaign.orientations)
    # Within the measured A0 range: beyond it the data model extrapolates, and what a ring would
    # show of a term is the extrapolation's as much as the term's.
    pool = pool[pool[:, 0] <= campaign.orientations[:, 0].max() + 1e-9]
    train = ~campaign.holdout_mask()
    weights = TrilinearModel().fit(unit_campaign(campaign.orientations), train).interpolate(pool)  # (n_pool, n_o)
    sigma = campaign.noise_sigma_um()
    floor = sigma / math.sqrt(campaign.n_repetitions) * np.sqrt(1.0 + (weights**2).sum(axis=1))  # (n_pool,)
    own, new = campaign_touches(campaign), touch_kinematics(pool, campaign.geometry, 1)
    ratio, grams, measured = [], [], []
    for question in asked:
        shown = seen_at(question.effect, campaign, pool, weights)
        if question.other is not None:
            shown = shown - seen_at(question.other, campaign, pool, weights)
            # A new ring is measured as the others: its repetitions weigh in.
            grams.append(ring_grams(question.effect, question.other, new, campaign.n_repetitions))
            measured.append(tuple(g.sum(axis=0) for g in ring_grams(question.effect, question.other, own, campaign.n_repetitions)))
        else:
            grams.append(None)
            measured.append(None)
        ratio.append(np.sqrt((shown**2).mean(axis=1)) / floor)
    # The closest pairs first, then the candidates to confirm; in turn, each takes the ring that
    # lowers its shared fraction most (separate) or shows its term most (confirm).
    shared_now = [float(shared_from_grams(*m)) if m is not None else -1.0 for m in measured]
    turn = sorted(range(len(asked)), key=lambda q: -shared_now[q])
    taken: list[tuple[int, int, float]] = []  # (question, ring, shared after it)
    mine: dict[int, list[int]] = {q: [] for q in turn}
    current = {q: shared_now[q] for q in turn}
    open_questions = list(turn)
    while len(taken) < budget and open_questions:
        for q in list(open_questions):
            free = np.setdiff1d(np.arange(len(pool)), [i for _, i, _ in taken])
            if len(taken) >= budget or not free.size:
                break
            if grams[q] is not None:
                # Each free ring added to the measured rings and this question's rings so far.
                base = [m + g[mine[q]].sum(axis=0) for m, g in zip(measured[q], grams[q])]
                after = shared_from_grams(*(b[None] + g[free] for b, g in zip(base, grams[q])))
                pick = int(np.argmin(after - 1e-6 * ratio[q][free]))  # ties: the larger difference
                best, shared = int(free[pick]), float(after[pick])
                decides = current[q] - shared >= LOWERS_SHARED
            else:
                best, shared = int(free[np.argmax(ratio[q][free])]), float("nan")
                decides = ratio[q][best] >= BEYOND_FLOOR
            if not decides:
                open_questions.remove(q)  # no ring left decides it: said below, not padded with rings
                continue
            taken.append((q, best, shared))
            mine[q].append(best)
            current[q] = shared
    taken.sort(key=lambda item: -ratio[item[0]][item[1]])  # the most decisive difference first
    rings = []
    for order, (q, i, shared) in enumerate(taken, start=1):
        entry = {
            "A_deg": float(pool[i, 0]),
            "B_deg": float(pool[i, 1]),
            "order": order,
            "question": asked[q].label,
            "reason": asked[q].reason(float(ratio[q][i])),
            "over_floor": round(float(ratio[q][i]), 2),
        }
        if np.isfinite(shared):
            entry["shared_after"] = round(shared, 3)
        rings.append(entry)
    expected: dict[str, dict[str, float]] = {}
    for q, question in enumerate(asked):
        if grams[q] is not None:
            total = [m + g[mine[q]].sum(axis=0) for m, g in zip(measured[q], grams[q])]
            expected[question.label] = {"shared_now": round(shared_now[q], 3), "shared_after": round(float(shared_from_grams(*total)), 3)}
        else:
            expected[question.label] = {"best_over_floor": round(float(ratio[q].max()), 2)}
    for q in range(len(asked)):
        if not mine[q]:
            expected[asked[q].label]["decided_by_rings"] = False
            if asked[q].separated_by:
                expected[asked[q].label]["separated_by"] = asked[q].separated_by
    per_ring = ring_minutes(campaign)
    return Decision(
        rings,
        expected,
        None if per_ring is None else per_ring * len(rings),
        [q.label for q in asked],
        "" if per_ring is not None else "no touch times in the campaign: the CMM time cannot be estimated",
    )


def rings_text(decision: Decision) -> list[str]:
    """The decision in lines, one ring a line."""
    lines = [f"{r['order']:>3}. {orientation_label(r['A_deg'], r['B_deg']):<12} {r['reason']}" for r in decision.rings]
    return lines
