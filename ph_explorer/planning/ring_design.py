"""Which rings to measure: an optimal design of a campaign's orientations.

The design chooses N orientations (A0, B0) from reachable lattice nodes, greedily, for two purposes
at once: the catalog's effects identifiable (D-optimality on their orthonormalised basis columns
after each ring's circle fit, with a weak RIDGE_PRIOR) and the data part covered (space filling
in stylus direction). A measured campaign's rings are the prior; without one the design keeps to
rings a lattice interpolator can use. The rings come in measuring order, most informative first.

Method: docs/methods/ring_design.md.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign, lattice_axes, orientation_keys, orientation_match
from ph_explorer.effects import DEFAULT_CATALOG, Effect, effect_label
from ph_explorer.errors import InputError
from ph_explorer.geometry import A_LIMIT_DEG, DEFAULT_GEOMETRY, Geometry, stylus_direction, wrap_deg
from ph_explorer.kinematics import touch_kinematics
from ph_explorer.models.hybrid import fitted_basis

# Scanned settings of each effect entered in the design (e.g. cycles per revolution 1-6): the low
# orders carry most of a head's axis errors, and separating them is what a small design must do.
DESIGN_SCAN_VALUES = 6
# The prior information, as a fraction of the identity (the information of every candidate).
RIDGE_PRIOR = 1e-4
# Nats of space filling per nat of log-determinant: the two criteria in the same currency.
SPACE_FILLING_WEIGHT = 1.0
# Candidate lattice: the paper's steps.
A_STEP_DEG = 15.0
B_STEP_DEG = 20.0
# Two rings whose stylus directions are closer than this are the same circle in space.
SAME_RING_DEG = 1e-3
# Singular values below this fraction of the largest are directions no candidate ring can show.
RANK_RTOL = 1e-8


@dataclass
class RingDesign:
    """The proposed rings in measuring order, and what the design criterion says of them."""

    orientations: NDArray[np.float64]  # (N, 2) A0, B0 in degrees, in measuring order
    log_det: float  # the D-criterion of the design (prior included; measured rings too with data)
    gain: NDArray[np.float64]  # (N,) what each ring added to it, in order
    nearest_deg: NDArray[np.float64]  # (N,) angle to the nearest stylus direction before it
    columns: int  # orthonormal directions of the effects' columns the candidates can show
    candidates: int
    effects: list[str]  # labels of the effect instances designed for
    not_designed_for: list[str] = field(default_factory=list)  # effects the touches cannot test, with why
    measured: int = 0  # rings of the campaign the design starts from

    def as_dict(self) -> dict[str, Any]:
        return {
            "orientations": [[float(a), float(b)] for a, b in self.orientations],
            "order": list(range(1, len(self.orientations) + 1)),
            "log_det": round(self.log_det, 4),
            "gain": [round(float(g), 4) for g in self.gain],
            "nearest_deg": [round(float(d), 2) for d in self.nearest_deg],
            "columns": self.columns,
            "candidates": self.candidates,
            "measured": self.measured,
            "effects": self.effects,
            "not_designed_for": self.not_designed_for,
            "criterion": "D-optimal on the effects' bases after the circle fit (orthonormalised over the candidates) "
            f"+ {SPACE_FILLING_WEIGHT:g} x log(angle to the nearest stylus direction)",
        }


def candidate_orientations(
    geometry: Geometry = DEFAULT_GEOMETRY, a_step_deg: float = A_STEP_DEG, b_step_deg: float = B_STEP_DEG
) -> NDArray[np.float64]:
    """Lattice nodes A0 = 0, a_step, ... and B0 in [-180, 180) whose every touch the head can reach.

    A0 = 0 enters once (B does not change where the stylus points there). Reach: the A joint at
    every touch of the ring within its limit (the ring's joint sweep adds to A0).
    """
    a_values = np.arange(0.0, A_LIMIT_DEG + 1e-9, a_step_deg)
    b_values = np.arange(-180.0 + b_step_deg, 180.0 + 1e-9, b_step_deg)
    grid = np.array([(a, b) for a in a_values for b in (b_values if a > 0 else [0.0])])
    reachable = touch_kinematics(grid, geometry).reachable[:, 0, :].all(axis=1)
    return grid[reachable]


def measured_side(pool: NDArray[np.float64], measured: NDArray[np.float64]) -> NDArray[np.float64]:
    """The candidates on the side of A0 the campaign measures (the PH20 turns A both ways): the ring
    at (A0, B0) is the ring at (-A0, B0 + 180), the same stylus direction. A campaign measured at
    negative A0 only is offered them there, one at both signs on both (the positive first), and
    one at A0 >= 0 (or none yet) the pool as it is, in the same order."""
    below, above = bool((measured[:, 0] < 0).any()), bool((measured[:, 0] > 0).any())
    if not below:
        return pool
    mirrored = np.column_stack([-pool[:, 0], wrap_deg(pool[:, 1] + 180.0)])[pool[:, 0] > 0]
    return np.concatenate([pool if above else pool[pool[:, 0] <= 0], mirrored])


def on_measured_side(pool: NDArray[np.float64], measured: NDArray[np.float64]) -> NDArray[np.float64]:
    """measured_side, kept from A0 = 0 to the farthest measured A0 on each side: beyond, the
    campaign's data model extrapolates, and what a ring would show of a term is the extrapolation's
    as much as the term's."""
    both = measured_side(pool, measured)
    low, high = min(0.0, float(measured[:, 0].min())), max(0.0, float(measured[:, 0].max()))
    return both[(both[:, 0] >= low - 1e-9) & (both[:, 0] <= high + 1e-9)]


def cell_centres(campaign: Campaign, count: int) -> NDArray[np.float64]:
    """`count` reachable check rings at the centres of the cells of a campaign's lattice (half-way
    between its A rows and between its B columns, where its rings interpolate from farthest), in
    distinct A intervals while there are any, each the centre farthest (in stylus direction) from
    every ring measured or chosen. On a row, an error of one axis interpolates along the row."""
    a_axis, b_axis = lattice_axes(campaign.orientations[~campaign.holdout_mask()])
    a_mid, b_mid = (a_axis[:-1] + a_axis[1:]) / 2, (b_axis[:-1] + b_axis[1:]) / 2
    cells = np.stack(np.meshgrid(a_mid, b_mid, indexing="ij"), axis=-1).reshape(-1, 2)
    cells = cells[touch_kinematics(cells, campaign.geometry).reachable[:, 0, :].all(axis=1)] if len(cells) else cells
    return cells[farthest_first(cells, campaign.orientations, count, groups=cells[:, 0])]


def farthest_first(
    pool: NDArray[np.float64], known: NDArray[np.float64], count: int, groups: NDArray[np.float64] | None = None
) -> list[int]:
    """Indices of `count` pool orientations, each the farthest (in stylus direction) from every known
    ring and every one chosen before it; groups: one of each group while any is left unchosen."""
    directions = stylus_direction(pool[:, 0], pool[:, 1])
    nearest = _angle_deg(directions, stylus_direction(known[:, 0], known[:, 1])).min(axis=1, initial=180.0)
    chosen: list[int] = []
    while len(chosen) < min(count, len(pool)):
        free = ~np.isin(np.arange(len(pool)), chosen)
        spread = free if groups is None else free & ~np.isin(groups, groups[chosen])
        pick = int(np.argmax(np.where(spread if spread.any() else free, nearest, -1.0)))
        chosen.append(pick)
        nearest = np.minimum(nearest, _angle_deg(directions, directions[pick : pick + 1])[:, 0])
    return chosen


def distinct_rings(pool: NDArray[np.float64], known: NDArray[np.float64]) -> NDArray[np.float64]:
    """The candidates less those whose ring lies where another candidate's (or a measured one's)
    does: the same stylus direction is the same circle in space, whatever B0 (every A0 = 0 ring
    is the same ring, its B joint sweeping the full turn). Measuring it again adds repetitions,
    not information on the effects or the data part's coverage. The first candidate of each is kept."""
    directions = stylus_direction(pool[:, 0], pool[:, 1])
    taken = stylus_direction(known[:, 0], known[:, 1]) if known.size else np.zeros((0, 3))
    # "The same ring" is an equivalence (one direction), so an earlier candidate of a ring, kept or
    # not, means this one is not the first: no need to know which earlier ones were kept.
    earlier_same = np.tril(_angle_deg(directions, directions) < SAME_RING_DEG, k=-1).any(axis=1)
    measured_same = (_angle_deg(directions, taken) < SAME_RING_DEG).any(axis=1)
    return pool[~(earlier_same | measured_same)]


def effect_instances(catalog: Iterable[type[Effect]]) -> list[Effect]:
    """Every candidate effect of the catalog at its first DESIGN_SCAN_VALUES scanned settings."""
    instances = []
    for cls in catalog:
        if not cls.candidate:
            continue
        for settings in cls.scan_grid()[:DESIGN_SCAN_VALUES]:
            instances.append(cls(**settings))
    return instances


def ring_information(
    orientations: ArrayLike, effects: Sequence[Effect], geometry: Geometry = DEFAULT_GEOMETRY
) -> tuple[NDArray[np.float64], list[str], list[str]]:
    """Each ring's stacked effect columns after its circle fit, (n_o, n_pt, c), with the labels of
    the effects entered and of those the touches cannot test (with why).

    Effects that change between repetitions enter through their first repetition's columns.
    """
    touches = touch_kinematics(np.asarray(orientations, dtype=float), geometry)
    blocks, used, skipped = [], [], []
    for effect in effects:
        unmet = effect.unmet_needs(touches)
        if unmet:
            reason = f"{effect.id}: {'; '.join(unmet)}"
            if reason not in skipped:  # once per effect, not per scanned setting
                skipped.append(reason)
            continue
        columns, _ = fitted_basis(effect, touches)
        if columns.shape[-1]:
            blocks.append(np.asarray(columns[:, 0]))
            used.append(effect_label(effect))
    if not blocks:
        raise InputError("no effect of the catalog can be seen by head touches: nothing to design for")
    return np.concatenate(blocks, axis=-1), used, skipped


def orthonormal_rows(columns: NDArray[np.float64]) -> NDArray[np.float64]:
    """The columns (n_o, n_pt, c) in an orthonormal basis of their span over all rings, (n_o, n_pt, k).

    The sum of every ring's information is then the identity: the criterion is the same in any
    units, and directions no ring can show (absorbed by the circle fit) are gone.
    """
    n_o, n_pt, c = columns.shape
    flat = columns.reshape(-1, c)
    scale = np.sqrt((flat**2).sum(axis=0))
    flat = flat / np.where(scale > 0, scale, 1.0)
    # The singular values of the columns themselves, not the eigenvalues of their Gram matrix: the
    # Gram squares the condition, and at RANK_RTOL**2 = 1e-16 of its largest eigenvalue rounding
    # decided the rank (157 or 158 columns with 1 or 2 BLAS threads, and so another design).
    left, singular, _ = np.linalg.svd(flat, full_matrices=False)
    keep = singular > RANK_RTOL * max(singular.max(initial=0.0), 1e-300)
    return left[:, keep].reshape(n_o, n_pt, int(keep.sum()))


def _angle_deg(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles (deg) between unit vectors a (n, 3) and b (m, 3), (n, m)."""
    return np.degrees(np.arccos(np.clip(a @ b.T, -1.0, 1.0)))


def _counts_allowed(keys: NDArray[np.float64], chosen: list[int], budget: int, at_most_once: bool) -> NDArray[np.bool_]:
    """Which candidates keep a lattice value's count feasible for `lattice_axes` (docs/methods/ring_design.md).

    at_most_once: every value at most once (all counts 1: all kept). Otherwise every value used
    lowest..2 lowest times: the lowest count is at least half the most common one.
    """
    values, inverse = np.unique(keys, return_inverse=True)
    counts = np.bincount(inverse[chosen], minlength=values.size) if chosen else np.zeros(values.size, dtype=int)
    if at_most_once:
        return counts[inverse] == 0
    lowest = max(2, math.ceil(budget / (2 * values.size)))
    left = budget - len(chosen)
    # Values started but below the lowest count must still be completed with the picks left.
    owed = np.maximum(lowest - counts, 0) * (counts > 0)
    # A value with too few candidates to reach the lowest count (A0 = 0: one ring) is never opened.
    available = np.bincount(inverse, minlength=values.size)
    allowed = (counts[inverse] < 2 * lowest) & (available[inverse] >= lowest)
    if owed.sum() >= left:
        allowed &= owed[inverse] > 0
    elif owed.sum() + lowest > left:
        allowed &= counts[inverse] > 0  # no room to open a new value and complete it
    return allowed


def propose_rings(
    budget: int,
    candidates: ArrayLike | None = None,
    geometry: Geometry = DEFAULT_GEOMETRY,
    catalog: Iterable[type[Effect]] = DEFAULT_CATALOG.values(),
    measured: Campaign | None = None,
    lattice: bool | None = None,
) -> RingDesign:
    """The next `budget` rings to measure, in measuring order (docs/methods/ring_design.md).

    candidates: orientations to choose from (default: candidate_orientations, on the side of A0 a
    measured campaign turns to (measured_side), minus the rings it holds). measured: a campaign whose rings are
    the prior information and the data already covered. lattice: keep the design usable by a lattice
    interpolator (default: without a campaign).
    """
    if budget < 1:
        raise InputError("the budget must be at least one ring", option="--budget")
    geometry = measured.geometry if measured is not None else geometry
    known = np.zeros((0, 2)) if measured is None else measured.orientations
    pool = (
        measured_side(candidate_orientations(geometry), known) if candidates is None else np.asarray(candidates, dtype=float).reshape(-1, 2)
    )
    if known.size:
        pool = pool[~orientation_match(pool, known).any(axis=1)]
    pool = distinct_rings(pool, known)
    if len(pool) < budget:
        raise InputError(
            f"only {len(pool)} candidate orientations are left to choose from, fewer than the budget {budget}", option="--budget"
        )
    lattice = measured is None if lattice is None else lattice
    stacked = np.concatenate([pool, known]) if known.size else pool
    columns, used, skipped = ring_information(stacked, effect_instances(catalog), geometry)
    basis = orthonormal_rows(columns)
    k = basis.shape[-1]
    ring_info = np.einsum("opc,opd->ocd", basis, basis)  # (n, k, k): each ring's share of X'X
    information = RIDGE_PRIOR * np.eye(k) + ring_info[len(pool) :].sum(axis=0)
    directions = stylus_direction(stacked[:, 0], stacked[:, 1])
    pool_dir, known_dir = directions[: len(pool)], directions[len(pool) :]
    nearest = _angle_deg(pool_dir, known_dir).min(axis=1) if len(known_dir) else np.full(len(pool), 180.0)
    a_keys, b_keys = orientation_keys(pool[:, 0]), orientation_keys(np.mod(pool[:, 1] + 180.0, 360.0))
    b_once = budget <= np.unique(b_keys).size

    chosen: list[int] = []
    gains, distances = [], []
    log_det = float(np.linalg.slogdet(information)[1])
    for _ in range(budget):
        inverse = np.linalg.inv(information)
        # Matrix determinant lemma: log det(M + X'X) - log det M = log det(I + X M^-1 X').
        candidate_basis = basis[: len(pool)]
        projected = (candidate_basis @ inverse) @ np.swapaxes(candidate_basis, 1, 2)
        gain = np.linalg.slogdet(np.eye(basis.shape[1])[None] + projected)[1]
        score = gain + SPACE_FILLING_WEIGHT * np.log(np.maximum(nearest, 1e-3))
        allowed = np.ones(len(pool), dtype=bool)
        allowed[chosen] = False
        if lattice:
            allowed &= _counts_allowed(a_keys, chosen, budget, at_most_once=False)
            allowed &= _counts_allowed(b_keys, chosen, budget, at_most_once=b_once)
        if not allowed.any():
            raise InputError(f"no lattice design of {budget} rings among {len(pool)} candidates", option="--budget")
        pick = int(np.flatnonzero(allowed)[np.argmax(score[allowed])])
        chosen.append(pick)
        gains.append(float(gain[pick]))
        distances.append(float(nearest[pick]))
        information = information + ring_info[pick]
        log_det += float(gain[pick])
        nearest = np.minimum(nearest, _angle_deg(pool_dir, pool_dir[pick : pick + 1])[:, 0])
    return RingDesign(
        orientations=pool[chosen],
        log_det=log_det,
        gain=np.array(gains),
        nearest_deg=np.array(distances),
        columns=k,
        candidates=len(pool),
        effects=used,
        not_designed_for=skipped,
        measured=len(known),
    )


def design_log_det(
    orientations: ArrayLike,
    candidates: ArrayLike,
    geometry: Geometry = DEFAULT_GEOMETRY,
    catalog: Iterable[type[Effect]] = DEFAULT_CATALOG.values(),
) -> float:
    """The D-criterion of any set of rings among the candidates, as propose_rings computes it
    (to compare a design with another of the same size, e.g. a random one)."""
    pool = np.asarray(candidates, dtype=float).reshape(-1, 2)
    rings = orientation_match(pool, orientations).any(axis=1)
    columns, _, _ = ring_information(pool, effect_instances(catalog), geometry)
    basis = orthonormal_rows(columns)
    information = RIDGE_PRIOR * np.eye(basis.shape[-1]) + np.einsum("opc,opd->cd", basis[rings], basis[rings])
    return float(np.linalg.slogdet(information)[1])
