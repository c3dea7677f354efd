"""Measure until you know: the first rings of a head nothing is known about (designed lattice rings
and check rings off the lattice), the next rings from what its diagnosis leaves open (rings measured
badly again, once; rings that decide its questions; lattice rings where the data part is thinnest
and fresh check rings, unless the model already holds at unseen rings), and a stated stop: the
verdict `none`, `missing` or `uncatalogued` (a claim or a shape replicated; a shape claimed again
after fresh rings), nothing a ring decides, no ring measured badly that was not measured again, and
what the model misses at its check rings within the tolerance (95 % upper bound); or a verdict that
establishes something the same (plans.Answer) as the last plan's read, fresh check rings measured
since, with nothing to decide or measure again; else the budget, or no lattice ring left (a full
lattice whose model fails: once fresh check rings at its cells' centres have not settled it). One
tolerance sets the repetitions too. The closed loop on the twin: planning.closed_loop. Method:
docs/planning.md.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from ph_explorer.campaign import Campaign, orientation_keys, orientation_label, orientation_match
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry, stylus_direction
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.planning.deciding import DECIDE_BUDGET, questions_of, ring_minutes, rings_that_decide
from ph_explorer.planning.plans import DEFAULT_CADENCE, Answer, Cadence, Plan, PlannedRing
from ph_explorer.planning.ring_design import (
    A_STEP_DEG,
    B_STEP_DEG,
    candidate_orientations,
    cell_centres,
    distinct_rings,
    farthest_first,
    measured_side,
    propose_rings,
)
from ph_explorer.planning.ring_evidence import check_residual

START_RINGS = 6  # lattice rings first: as many as the catalog's low orders need to be told apart
A0_RINGS = 2  # the data part's A0 = 0 row: two, so that each is predicted out of sample by the other
START_CHECK_RINGS = 4  # the check rings' group test needs 3 (the worst left out): one more
NEXT_DATA_RINGS = 3  # lattice rings a step adds for the data part
NEXT_CHECK_RINGS = 2  # fresh check rings a step adds
FRESH = "test the model at fresh check rings"  # asked once a full lattice's model still fails
# The verdicts a campaign can stop at: every claim, catalog effect or shape, replicated over rings.
KNOWN_VERDICTS = ("none", "missing", "uncatalogued")
# Verdicts that establish nothing, which more rings are asked to change: nothing found (with a model
# that misses beyond the tolerance: an effect these rings have not shown yet?), and a suggestion to
# confirm. Any other stops once it holds with fresh check rings.
UNSETTLED = ("none", "suggested")
CHECK_A_STEP_DEG, CHECK_B_STEP_DEG = 5.0, 10.0  # the pool of check rings, off the lattice
# The tolerance: what the model may miss at a ring it never saw, um rms. By default the touch noise
# of a PAPER_REPETITIONS-repetition ring mean: the model then predicts an unseen ring as well as the
# paper's campaign measures it. Each ring is measured so that its mean holds no more noise than the
# tolerance (at least MIN_REPETITIONS: two estimate the noise, a third lets the test of the scatter
# between repetitions see drift); the rings then buy what repetitions cannot.
MIN_REPETITIONS = 3
PAPER_REPETITIONS = 10  # the paper's: what the model misses at an unseen ring may be what its ring mean could not see
TP20_SIGMA_UM = 0.175  # the TP20's repeatability per touch, 1 sigma (docs/twin.md)


def base_model(catalog: Catalog = DEFAULT_CATALOG) -> list[Effect]:
    """The effects an adaptive campaign's diagnosis offers as its base model, never claimed: the
    catalog's location errors (ISO 230-7: where each axis line lies), which every five-axis
    calibration identifies. A dense lattice's data part interpolates them; a few rings' cannot, and
    without them the search would spend its steps claiming them; the diagnosis fits those the rings
    can use (diagnosis.choice.usable_base; docs/planning.md#the-base-model)."""
    return [cls() for cls in catalog.candidates().values() if cls.kind == "location"]


def plan_diagnosis(campaign: Campaign, catalog: Catalog = DEFAULT_CATALOG, **options: Any) -> Diagnosis:
    """The diagnosis a plan reads: diagnosis.diagnose with the base model (options: diagnose's others)."""
    from ph_explorer.diagnosis import diagnose

    return diagnose(campaign, catalog=catalog, base=base_model(catalog), **options)


def default_tolerance_um(sigma_um: float) -> float:
    """What the model may miss at an unseen ring by default: the noise of a paper-style ring mean."""
    return sigma_um / math.sqrt(PAPER_REPETITIONS)


def repetitions_for(sigma_um: float, tolerance_um: float | None = None) -> int:
    """Repetitions per ring for a probe of this repeatability: its ring mean's noise within the tolerance."""
    for value, option in ((sigma_um, "--sigma-um"), (tolerance_um, "--tolerance-um")):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"must be a positive number of um, got {value!r}", option=option)
    tolerance = default_tolerance_um(sigma_um) if tolerance_um is None else tolerance_um
    return max(MIN_REPETITIONS, math.ceil((sigma_um / tolerance) ** 2 - 1e-9))


