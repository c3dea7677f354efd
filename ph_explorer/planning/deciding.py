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

from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.diagnosis.candidates import Candidate, Partner, RivalSetting
from ph_explorer.diagnosis.replication import replication
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects import Catalog, Effect, effect_label
from ph_explorer.kinematics import campaign_touches, touch_kinematics
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.models.hybrid import fitted_basis
from ph_explorer.planning.ring_design import candidate_orientations, distinct_rings


@dataclass
class Question:
    """What a few rings should decide: tell `effect` from `other`, or confirm `effect` (other None)."""

    effect: Effect
    other: Effect | None = None
    shared: float = 0.0  # the share of their columns' variance on the measured rings (partners.confounding)
    separated_by: str = ""  # a measurement other than rings that would separate them (diagnosis.separation)

    @property
    def names(self) -> tuple[str, str]:
        """The two sides in words: their ids, each with its settings when both are one effect (its period)."""
        if self.other is None:
            return self.effect.id, ""
        if self.other.id == self.effect.id:
            return effect_label(self.effect), effect_label(self.other)
        return self.effect.id, self.other.id

    @property
    def label(self) -> str:
        return " vs ".join(self.names) if self.other is not None else self.effect.id

    @property
    def words(self) -> str:
        """The question's sides named at their settings: 'a_axis_axial_motion 20 cycles/rev or a_axis_tilt_motion 21 cycles/rev'."""
        return " or ".join(effect_label(e) for e in (self.effect, self.other) if e is not None)

    def reason(self, gain: float, total: float) -> str:
        if self.other is not None:
            first, second = self.names
            return f"tells {first} from {second}: {gain:.0f} of the set's {total:.0f} noise variances of evidence"
        return f"confirms or refutes {self.effect.id}: {gain:.0f} of the set's {total:.0f} noise variances of evidence"


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


