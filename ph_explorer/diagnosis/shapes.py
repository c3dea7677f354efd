"""A shape for what no catalog holds: the remainder as error functions of the head's own variables.

When the catalog's claims leave the model failing beyond noise, each group of error functions
(effects/error_functions.py: ISO 230-7 component groups of each axis's joint angle, the probe's
lobes in time) is fitted on the out-of-sample residual beside the chain (a ridge chosen by leaving
rings out), each ring's gain measured with that ring left out. The group that gains most is claimed
when it is significant as the best of the groups (`family_test`), still without its most
influential ring, and material (MATERIAL_REDUCTION, or rings brought within noise); groups the
rings cannot tell from it are named beside it. When nothing is claimed, the groups a ring's
neighbours in its A row carry get a second look with A rows left out (view_of), p doubled.
Method: docs/methods/shapes.md.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.blas import in_parts
from ph_explorer.diagnosis.candidates import DIGITS
from ph_explorer.diagnosis.replication import REPLICATION_LEVEL, Replication, family_test, replication, ring_residual_squares
from ph_explorer.diagnosis.search import (
    JACKKNIFE_INFLATION,
    MATERIAL_REDUCTION,
    RINGS_BROUGHT_WITHIN,
    SHARE_BROUGHT_WITHIN,
    CandidateSearch,
)
from ph_explorer.diagnosis.within_noise import NoiseTest, ring_sigma, within_noise
from ph_explorer.effects import Effect
from ph_explorer.effects.error_functions import SHAPE_GROUPS, ErrorFunction, error_function, value_name
from ph_explorer.effects.shapes_file import shape_class
from ph_explorer.kinematics import Touches
from ph_explorer.models import least_squares
from ph_explorer.models.crossval import LeaveOut
from ph_explorer.models.least_squares import Design, RingDeletion
from ph_explorer.uncertainty.jackknife import COVERAGE_FACTOR, jackknife_parameters

# Knot spacing of a joint angle's error functions (deg): a ring samples its joints every 0.2-1 deg
# (A sweeps +-6.5 deg over 64 points; B a full turn at A0 = 0, 51 deg at A0 = 15), so the knots,
# not the touches, bound what a shape resolves: periods down to two knot steps (4 deg of B: 90
# cycles/rev) where the rings' sweeps leave no wider gap.
KNOT_STEP_DEG = {"a_joint_deg": 1.0, "b_joint_deg": 2.0}
FULL_TURN_DEG = 300.0  # a joint sampled over more than this: periodic knots over the whole turn
TIME_KNOTS = 13  # time: the campaign's span in 12 steps
MAX_SHAPES = 2
SAMPLED_LEVER = 0.05  # a lever below this share of its largest samples nothing (B's angular at A0 = 0)


@dataclass(frozen=True)
class Shape:
    """A shape found (or tried) for what no catalog holds: one group's error functions, tabulated
    at its knots with their expanded uncertainty (k = 2), and the test it passed or failed."""

    group: str  # error_functions.SHAPE_GROUPS key, e.g. "b_angular"
    variable: str  # "b_joint_deg", "time_s", ...
    x: tuple[float, ...]
    value: tuple[tuple[float, ...], ...]  # per component, in its unit
    U: tuple[tuple[float, ...], ...]
    periodic: bool
    replication: Replication
    family_p: float  # the family-wise p-value of the best group's gain over rings (family_test)
    check_reduction: float  # the fall of the check rings' rms error (vs the mean) with it
    rings_brought_within: int  # rings that exceed their noise before it and not with it
    claimed: bool
    untold: tuple[str, ...] = ()  # groups whose gains these rings cannot tell from its own
    aliasing_deg: float | None = None  # shortest period it resolves (angles), deg
    period_cycles: float | None = None  # the curve's dominant period, cycles/rev (None: no period dominates)
    widest_at: float | None = None  # where its band is widest, in the variable's unit
    leave_out: LeaveOut = "ring"  # what each training ring was predicted without when it was judged
    # A second look's shape not claimed: the first look's best group of another variable, which
    # gains significantly more at the check rings, and their fall with it (find_shapes).
    rival: tuple[str, float] | None = None
    unsampled_deg: float | None = None  # the widest gap between rings' sweeps that no ring samples, deg

    @property
    def id(self) -> str:
        return f"shape_{self.group}"

    @property
    def words(self) -> str:
        return SHAPE_GROUPS[self.group].words

    @property
    def components(self) -> tuple[tuple[str, str], ...]:
        return SHAPE_GROUPS[self.group].components

    @property
    def plausible(self) -> bool:
        return plausible_curve(self.group, self.value)

    @property
    def replicated(self) -> bool:
        """Its gain over rings significant as the best of the groups (family_p), and still without its top ring."""
        return self.family_p < REPLICATION_LEVEL and self.replication.p_without_top < REPLICATION_LEVEL

    def effect(self) -> ErrorFunction:
        """The shape as an effect at its found values, its class made as a shapes file's (shape_class):
        added here or from an export, the same fit (in the metric of its curve's steps)."""
        return shape_class(self.table(), lambda message, column=None: ValueError(f"its own table ({column}): {message}"))()

    def table(self) -> dict[str, Any]:
        """The shape as a table of the shapes file (effects.shapes_file.shapes_file_text)."""
        values = {value_name(s, j): v for (s, _), row in zip(self.components, self.value) for j, v in enumerate(row)}
        at = error_function(self.group, self.x, self.periodic)(**values)
        return at.table(self.claimed, np.array(self.U)) | {"variable": self.variable}

    def to_json(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "group": self.group,
            "words": self.words,
            "variable": self.variable,
            "components": [{"symbol": s, "unit": u} for s, u in self.components],
            "x": [round(v, 4) for v in self.x],
            "value": [[round(v, DIGITS) for v in row] for row in self.value],
            "U": [[round(v, DIGITS) for v in row] for row in self.U],
            "periodic": self.periodic,
            "replicated": self.replicated,
            "claimed": self.claimed,
            "replication": self.replication.as_dict(),
            "family_p": round(self.family_p, 5),
            "check_reduction": round(self.check_reduction, 4),
            "rings_brought_within": self.rings_brought_within,
            "untold": list(self.untold),
            "aliasing_deg": self.aliasing_deg,
            "period_cycles_per_rev": self.period_cycles,
            "widest_at": self.widest_at,
            "leave_out": self.leave_out,
            "rival": None if self.rival is None else {"group": self.rival[0], "check_reduction": round(self.rival[1], 4)},
            "unsampled_deg": None if self.unsampled_deg is None else round(self.unsampled_deg, 4),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Shape:
        return cls(
            data["group"],
            data["variable"],
            tuple(float(v) for v in data["x"]),
            tuple(tuple(float(v) for v in row) for row in data["value"]),
            tuple(tuple(float(v) for v in row) for row in data["U"]),
            bool(data["periodic"]),
            Replication.from_json(data["replication"]),
            float(data["family_p"]),
            float(data["check_reduction"]),
            int(data["rings_brought_within"]),
            bool(data["claimed"]),
            tuple(data.get("untold", ())),
            data.get("aliasing_deg"),
            data.get("period_cycles_per_rev"),
            data.get("widest_at"),
            data.get("leave_out", "ring"),
            None if data.get("rival") is None else (str(data["rival"]["group"]), float(data["rival"]["check_reduction"])),
            data.get("unsampled_deg"),
        )


def knots(group: str, touches: Touches, train: NDArray[np.bool_]) -> tuple[tuple[float, ...], bool, float | None, float | None]:
    """(knots, periodic, aliasing limit in deg or None, widest unsampled gap in deg or None) of a
    group's functions on these touches.

    A joint angle: knots every KNOT_STEP_DEG over the angles its rings sample with a lever (the
    whole turn, periodic, when that is more than FULL_TURN_DEG). The aliasing limit is twice the
    larger of the knot step and the widest spacing of the touches where some ring sweeps; between
    rings' sweeps (A rows apart) lie gaps no ring samples, where the curve is the penalty's
    interpolation, not a period's alias. Time: TIME_KNOTS over the span of the training rings
    (`train`), which the hybrid is fitted on; later rings (check rings are often measured last)
    see the function's last value."""
    spec = SHAPE_GROUPS[group]
    variable = spec.variable_of(touches)
    x = np.broadcast_to(variable.values(touches), touches.shape)[:, 0]  # (n_o, n_pt): the joints repeat
    if not variable.angle:
        span = np.broadcast_to(variable.values(touches), touches.shape)[train]
        return tuple(np.linspace(float(span.min()), float(span.max()), TIME_KNOTS)), False, None, None
    lever = np.abs(spec.lever(touches)).max(axis=-1)[:, 0]  # (n_o, n_pt)
    seen = lever > SAMPLED_LEVER * lever.max()
    sampled = np.sort(x[seen])
    step = KNOT_STEP_DEG[variable.name]
    if np.ptp(sampled) > FULL_TURN_DEG:  # sampled around the turn: its widest spacing bounds the periods
        count = int(round(360.0 / step))
        grid = tuple(-180.0 + np.arange(count) * 360.0 / count)
        gaps = np.diff(np.concatenate([sampled, sampled[:1] + 360.0]))
        return grid, True, float(2.0 * max(step, gaps.max())), None
    low, high = float(sampled[0]), float(sampled[-1])
    count = max(int(np.ceil((high - low) / step)) + 1, 2)
    gaps, middle = np.diff(sampled), 0.5 * (sampled[1:] + sampled[:-1])
    # A gap lies within a sweep when some ring samples both sides of it.
    first, last = np.where(seen, x, np.inf).min(axis=1), np.where(seen, x, -np.inf).max(axis=1)
    swept = ((first[:, None] <= middle) & (middle <= last[:, None])).any(axis=0)
    unsampled = float(gaps[~swept].max()) if (~swept).any() else None
    return tuple(np.linspace(low, high, count)), False, float(2.0 * max(step, gaps[swept].max(initial=0.0))), unsampled


@dataclass
class GroupFit:
    """One group's fit beside the chain: its effect class, design, coefficients, each ring's left-out fit."""

    effect: ErrorFunction
    design: Design
    coefficients: NDArray[np.float64]  # (c,): the group's values at its knots
    without: NDArray[np.float64]  # (n_o, c_all): every column's coefficient without each ring
    joint: Design
    gain: NDArray[np.float64]  # (n_o,) in noise variances
    aliasing: float | None
    unsampled: float | None  # the widest gap between rings' sweeps, deg
    squares: NDArray[np.float64]  # (n_o,): each ring's left-out sum of squares with it (the next group's "before")


def plausible_curve(group: str, value: Any) -> bool:
    """Every value within its group's plausible size (error_functions.ShapeGroup.plausible): an
    implausible fit is no explanation, however well it predicts the rings it was fitted on."""
    return bool(np.abs(np.asarray(value, dtype=float)).max(initial=0.0) <= SHAPE_GROUPS[group].plausible[1])


def view_of(search: CandidateSearch, group: str) -> CandidateSearch:
    """The search a group is judged in: its own, or its in_rows() view when its own smoother predicts
    the group's columns exactly at more than least_squares.UNSEEN_SHARE of the training rings (an
    error of the A joint on a lattice, which each ring's B neighbours in its row carry)."""
    if group not in search.group_views:
        unseen = False
        if search.smoother.leave_out == "ring":  # a row view has no further look to choose
            grid, periodic, *_ = knots(group, search.touches, search.train)
            unseen = Design(search.bases(error_function(group, grid, periodic)()), search.smoother).unseen_at_most(search.train)
        search.group_views[group] = search.in_rows() if unseen else search
    return search.group_views[group]


def fit_group(
    search: CandidateSearch, fixed: Design | None, before: NDArray[np.float64], group: str, noise: NDArray[np.float64]
) -> GroupFit:
    """One group's error functions fitted beside `fixed` (the chain's design, or None) on the
    out-of-sample residual, the ridge chosen by leaving rings out; each ring's gain over `before`
    (its left-out sum of squares without the group) in its noise variances `noise`."""
    grid, periodic, aliasing, unsampled = knots(group, search.touches, search.train)
    effect = error_function(group, grid, periodic)()
    design = Design(search.bases(effect), search.smoother)
    joint = design if fixed is None else fixed.stacked(design)
    target = search.targets.first_column()
    if joint.within is None:
        deletion = RingDeletion(joint, target)
        coefficients, without, squares = deletion.at(deletion.best_ridge())
        coefficients, squares = coefficients[:, 0], squares[:, 0]
    else:  # columns that change between repetitions (time, or a chain's drift): each ring decomposed
        ridge = least_squares.choose_ridge(joint, target)
        coefficients = least_squares.fit(joint, target, ridge)[0][:, 0]
        without = least_squares.jackknife(joint, target, np.arange(joint.mean.shape[0]), ridge)
        mean, within = joint.apply_each(without)
        squares = ((search.residual - mean[:, None, :] - (0.0 if within is None else within)) ** 2).sum(axis=(1, 2))
    gain = (before - squares) / np.maximum(noise, 1e-300)
    return GroupFit(effect, design, coefficients[-design.n_columns :], without, joint, gain, aliasing, unsampled, squares)


def fit_groups(
    search: CandidateSearch,
    fixed: Design | None,
    before: NDArray[np.float64],
    groups: Sequence[str],
    noise: NDArray[np.float64],
    stop: threading.Event | None = None,
) -> dict[str, GroupFit]:
    """Each group fitted beside `fixed` (fit_group), as many at a time as blas.in_parts allows (they
    are independent); stop: once set, the groups not yet begun raise blas.Dropped."""
    repetitions = search.campaign.n_repetitions

    def cost(group: str) -> float:
        # A time group's columns change between repetitions: fitted ring by ring on every
        # repetition's touches (measured on head_3: 0.4 s, against 0.04-0.19 s for an axis's group).
        spec = SHAPE_GROUPS[group]
        return len(spec.components) * (repetitions if spec.variable == "time" else 1)

    return dict(zip(groups, in_parts(lambda group: fit_group(search, fixed, before, group, noise), groups, stop, cost)))


def _left_out_residual(search: CandidateSearch, fit: GroupFit) -> NDArray[np.float64]:
    """What the chain and the group leave of each ring's residual, fitted without that ring."""
    mean, within = fit.joint.apply_each(fit.without)
    return search.residual - mean[:, None, :] - (0.0 if within is None else within)


def _rms(x: NDArray[np.float64]) -> float:
    return float(np.sqrt(np.mean(x**2))) if x.size else 0.0


# The look with whole A rows left out is a second look at the same rings, taken when the first
# claims nothing: its family-wise p-value is doubled (Bonferroni over the two looks).
LOOKS = 2


def find_shapes(
    search: CandidateSearch,
    chain: Sequence[Effect],
    current: NoiseTest | None,
    seed: int = 0,
    groups: Sequence[str] | None = None,
    stop: threading.Event | None = None,
) -> list[Shape]:
    """The shapes claimed beside the chain, at most MAX_SHAPES, each with the others before it in
    the model; then the best tried that was not claimed (the module docstring). `current`: the
    within-noise test of the chain (None: one repetition, nothing is claimed). When nothing is
    claimed, the groups the search's smoother cannot see at most rings (view_of) are looked at
    again with whole A rows left out. stop: once set, the groups not yet fitted raise blas.Dropped
    (a look ahead no longer wanted)."""
    # A group already in the model (a resumed study's shape) is not searched again.
    held = {effect.group.key for effect in chain if isinstance(effect, ErrorFunction)}
    groups = [g for g in (groups or SHAPE_GROUPS) if g not in held]
    if current is None or not current.fails or not groups:
        return []
    looked = look_at(search, chain, current, groups, seed, stop=stop)
    unseen = [] if any(shape.claimed for shape, _ in looked) else [g for g in groups if view_of(search, g) is not search]
    if unseen:
        rows = search.in_rows()
        current = rows.within_noise_after(list(chain), seed)
        if current is not None and current.fails:
            second = look_at(rows, chain, current, unseen, seed, LOOKS, stop=stop)
            looked += _across_looks(looked[-1], second, unseen, ~search.train, seed)
    return [shape for shape, _ in looked]


Looked = tuple[Shape, NDArray[np.float64]]  # a shape tried, with its rings' gains


def _across_looks(first: Looked, second: list[Looked], unseen: list[str], check: NDArray[np.bool_], seed: int) -> list[Looked]:
    """The second look's shapes beside the first look's best, when that is of another variable.
    Both looks predict the check rings alike, so their gains there compare them (the sign-flip
    test of replication over the check rings): a rival significantly better there takes the
    claim back; one not significantly worse is named beside it (these rings cannot tell)."""
    (rival, rival_gain), (shape, gain) = first, second[0]
    if rival.group in unseen or not shape.claimed:
        return second
    if replication(np.where(check, rival_gain - gain, 0.0), check, True, seed).p_value < REPLICATION_LEVEL:
        return [(replace(shape, claimed=False, rival=(rival.group, rival.check_reduction)), gain)]
    if replication(np.where(check, gain - rival_gain, 0.0), check, True, seed).p_value >= REPLICATION_LEVEL:
        return [(replace(shape, untold=(*shape.untold, rival.group)), gain), *second[1:]]
    return second


def look_at(
    search: CandidateSearch,
    chain: Sequence[Effect],
    current: NoiseTest,
    groups: list[str],
    seed: int,
    looks: int = 1,
    most: int = MAX_SHAPES,
    stop: threading.Event | None = None,
) -> list[Looked]:
    """One look at the groups in one search: the best claimed while the model fails, at most
    `most`, then the best tried that was not (find_shapes), each with its rings' gains; `looks`:
    the family-wise p-value's Bonferroni factor."""
    noise = ring_sigma(search.campaign.deviations) ** 2
    check = ~search.train
    fixed = search.design(list(chain)) if chain else None
    out: list[Looked] = []
    # Each ring's left-out sum of squares before the next group: the chain's (as a claim's), then
    # with the shapes claimed, as their ridge fit left it (an unpenalised refit of hundreds of
    # columns would overfit, and every next group would seem to gain).
    before = ring_residual_squares(search.residual, fixed, search.targets)
    check_before = search.check_residual(fixed)[0]
    while len([s for s, _ in out if s.claimed]) < most and groups:
        fits = fit_groups(search, fixed, before, groups, noise, stop)
        statistics, family_p = family_test(np.stack([fits[g].gain for g in fits]), check, seed)
        family_p = min(1.0, looks * family_p)
        best = list(fits)[int(np.argmax(statistics))]
        fit = fits[best]
        test = replication(fit.gain, check, True, seed)
        residual = _left_out_residual(search, fit)
        reduction = 1.0 - _rms(residual[check].mean(axis=1)) / max(_rms(check_before), 1e-300)
        after = within_noise(residual, search.smoother.weights, search.campaign.deviations, seed, held_out=check)
        brought = current.failing_rings - (after.failing_rings if after is not None else current.failing_rings)
        needed = max(RINGS_BROUGHT_WITHIN, math.ceil(SHARE_BROUGHT_WITHIN * current.failing_rings))
        material = reduction >= MATERIAL_REDUCTION or brought >= needed
        significant = family_p < REPLICATION_LEVEL and test.p_without_top < REPLICATION_LEVEL
        # Groups the rings cannot tell from it: their gains not significantly below its own.
        untold = tuple(
            g for g in fits if g != best and replication(fit.gain - fits[g].gain, check, True, seed).p_value >= REPLICATION_LEVEL
        )
        without = fit.without[:, -fit.design.n_columns :]
        params, params_u = jackknife_parameters(fit.effect, without, fit.coefficients, k=COVERAGE_FACTOR * JACKKNIFE_INFLATION)
        n_c = len(SHAPE_GROUPS[best].components)
        value = np.array([params[p.name] for p in fit.effect.parameters]).reshape(n_c, -1)
        spread = np.array([params_u[p.name] for p in fit.effect.parameters]).reshape(n_c, -1)
        fitted = type(fit.effect)(**params)
        variable = SHAPE_GROUPS[best].variable_of(search.touches)
        sampled = np.broadcast_to(variable.values(search.touches), search.touches.shape)[:, 0].ravel()
        shape = Shape(
            best,
            variable.name,
            fit.effect.knots,
            tuple(tuple(float(v) for v in row) for row in value),
            tuple(tuple(float(v) for v in row) for row in spread),
            fit.effect.periodic,
            test,
            float(family_p),
            float(reduction),
            int(brought),
            bool(significant and material and plausible_curve(best, value)),
            untold,
            fit.aliasing,
            fitted.dominant_period(sampled, fit.design.flat()[0]) if variable.angle else None,
            float(fit.effect.knots[int(np.argmax(spread.max(axis=0)))]),
            search.smoother.leave_out,
            unsampled_deg=fit.unsampled,
        )
        out.append((shape, fit.gain))
        if not shape.claimed:
            break
        # The check rings as the ridge fit left them (an unpenalised refit of the shape's hundreds
        # of columns would leave them far off, and every next group would seem material).
        fixed, before, check_before = fit.joint, fit.squares, residual[check].mean(axis=1)
        current = after
        groups = [g for g in groups if g != best]
        if after is None or not after.fails:
            break
    return out