def _angles_deg(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles (deg) between the stylus directions of orientations a (n, 2) and b (m, 2): (n, m)."""
    da, db = stylus_direction(a[:, 0], a[:, 1]), stylus_direction(b[:, 0], b[:, 1])
    return np.degrees(np.arccos(np.clip(da @ db.T, -1.0, 1.0)))


def check_rings(known: NDArray[np.float64], count: int, geometry: Geometry) -> NDArray[np.float64]:
    """`count` reachable rings off the lattice, each as far (in stylus direction) from every ring
    known and chosen before it as the pool allows: the model is tested where it has not been."""
    pool = candidate_orientations(geometry, CHECK_A_STEP_DEG, CHECK_B_STEP_DEG)
    on_lattice = np.isclose(np.mod(pool[:, 0], A_STEP_DEG), 0.0) & np.isclose(np.mod(pool[:, 1], B_STEP_DEG), 0.0)
    pool = measured_side(pool[~on_lattice & (pool[:, 0] > 0)], known)  # on the side of A0 the rings are measured at
    return pool[farthest_first(pool, known, count)]


def first_rings(
    budget_minutes: float | None = None,
    geometry: Geometry = DEFAULT_GEOMETRY,
    sigma_um: float = TP20_SIGMA_UM,
    cadence: Cadence = DEFAULT_CADENCE,
    catalog: Catalog = DEFAULT_CATALOG,
    tolerance_um: float | None = None,
) -> Plan:
    """The first rings of a head one knows nothing about (module docstring); InputError when they
    do not fit the budget."""
    repetitions = repetitions_for(sigma_um, tolerance_um)
    design = propose_rings(START_RINGS, geometry=geometry, catalog=catalog.values()).orientations
    # Two A0 = 0 rings: the data part's A0 row near the head's singular orientation, each predicting
    # the other out of sample (models.trilinear.a0_row_rings; a lone one cannot be cross-validated).
    low = A0_RINGS * (not (design[:, 0] == 0.0).any())
    a0_rings = np.column_stack([np.zeros(low), design[:low, 1]])  # at B0 of the design: on its columns
    checks = check_rings(np.concatenate([design, a0_rings]), START_CHECK_RINGS, geometry)
    minutes = (len(design) + low + len(checks)) * cadence.ring_minutes(repetitions, geometry.points_per_circle)
    if budget_minutes is not None and minutes > budget_minutes:
        raise InputError(
            f"{budget_minutes:g} minutes is less than the first {len(design) + low} rings and {len(checks)} check rings take "
            f"at {repetitions} repetitions ({minutes:.0f} min)",
            option="--budget-minutes",
        )
    rings = [
        PlannedRing(float(a), float(b), "designed: the catalog's effects identifiable, the data part covered", False) for a, b in design
    ]
    rings += [PlannedRing(0.0, float(b), "the A0 = 0 row: every B0 is the same ring there", False) for b in a0_rings[:, 1]]
    rings += [PlannedRing(float(a), float(b), "check ring: tests the model where no ring is near", True) for a, b in checks]
    reason = "the first rings of a head nothing is known about"
    return Plan(tuple(rings), False, reason, minutes, repetitions, budget_minutes=budget_minutes)


def _lattice_kept(counts: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(..., values) rings per value of an angle -> (...): campaign.lattice_axes keeps every value
    held (a value shared by at least half as many rings as the most common one, and by two)."""
    top = counts.max(axis=-1, keepdims=True)
    return ((counts == 0) | (counts >= np.maximum(2.0, 0.5 * top)) | (top < 2)).all(axis=-1)


def data_rings(campaign: Campaign, count: int, taken: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Lattice rings for the data part, each the node farthest (in stylus direction) from every ring
    measured or planned: (orientations, their distances, deg).

    The trilinear model's lattice must keep every training ring (campaign.lattice_axes keeps an A or
    B value shared by at least half as many rings as the most common one, and by two when one is):
    up to `count` rings are taken one at a time where that holds, or two at once (a new A row); when
    no ring or pair keeps it (every B value held once: a second ring at one would drop the others),
    every B value takes one more ring at once (a count of 0 takes none)."""
    train = campaign.orientations[~campaign.holdout_mask()]
    train = train[train[:, 0] != 0]  # an A0 = 0 ring is its whole row whatever the lattice holds (models.trilinear.a0_row_rings)
    known = np.concatenate([campaign.orientations, taken])
    nodes = distinct_rings(measured_side(candidate_orientations(campaign.geometry), campaign.orientations), known)
    nodes = nodes[nodes[:, 0] != 0]  # A0 = 0 rings come in the first plan (first_rings), as a pair
    keys = [np.stack([orientation_keys(o[:, 0]), orientation_keys(np.mod(o[:, 1] + 180.0, 360.0))], axis=1) for o in (train, nodes)]
    counts, onehot = [], []
    for angle in (0, 1):  # each node as one-hot over the values of its angle, and the training rings' counts
        values, index = np.unique(np.concatenate([keys[0][:, angle], keys[1][:, angle]]), return_inverse=True)
        counts.append(np.bincount(index[: len(train)], minlength=values.size).astype(float))
        onehot.append(np.eye(values.size)[index[len(train) :]])
    nearest = _angles_deg(nodes, known).min(axis=1) if len(known) else np.full(len(nodes), 180.0)
    free = np.ones(len(nodes), dtype=bool)
    chosen: list[int] = []

    def take(k: int) -> None:
        nonlocal nearest
        chosen.append(k)
        free[k] = False
        counts[0], counts[1] = counts[0] + onehot[0][k], counts[1] + onehot[1][k]
        nearest = np.minimum(nearest, _angles_deg(nodes, nodes[k : k + 1])[:, 0])

    while len(chosen) < count and free.any():
        single = free & _lattice_kept(counts[0] + onehot[0]) & _lattice_kept(counts[1] + onehot[1])
        pair = free[:, None] & free[None, :] & ~np.eye(len(nodes), dtype=bool) & (len(chosen) + 2 <= count)
        pair &= _lattice_kept(counts[0] + onehot[0][:, None] + onehot[0][None]) & _lattice_kept(
            counts[1] + onehot[1][:, None] + onehot[1][None]
        )
        best_single = nearest[single].max() if single.any() else -1.0
        pair_score = np.where(pair, np.minimum(nearest[:, None], nearest[None, :]), -1.0)
        if best_single < 0 and pair_score.max() < 0:
            break
        if best_single >= pair_score.max():
            take(int(np.flatnonzero(single)[np.argmax(nearest[single])]))
        else:
            i, j = np.unravel_index(int(np.argmax(pair_score)), pair_score.shape)
            take(int(i))
            take(int(j))
    if not chosen and count > 0 and free.any():
        # Every B value one ring more, each where the data part is farthest, in the A rows held and
        # spread over them evenly (so that every row keeps its share), farthest B values first.
        held_b, rows = np.flatnonzero(counts[1] > 0), counts[0] > 0
        cap = math.ceil(held_b.size / max(int(rows.sum()), 1))
        added = np.zeros_like(counts[0])
        order = held_b[np.argsort([-nearest[free & (onehot[1][:, b] > 0)].max(initial=-1.0) for b in held_b])]
        for b in order:
            at = free & (onehot[1][:, b] > 0) & (onehot[0] @ (rows & (added < cap)) > 0)
            if at.any():
                k = int(np.flatnonzero(at)[np.argmax(nearest[at])])
                added += onehot[0][k]
                take(k)
        if len(chosen) < held_b.size or not (_lattice_kept(counts[0]) and _lattice_kept(counts[1])):
            chosen = []
    distance = _angles_deg(nodes[chosen], known).min(axis=1) if chosen and len(known) else np.zeros(len(chosen))
    return nodes[chosen], distance


def unseen_error_um(campaign: Campaign, result: Diagnosis) -> tuple[float, float, NDArray[np.float64]]:
    """What the diagnosed model misses at rings it never saw, in um rms: at each check ring, the
    mean square of its repetition mean's residual less what touch noise puts there (sigma^2 / R for
    the ring, and for the rings the data part predicts it from, times their weights' squares);
    the mean over check rings, its one-sided 95 % upper bound (a t quantile over the rings), and
    the A0 of the check rings it read (deg).
    Each check ring is predicted as the error history measures it: left out of the physical fit,
    which reads every ring's out-of-sample residual (predict_held_out), on the campaign the
    diagnosis fitted (result.judged)."""
    fitted, held_out, residual = check_residual(campaign, result)
    train = ~fitted.holdout_mask()
    # The touch noise in a residual: the ring's own mean's, and that of the training rings' means the
    # data part predicts it from (their weights' squares).
    neighbours = (OutOfSampleSmoother(fitted.orientations, train).weights[held_out] ** 2).sum(axis=1)
    excess = (residual**2).mean(axis=1) - (1.0 + neighbours) * fitted.noise_sigma_um() ** 2 / fitted.n_repetitions
    mean = float(excess.mean())
    error = float(excess.std(ddof=1) / math.sqrt(excess.size)) if excess.size > 1 else math.inf
    upper = mean + float(stats.t.ppf(0.95, max(excess.size - 1, 1))) * error
    return math.sqrt(max(mean, 0.0)), math.sqrt(max(upper, 0.0)), fitted.orientations[held_out, 0]


def campaign_minutes(campaign: Campaign, cadence: Cadence = DEFAULT_CADENCE) -> float:
    """Minutes at the machine the campaign took: its first touch to its last (with touch times),
    else its rings at the cadence."""
    if campaign.times_s is not None:
        return float(campaign.times_s.max() - campaign.times_s.min()) / 60.0
    return campaign.n_orientations * cadence.ring_minutes(campaign.n_repetitions, campaign.n_points)


def next_rings(
    campaign: Campaign,
    result: Diagnosis,
    budget_minutes: float | None = None,
    catalog: Catalog = DEFAULT_CATALOG,
    cadence: Cadence = DEFAULT_CADENCE,
    asked: Collection[str] = (),
    tolerance_um: float | None = None,
    previous: Answer | None = None,
) -> Plan:
    """The next rings of a measured campaign, or the reason to stop (module docstring). asked: the questions
    earlier plans asked (the last plan's Plan.questions): their rings are measured, and a question they did not
    decide is one no ring of this stylus decides. tolerance_um: what the model may miss at unseen rings.
    previous: the answer the last plan read (Plan.answer): the same again with fresh check rings stops."""
    spent = campaign_minutes(campaign, cadence)
    per_ring = ring_minutes(campaign) or cadence.ring_minutes(campaign.n_repetitions, campaign.n_points)
    tolerance = tolerance_um if tolerance_um is not None else default_tolerance_um(campaign.noise_sigma_um())
    unseen, unseen_upper, tested = unseen_error_um(campaign, result)  # tested: where it holds
    decision = rings_that_decide(campaign, result, catalog, DECIDE_BUDGET, skip=asked)
    done: dict[str, Any] = {"repetitions": campaign.n_repetitions, "measured_rings": campaign.n_orientations, "spent_minutes": spent}
    # A ring named as measured badly is measured again once, in its role (it replaces the old one);
    # named again after that, its fault repeats there (or the head errs at that ring alone): the
    # diagnosis keeps it out and the stop says so, rather than measuring it over and over.
    held_out = campaign.holdout_mask()
    seen = f"its {tested.size} check rings, A0 {tested.min():g}-{tested.max():g} deg" if tested.size else "no check ring"
    again: list[PlannedRing] = []
    repeated, remeasure = [], []  # the rings measured again already; the questions this plan asks
    for s in result.suspect_rings:
        label = orientation_label(s.a_deg, s.b_deg)
        if f"measure {label} again" in asked:
            repeated.append(f"{label} measured again and still named: " + ("left out" if s.left_out else "kept, a check ring"))
            continue
        remeasure.append(f"measure {label} again")
        at = orientation_match(campaign.orientations, np.array([[s.a_deg, s.b_deg]])).any(axis=1)
        reason = f"measured badly ({s.reason}, {s.ratio:.1f}x its floor): measure it again"
        again.append(PlannedRing(s.a_deg, s.b_deg, reason, bool(held_out[at].any())))
    # A shape is a flexible function chosen on these rings' check rings: it stops a campaign once it
    # is claimed again after fresh rings, measured after it was first claimed, have joined them.
    shapes = [f"confirm the shape {shape.id} on fresh rings" for shape in result.claimed_shapes]
    unconfirmed = [question for question in shapes if question not in asked]
    asked_now = [*asked, *decision.questions, *remeasure, *shapes]
    done |= {"budget_minutes": budget_minutes, "verdict": result.verdict, "questions": tuple(dict.fromkeys(asked_now))}
    answer = Answer.of(campaign, result)
    done |= {"unseen_um": (round(unseen, 4), round(unseen_upper, 4), round(tolerance, 4)), "answer": answer}
    known_well = unseen_upper <= tolerance
    knows = result.verdict in KNOWN_VERDICTS and not unconfirmed and known_well  # the stop by knowing
    # The same answer again with fresh check rings: the rings measured since did not change it, and
    # more of them would refine the model, not what the campaign says (docs/planning.md#the-stop).
    fresh_checks = answer.check_rings - previous.check_rings if previous is not None else 0
    held = previous is not None and answer.same_as(previous) and fresh_checks > 0 and result.verdict not in UNSETTLED
    if (held or knows) and not decision.rings and not again:
        left = questions_of(result, catalog)
        settled = "nothing is left open" if not left else f"{len(left)} question(s) left open that no ring of this stylus decides"
        kept_out = f"; {', '.join(repeated)} (its fault repeats there)" if repeated else ""
        missed = f"at unseen rings ({seen}) the model misses {unseen:.3f} um (95 % up to {unseen_upper:.3f} um)"
        if knows:
            claims = "every claim replicated over rings" if result.found or result.claimed_shapes else "no effect beyond noise"
            claims += ", a shape no catalog holds among them" if result.claimed_shapes else ""
            reason = f"you know: {claims}; {settled}{kept_out}; {missed}, within the tolerance {tolerance:.3f} um"
        else:
            beyond = "within" if known_well else "more than"
            reason = (
                f"the answer held with {fresh_checks} fresh check ring{'s' * (fresh_checks > 1)}: {answer.words}, as before them"
                f"{'' if answer.words == previous.words else f' within what these rings cannot tell ({previous.words})'}; "
                f"{settled}{kept_out}; {missed}, {beyond} the tolerance {tolerance:.3f} um: more rings would refine the model, "
                "not the answer"
            )
        return Plan((), True, reason, 0.0, **done)
    suspect = np.array([[r.a_deg, r.b_deg] for r in again]).reshape(-1, 2)
    rings = again + [
        PlannedRing(r["A_deg"], r["B_deg"], r["reason"], True)
        for r in decision.rings
        if not orientation_match(np.array([[r["A_deg"], r["B_deg"]]]), suspect).any()
    ]
    planned = np.array([[r.a_deg, r.b_deg] for r in rings]).reshape(-1, 2)
    # A model that holds at unseen rings needs only the rings that decide (check rings) and those measured again.
    deciding = bool(rings) and knows
    data, distance = data_rings(campaign, 0 if deciding else NEXT_DATA_RINGS, planned)
    full = not len(data) and not rings  # a full lattice whose model fails: fresh check rings at its cells' centres, once
    if not full:
        fresh = check_rings(np.concatenate([campaign.orientations, planned, data]), 0 if deciding else NEXT_CHECK_RINGS, campaign.geometry)
    else:
        fresh = cell_centres(campaign, START_CHECK_RINGS) if FRESH not in asked else np.zeros((0, 2))
    if full and not len(fresh):
        after = "; fresh check rings measured after the lattice was full did not settle it" if FRESH in asked else ""
        reason = (
            f"no lattice ring is left to add (a ring a B value, as the trilinear's lattice keeps them) and no ring decides "
            f"what is open{after}: the verdict stays {result.verdict}; at unseen rings ({seen}) the model misses {unseen:.3f} um "
            f"(95 % up to {unseen_upper:.3f} um, the tolerance {tolerance:.3f} um)"
        )
        return Plan((), True, reason, 0.0, **done)
    if full:
        done["questions"] = (*done["questions"], FRESH)
    batch = len(data) > NEXT_DATA_RINGS
    gap = "every B value one ring more (the lattice keeps them so)" if batch else "the data part's widest gap"
    fitted = [
        PlannedRing(float(a), float(b), f"{gap}: {near:.0f} deg from the nearest ring", False) for (a, b), near in zip(data, distance)
    ]
    checks = [PlannedRing(float(a), float(b), "a fresh check ring: the model where it has not been tested", True) for a, b in fresh]
    if budget_minutes is not None:
        # Within the budget: the rings measured again and those that decide first, the lattice rings
        # whole or none (a part of them could drop rings from the lattice), then the check rings.
        affordable = int(max(budget_minutes - spent, 0.0) // per_ring)
        if affordable == 0:
            return Plan((), True, f"the budget: {spent:.0f} of {budget_minutes:g} minutes spent, the verdict {result.verdict}", 0.0, **done)
        rings = rings[:affordable]
        fitted = fitted if len(rings) + len(fitted) <= affordable else []
        checks = checks[: max(affordable - len(rings) - len(fitted), 0)]
    rings += fitted + checks
    if result.verdict not in KNOWN_VERDICTS:
        why = f"the verdict is {result.verdict}"
    elif decision.rings or again:
        why = "questions left open" if decision.rings else "a ring measured badly"
        why += "; the model holds at unseen rings: no lattice or fresh check ring" if deciding else ""
    elif unconfirmed:
        why = "a shape no catalog holds, claimed on these rings: fresh rings confirm it or not"
    else:
        why = f"at unseen rings the model misses up to {unseen_upper:.3f} um (95 %), more than the tolerance {tolerance:.3f} um"
    why += "; no lattice ring is left to add" if full else ""
    return Plan(tuple(rings), False, why, len(rings) * per_ring, **done)