def seen_columns(effect: Effect, campaign: Campaign, pool: NDArray[np.float64], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """The effect's columns as the out-of-sample residual sees them, at the measured rings then the
    pool's, (n_o + n_pool, n_pt, k): after each ring's circle fit, less the data model's prediction
    there (weights: the smoother over both, the pool's rings held out); zeros where it cannot act."""
    own, new = campaign_touches(campaign), touch_kinematics(pool, campaign.geometry, 1)
    k = len(effect.coefficients())
    if effect.unmet_needs(new) or effect.unmet_needs(own):
        return np.zeros((len(weights), campaign.n_points, k))
    columns = np.concatenate([fitted_basis(effect, own)[0].mean(axis=1), fitted_basis(effect, new)[0][:, 0]])
    return np.nan_to_num(columns - np.tensordot(weights, columns, axes=(1, 0)))


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
# its rings' gains scattering about their expectations (decision_power, POWER_DRAWS draws).
DECIDING_POWER = 0.95  # the level expanded uncertainties are stated at (k = 2)
POWER_DRAWS = 100
SEES_NOTHING = 1e-6  # a ring whose evidence is below this share of the largest (or of one noise variance) sees nothing
DECIDING_RINGS = 3
TIE = 1e-6  # relative: evidence closer than this to the best ring's is a tie (rings_for)


class Evidence:
    """What each ring, measured or new, would add to one question, in touch noise variances, as the
    test over rings sees it (module docstring). For a pair, each candidate's prediction in turn is
    the truth and the other, at its settings or one scan step away (neighbour_settings), is refitted
    without the ring on the measured rings and the chosen new ones: what it cannot follow at the
    ring is the ring's evidence, and the truth and refit that leave least count. For a suggested
    candidate, its term at the ring."""

    def __init__(self, question: Question, campaign: Campaign, pool: NDArray[np.float64], weights: NDArray[np.float64]) -> None:
        self.scale = campaign.n_repetitions / max(campaign.noise_sigma_um(), 1e-12) ** 2
        self.n_o = campaign.n_orientations
        self.check = campaign.holdout_mask()
        x = seen_columns(question.effect, campaign, pool, weights)
        cx = np.asarray(question.effect.coefficients(), dtype=float)
        # Per (truth, refit): the truth's signal energy per ring, the refit's Gram blocks and their
        # products with the signal per ring (the measured rings first, then the pool's).
        self.fits: list[tuple[NDArray, NDArray, NDArray]] = []
        if question.other is None:
            self.term = (np.einsum("opi,i->op", x, cx) ** 2).sum(axis=1)  # (n_o + n_pool,), a suggestion's evidence
            return
        y = seen_columns(question.other, campaign, pool, weights)
        cy = np.asarray(question.other.coefficients(), dtype=float)
        for truth, coef, rival in ((x, cx, question.other), (y, cy, question.effect)):
            signal = np.einsum("opi,i->op", truth, coef)
            for settings in rival.neighbour_settings():
                fitted = seen_columns(rival.with_settings(**settings), campaign, pool, weights)
                self.fits.append(
                    (np.einsum("opi,opj->oij", fitted, fitted), np.einsum("opi,op->oi", fitted, signal), (signal**2).sum(axis=1))
                )

    def _left(self, fit: tuple[NDArray, NDArray, NDArray], total_g: NDArray, total_c: NDArray, at: NDArray[np.int64]) -> NDArray:
        """What the refit, on the totals less each ring of `at` (totals: one per ring or shared),
        cannot follow of the truth at that ring, (len(at),)."""
        gram, cross, energy = fit[0][at], fit[1][at], fit[2][at]
        beta = np.einsum("nij,nj->ni", np.linalg.pinv(total_g - gram, rcond=1e-10, hermitian=True), total_c - cross)
        return energy - 2 * np.einsum("ni,ni->n", cross, beta) + np.einsum("ni,nij,nj->n", beta, gram, beta)

    def per_ring(self, rings: list[int], extra: NDArray[np.int64]) -> NDArray[np.float64]:
        """(len(extra), len(rings) + 1): each new ring's evidence when the pool's `rings` and, in
        turn, each of `extra` (last column) are measured."""
        new = [self.n_o + i for i in rings]
        if not self.fits:
            term = self.scale * self.term
            return np.column_stack([np.broadcast_to(term[new], (len(extra), len(rings))), term[self.n_o + extra]])
        out = []
        for fit in self.fits:
            gram, cross = fit[0], fit[1]
            total_g = gram[: self.n_o].sum(axis=0) + gram[new].sum(axis=0) + gram[self.n_o + extra]  # (n_extra, k, k)
            total_c = cross[: self.n_o].sum(axis=0) + cross[new].sum(axis=0) + cross[self.n_o + extra]
            columns = [self._left(fit, total_g, total_c, np.full(len(extra), j)) for j in new]  # the rings chosen (a few)
            columns.append(self._left(fit, total_g, total_c, self.n_o + extra))  # each extra ring itself
            out.append(np.column_stack(columns))
        each = np.stack(out)  # (fits, n_extra, rings + 1)
        least = np.argmin(each.sum(axis=2), axis=0)  # per extra ring, the fit that leaves least
        return self.scale * each[least, np.arange(len(extra))]

    def every_ring(self, rings: list[int]) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Every ring's evidence, the measured rings' then the pool's `rings`, with the pool's
        measured, and which are check rings (the new ones are): the test's units and their groups."""
        at = np.concatenate([np.arange(self.n_o), self.n_o + np.asarray(rings, dtype=int)])
        check = np.concatenate([self.check, np.ones(len(rings), dtype=bool)])
        if not self.fits:
            return self.scale * self.term[at], check
        left = []
        for fit in self.fits:
            total_g, total_c = fit[0][at].sum(axis=0), fit[1][at].sum(axis=0)
            left.append(self._left(fit, total_g, total_c, at))
        each = np.stack(left)
        return self.scale * each[np.argmin(each.sum(axis=1))], check


def decision_power(gains: NDArray[np.float64], check: NDArray[np.bool_], draws: int = POWER_DRAWS) -> float:
    """How often the test over rings (diagnosis.replication: significant, and without its most
    influential ring) passes when each ring's gain scatters about its expectation g with variance
    4 g (its cross term with the touch noise); rings that see nothing (g = 0) are no units."""
    gains = np.maximum(np.asarray(gains, dtype=float), 0.0)
    seen = gains > max(SEES_NOTHING * float(gains.max(initial=0.0)), SEES_NOTHING)
    noise = np.random.default_rng(0).standard_normal((draws, gains.size))
    drawn = np.where(seen, gains + 2.0 * np.sqrt(gains) * noise, 0.0)
    return float(np.mean([replication(d, check, True, seed=k).replicated for k, d in enumerate(drawn)]))


def rings_for(evidence: Evidence, free: NDArray[np.bool_], budget: int) -> tuple[list[int], list[float], float]:
    """The question's rings, best first, until the test over rings would pass with DECIDING_POWER
    or the budget ends: (rings, each one's evidence, the power); no rings when the budget ends first."""
    rings: list[int] = []
    each_ring: list[float] = []
    power = decision_power(*evidence.every_ring([]))
    while len(rings) < budget and free.any():
        candidates = np.flatnonzero(free)
        each = evidence.per_ring(rings, candidates)  # (n_candidates, len(rings) + 1)
        # The ring whose set leaves most without its strongest ring: no single ring decides.
        robust = each.sum(axis=1) - each.max(axis=1)
        score = robust + 1e-9 * each.sum(axis=1)
        # Rings equal to rounding (turns of B an A-axis term does not see) go to the first in the
        # pool's order, so the choice does not hang on the BLAS's last digits.
        pick = int(np.flatnonzero(score >= score.max() - TIE * abs(score.max()))[0])
        rings.append(int(candidates[pick]))
        free = free.copy()
        free[rings[-1]] = False
        each_ring = [float(v) for v in each[pick]]
        if len(rings) >= DECIDING_RINGS:
            power = decision_power(*evidence.every_ring(rings))
            if power >= DECIDING_POWER:
                return rings, each_ring, power
    return [], each_ring, power


def rings_that_decide(campaign: Campaign, result: Diagnosis, catalog: Catalog, budget: int, skip: Collection[str] = ()) -> Decision:
    """Up to `budget` new rings that decide the diagnosis's questions (module docstring), but those
    labelled in `skip` (asked before, their rings measured: an adaptive campaign asks once)."""
    asked = [q for q in questions_of(result, catalog) if q.label not in skip]
    if not asked:
        note = "nothing to decide: every claimed candidate is told from its partners, none is only suggested"
        return Decision([], {}, 0.0, note=note, budget=budget)
    campaign = result.judged(campaign)  # the rings the diagnosis judged
    pool = distinct_rings(candidate_orientations(campaign.geometry, a_step_deg=DECIDE_A_STEP_DEG), campaign.orientations)
    # Within the measured A0 range: beyond it the data model extrapolates, and what a ring would
    # show of a term is the extrapolation's as much as the term's.
    pool = pool[pool[:, 0] <= campaign.orientations[:, 0].max() + 1e-9]
    # The smoother over the measured rings and the pool's, these held out as check rings are.
    train = np.concatenate([~campaign.holdout_mask(), np.zeros(len(pool), dtype=bool)])
    weights = OutOfSampleSmoother(np.concatenate([campaign.orientations, pool]), train).weights
    free = np.ones(len(pool), dtype=bool)
    taken: list[tuple[int, int]] = []
    evidence_of: dict[int, float] = {}  # each proposed ring's evidence within its question's set
    expected: dict[str, dict[str, Any]] = {}
    for q, question in enumerate(asked):
        rings, each_ring, power = rings_for(Evidence(question, campaign, pool, weights), free, budget - len(taken))
        total = sum(each_ring)
        without_top = total - max(each_ring, default=0.0)
        evidence_of.update(zip(rings, each_ring))
        free[rings] = False
        taken += [(q, i) for i in rings]
        expected[question.label] = {
            "words": question.words,
            "decided_by_rings": bool(rings),
            "power": round(power, 2),
            "expected_gain": round(total, 1),
            "without_top_ring": round(without_top, 1),
        }
        if question.other is not None:
            expected[question.label]["shared_now"] = question.shared
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


@dataclass(frozen=True)
class DecisionWords:
    """The decision in words, by part: a head line, one line a ring in measuring order, a line per
    question no ring decides, and the CMM time (None without rings)."""

    head: str
    rings: tuple[str, ...]
    undecided: tuple[str, ...]
    time: str | None

    def lines(self) -> list[str]:
        return [self.head, *self.rings, *self.undecided, *([self.time] if self.time is not None else [])]


def decision_words(decision: Decision, budget: int) -> DecisionWords:
    """The decision in words (DecisionWords); the command line prints its lines, the explorer lays out its parts."""
    head = (
        f"{len(decision.rings)} rings that decide, in this order:" if decision.rings else (decision.note or "no ring decides what is open")
    )
    rings = tuple(f"{r['order']:>3}. {orientation_label(r['A_deg'], r['B_deg']):<12} {r['reason']}" for r in decision.rings)
    undecided = []
    for label, expected in decision.expected.items():
        if not expected["decided_by_rings"]:
            other = f"; {expected['separated_by']} would" if expected.get("separated_by") else ""
            undecided.append(
                f"{expected.get('words', label)}: no {budget} rings of this stylus decide it (the test over rings would pass "
                f"{100 * expected['power']:.0f} % of the time with them, {100 * DECIDING_POWER:.0f} % decides){other}"
            )
    time = None
    if decision.rings:
        time = f"about {decision.minutes:.0f} minutes of CMM time" if decision.minutes is not None else decision.note
    return DecisionWords(head, rings, tuple(undecided), time)
