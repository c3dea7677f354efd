"""Which physical terms a hybrid carries on a campaign: those the campaign identifies, kept by the
hybrid's own cross-validation.

A cross-validation on the campaign's own rings cannot see one failure: aliasing. On a campaign of
few B columns (or 15-deg A rows), two catalog terms can take the same values at every ring measured
(a 4/rev and a 2/rev B error on six columns 60 deg apart: 4 = -2 modulo 6) while they differ between
the rings. A term fitted alone then holds the share of the other that the data carry (the paper
campaign's 6-column subset: B 4/rev fitted at 1.90 +- 0.06 arcsec, true 1.0, because its B 2/rev
alias, 1.8 arcsec, is not in the model; fitted together: 1.10 +- 0.11 and 1.61 +- 0.21), predicts
every ring left out of the cross-validation well (the rings left out are on the same columns,
where the alias is exact) and predicts wrongly between them, where the model is used. So before
the cross-validation chooses, a term is judged identifiable on the campaign's touches
(`identifiability`):

- an **alias** of a term is a catalog effect (any scanned setting) whose columns share more than
  CONFOUNDED with the term's over the campaign's touches, through the data part's out-of-sample
  smoother (what the hybrid's fit sees: diagnosis.separation.shared_variance), although over the
  prediction domain (the lattice at half the design's steps: between the rings) they share at most
  CONFOUNDED (separation.shared_over): the campaign cannot tell them apart, a denser one would;
- a term whose prediction between the rings the data part reproduces anyway (the trilinear
  interpolation of the term's own values at the rings gives more than CONFOUNDED of the term's
  fitted sum of squares over the prediction domain) is harmless whatever its aliases: the data part
  makes the same guess between the rings (the seat lobing on 15-deg A rows);
- otherwise the term is carried only together with its aliases that the candidates hold (one
  group, kept or dropped as one, so that each holds its own share), and not at all when it has an
  alias the candidates do not hold;
- nor when its setting (a scanned parameter: cycles per revolution, ...) is not the data's own
  choice whatever the subset cannot settle (`setting_moves`): the diagnosis chose it on part of
  the rings, in its chain's order; the setting kept must be the one of its effect that explains
  most of the data beside the other carried terms, beside each candidate not carried (found or
  seen present, so in the data, but not identifiable here), and beside all of those. A setting
  that moves to one predicting otherwise between the rings when a term the campaign cannot
  settle is or is not accounted for is not identified by it (the 3-B-column subset of a head with
  B 2/rev and a hidden B 22/rev: beside the rest B 25/rev explains most, beside the aliased
  B 2/rev B 22/rev does). No threshold: a comparison of settings of one effect, alike meaning
  more than CONFOUNDED shared over the prediction domain.

The candidates are what the diagnosis found plus what it saw present (beyond noise, plausible, but
not material on its check rings): omitting a present term biases the terms that share columns
with it. A set of terms whose fit on the campaign is implausible for a PH20/TP20-class head
(Effect.implausible) is never carried. Among the admissible sets, backward elimination on the
hybrid's cross-validated error (crossval.cross_val_predict, strict) with the one-standard-error
rule: see carried_effects. The data part beside the terms: benchmarks.stacking.carried_hybrid.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer import metrics
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.separation import CONFOUNDED, shared_over, span_share, touch_span
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect, effect_label
from ph_explorer.kinematics import Touches, campaign_touches, touch_kinematics
from ph_explorer.models import least_squares
from ph_explorer.models.crossval import OutOfSampleSmoother, cross_val_predict, unit_campaign
from ph_explorer.models.deviation_model import training_mask
from ph_explorer.models.hybrid import DataPart, HybridModel, fitted_basis, make_data_part, smoother_type
from ph_explorer.models.least_squares import Design
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.planning.ring_design import A_STEP_DEG, B_STEP_DEG, candidate_orientations

# Rings up to which the term selection leaves one ring out at a time; beyond, CARRIED_FOLDS groups
# (each hybrid fit refits its smoother, O(rings) lattice fits: leave-one-out on 123 rings costs minutes).
CARRIED_LEAVE_ONE_OUT_MAX = 30
CARRIED_FOLDS = 10


def cross_validated_curves(
    effects: Sequence[Effect], campaign: Campaign, train: NDArray[np.bool_], data_part: DataPart = "trilinear"
) -> NDArray[np.float64]:
    """Each training ring's out-of-sample curve (n_train, n_pt) um of a hybrid with these effects:
    every ring predicted by the hybrid fitted without it (crossval.cross_val_predict, strict:
    neither its physical terms nor its data part see the ring)."""
    rings = int(train.sum())
    folds = None if rings <= CARRIED_LEAVE_ONE_OUT_MAX else CARRIED_FOLDS
    predicted = cross_val_predict(lambda: HybridModel(effects, data_part), campaign, train, folds=folds, strict=True)
    return predicted[train]


def cross_validated_errors(
    effects: Sequence[Effect], campaign: Campaign, train: NDArray[np.bool_], data_part: DataPart = "trilinear"
) -> NDArray[np.float64]:
    """Each training ring's out-of-sample MAE (um, against the repetition mean) of a hybrid with
    these effects (cross_validated_curves)."""
    return metrics.ring_mae(cross_validated_curves(effects, campaign, train, data_part), campaign.deviations[train])["mean"]


def cross_validated_mae(
    effects: Sequence[Effect], campaign: Campaign, train: NDArray[np.bool_], data_part: DataPart = "trilinear"
) -> float:
    """The mean of cross_validated_errors over the training rings."""
    return float(cross_validated_errors(effects, campaign, train, data_part).mean())


def gain_beyond_noise(simpler: NDArray[np.float64], fuller: NDArray[np.float64]) -> float:
    """How far the fuller model's cross-validated error lies below the simpler one's, in standard
    errors of the mean paired difference over the rings (> 1: the terms earn their place)."""
    difference = simpler - fuller
    if np.abs(difference).max(initial=0.0) <= 1e-9 * max(float(np.abs(simpler).mean()), 1e-300):
        return 0.0  # the same predictions (a term the data part already holds exactly): rounding only
    error = difference.std(ddof=1) / np.sqrt(difference.size) if difference.size > 1 else 0.0
    return float(difference.mean() / error) if error > 0 else (np.inf if difference.mean() > 0 else -np.inf)


# -- identifiability ---------------------------------------------------------------------------------
def prediction_domain(campaign: Campaign) -> Touches:
    """Where the model will be asked: the design's candidate lattice at half its steps (rings on and
    between the nodes), within the campaign's A range, one repetition each."""
    grid = candidate_orientations(campaign.geometry, A_STEP_DEG / 2.0, B_STEP_DEG / 2.0)
    a = campaign.orientations[:, 0]
    inside = (grid[:, 0] >= a.min() - 1e-9) & (grid[:, 0] <= a.max() + 1e-9)
    return touch_kinematics(grid[inside], campaign.geometry, 1)


def interpolation_weights(orientations: ArrayLike, at: ArrayLike, model_type: type[TrilinearModel] = TrilinearModel) -> NDArray[np.float64]:
    """(m, n_o): a linear data part's interpolation, from the rings at `orientations`, at `at`
    (fitted on unit vectors, its interpolation is its weights: crossval.unit_campaign)."""
    return model_type().fit(unit_campaign(orientations)).interpolate(at)


def catalog_alternatives(catalog: Catalog = DEFAULT_CATALOG) -> list[Effect]:
    """Every candidate effect of the catalog at every scanned setting: the possible aliases."""
    return [cls(**settings) for cls in catalog.candidates().values() for settings in cls.scan_grid()]


def _same(a: Effect, b: Effect) -> bool:
    return a.id == b.id and a.settings() == b.settings()


class Identification:
    """What a campaign's touches identify of candidate terms (see the module docstring)."""

    def __init__(self, campaign: Campaign, alternatives: Sequence[Effect] | None = None, data_part: DataPart = "trilinear") -> None:
        self.campaign = campaign
        self.touches = campaign_touches(campaign)
        every = np.ones(campaign.n_orientations, dtype=bool)
        linear = smoother_type(make_data_part(data_part), campaign, every)  # the data part the terms sit beside
        self.smoother = OutOfSampleSmoother(campaign.orientations, every, linear)
        self.targets = Design(self.smoother.residual(campaign.deviations)[..., None], None)
        self.domain = prediction_domain(campaign)
        self.between = interpolation_weights(campaign.orientations, self.domain.orientations, linear)
        self.alternatives = catalog_alternatives() if alternatives is None else list(alternatives)
        self._designs: dict[str, Design | None] = {}
        self._spans: dict[str, tuple[NDArray[np.float64], NDArray[np.float64] | None]] = {}
        self._crosses: dict[tuple[str, str], NDArray[np.float64]] = {}

    def design(self, effect: Effect) -> Design | None:
        """The effect's columns through the smoother (None: the touches cannot show it)."""
        key = effect_label(effect)
        if key not in self._designs:
            made = None
            if not effect.unmet_needs(self.touches):
                made = Design(fitted_basis(effect, self.touches)[0], self.smoother)
                made = made if made.n_columns and np.abs(made.mean).max(initial=0.0) > 0 else None
            self._designs[key] = made
        return self._designs[key]

    def shared(self, effect: Effect, other: Effect) -> float:
        """diagnosis.separation.shared_variance of the two designs, each one's span made once."""
        keys = effect_label(effect), effect_label(other)
        for key, e in zip(keys, (effect, other)):
            if key not in self._spans:
                self._spans[key] = touch_span(self.design(e))
        return span_share(self._spans[keys[0]], self._spans[keys[1]])

    def learnable_between(self, effect: Effect) -> float:
        """The share of the effect's fitted term over the prediction domain that the data part's
        interpolation of its values at the rings reproduces (1: the data part guesses the same)."""
        own = self.design(effect)
        if own is None or effect.unmet_needs(self.domain):
            return 1.0  # nothing to fit, or nothing it predicts there (no touch times)
        coef = least_squares.fit(own, self.targets)[0][:, 0]
        at_rings = fitted_basis(effect, self.touches)[0].mean(axis=1) @ coef  # (n_o, n_pt)
        there = fitted_basis(effect, self.domain)[0][:, 0] @ coef  # (m, n_pt)
        left = there - np.tensordot(self.between, at_rings, axes=(1, 0))
        total = float((there**2).sum())
        return 1.0 - float((left**2).sum()) / total if total > 0 else 1.0

    def aliases(self, effect: Effect) -> list[tuple[Effect, float]]:
        """Catalog terms the campaign cannot tell from the effect that the prediction domain can,
        with their shared variance over the campaign (largest first)."""
        own = self.design(effect)
        if own is None:
            return []
        found = []
        for other in self.alternatives:
            if _same(other, effect):
                continue
            theirs = self.design(other)
            if theirs is None:
                continue
            shared = self.shared(effect, other)
            if shared > CONFOUNDED and not self._alike_between(effect, other):
                found.append((other, shared))
        return sorted(found, key=lambda item: -item[1])

    def _cross(self, a: Effect | None, b: Effect | None) -> NDArray[np.float64]:
        """a'b over single touches through the smoother (None: the data), each pair made once."""
        key = (effect_label(a) if a else "", effect_label(b) if b else "")
        if key not in self._crosses:
            x, y = (self.design(a) if a else self.targets), (self.design(b) if b else self.targets)
            (xm, xw), (ym, yw) = x.flat(), y.flat()
            product = x.n_rep * xm.T @ ym
            self._crosses[key] = product if xw is None or yw is None else product + xw.T @ yw
        return self._crosses[key]

    def explained(self, terms: Sequence[Effect]) -> float:
        """The sum of squares of the data the terms explain jointly (through the smoother)."""
        terms = [t for t in terms if self.design(t) is not None]
        if not terms:
            return 0.0
        gram = np.block([[self._cross(a, b) for b in terms] for a in terms])
        dot = np.concatenate([self._cross(a, None) for a in terms])
        scale = max(self.design(t).scale for t in terms)
        return float(least_squares.solve(gram, dot, scale, self.targets.mean.shape[0] * self.targets.mean.shape[1])[1][0])

    def setting_moves(self, effect: Effect, carried: Sequence[Effect], dropped: Sequence[Effect]) -> tuple[Effect, str] | None:
        """The setting of the effect that explains most of the data instead of the effect's own, and
        beside what, when it predicts otherwise between the rings; None when the effect's own
        setting is the best beside the other carried terms, beside each dropped candidate and
        beside all of them (module docstring)."""
        family = [a for a in self.alternatives if a.id == effect.id and self.design(a) is not None]
        rest = [c for c in carried if c is not effect]
        extras = [[], *([d] for d in dropped)] + ([list(dropped)] if len(dropped) > 1 else [])
        for extra in extras if len(family) > 1 else []:
            beside = [*rest, *extra]
            before = self.explained(beside)
            scores = [-np.inf if any(_same(a, b) for b in beside) else self.explained([*beside, a]) - before for a in family]
            best = family[int(np.argmax(scores))]
            if not _same(best, effect) and not self._alike_between(effect, best):
                return best, ", ".join(effect_label(e) for e in extra) or "the other carried terms"
        return None

    def groups(self, effects: Sequence[Effect]) -> tuple[list[list[Effect]], list[dict[str, Any]]]:
        """The candidate terms as groups carried together, and why each term is or is not carried.

        A term is dropped when the data part does not reproduce it between the rings and it has an
        alias no candidate holds; a term that predicts the same as an earlier candidate everywhere
        (shared over the prediction domain too) is that candidate already.
        """
        kept: list[Effect] = []
        report: list[dict[str, Any]] = []
        partners: list[list[Effect]] = []  # each kept term's aliases among the candidates
        for effect in effects:
            entry: dict[str, Any] = {"effect": effect_label(effect)}
            report.append(entry)
            if self.design(effect) is None:
                entry.update(carried=False, reason="nothing of it is left by the circle fit and the data part on these rings")
                continue
            twin = next((k for k in kept if self._redundant(effect, k)), None)
            if twin is not None:
                entry.update(carried=False, reason=f"predicts as {effect_label(twin)} does wherever the head goes")
                continue
            entry["learnable_between"] = round(self.learnable_between(effect), 3)
            if entry["learnable_between"] > CONFOUNDED:
                kept.append(effect)
                partners.append([])
                entry.update(carried=True, reason="the data part reproduces it between the rings")
                continue
            aliases = self.aliases(effect)
            inside = [c for c in effects if any(_same(a, c) for a, _ in aliases)]
            outside = [(a, s) for a, s in aliases if not any(_same(a, c) for c in effects)]
            entry["aliases"] = [f"{effect_label(a)} ({s:.2f})" for a, s in aliases[:5]]
            if outside:
                entry.update(
                    carried=False, reason=f"aliased with {effect_label(outside[0][0])} on these rings ({outside[0][1]:.2f} shared)"
                )
                continue
            kept.append(effect)
            partners.append(inside)
            entry.update(carried=True, reason="identifiable" if not inside else "carried with its aliases among the candidates")
        # A setting the data choose only with or without a term the campaign cannot settle: out.
        left_out = [
            e
            for e in effects
            if self.design(e) is not None and not any(k is e for k in kept) and not any(self._redundant(e, k) for k in kept)
        ]
        for i in reversed(range(len(kept))):
            entry = next(r for r in report if r["effect"] == effect_label(kept[i]))
            moved = None if entry["learnable_between"] > CONFOUNDED else self.setting_moves(kept[i], kept, left_out)
            if moved is not None:
                entry.update(
                    carried=False,
                    reason=f"beside {moved[1]}, {effect_label(moved[0])} explains more of the data: "
                    "its setting is not settled by these rings",
                )
                del kept[i], partners[i]
        # A term carried with an alias that is itself not carried would hold the alias's share: out too.
        dropped = True
        while dropped:
            dropped = False
            for i, mine in enumerate(partners):
                missing = [a for a in mine if not any(k is a for k in kept)]
                if missing:
                    entry = next(r for r in report if r["effect"] == effect_label(kept[i]))
                    entry.update(carried=False, reason=f"its alias {effect_label(missing[0])} is not carried")
                    del kept[i], partners[i]
                    dropped = True
                    break
        links = [(i, j) for i, mine in enumerate(partners) for j, other in enumerate(kept) if any(_same(other, a) for a in mine)]
        return _connected(kept, links), report

    def _redundant(self, effect: Effect, other: Effect) -> bool:
        mine, theirs = self.design(effect), self.design(other)
        if mine is None or theirs is None:
            return False
        return self.shared(effect, other) > CONFOUNDED and self._alike_between(effect, other)

    def _alike_between(self, effect: Effect, other: Effect) -> bool:
        """Whether the two share more than CONFOUNDED over the prediction domain; one that needs what
        the domain lacks (touch times) predicts nothing there: not alike."""
        if effect.unmet_needs(self.domain) or other.unmet_needs(self.domain):
            return False
        return shared_over(effect, other, [self.domain]) > CONFOUNDED


def _connected(effects: list[Effect], links: list[tuple[int, int]]) -> list[list[Effect]]:
    """The effects in groups joined by the links (union-find), in their first member's order."""
    parent = list(range(len(effects)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for a, b in links:
        parent[root(a)] = root(b)
    groups: dict[int, list[Effect]] = {}
    for i, effect in enumerate(effects):
        groups.setdefault(root(i), []).append(effect)
    return sorted(groups.values(), key=lambda g: effects.index(g[0]))


def plausible_fit(effects: Sequence[Effect], campaign: Campaign, data_part: DataPart = "trilinear") -> bool:
    """Every fitted parameter of the hybrid with these effects within its plausible range."""
    if not effects:
        return True
    model = HybridModel(effects, data_part).fit(campaign)
    return not any(e.implausible(p["params"]) for e, p in zip(model.effects, model.effect_parameters()))


def fixed_data_part(data_part: DataPart, campaign: Campaign, train: NDArray[np.bool_]) -> DataPart:
    """A data part with hyperparameters (the GP's kernel) as the factory of it with them learnt once
    on the training rings, else the data part as given: every fold and every set of terms is then
    cross-validated beside the same smoother, its kernel not re-learnt per fold (as the GP's
    closed-form leave-one-out does: Rasmussen and Williams 2006, section 5.4.2)."""
    linear = getattr(make_data_part(data_part), "linear_smoother", None)
    return linear(campaign, train) if linear is not None else data_part


def carried_effects(
    campaign: Campaign,
    effects: Sequence[Effect],
    data_part: DataPart = "trilinear",
    train: ArrayLike | None = None,
    identification: Identification | None = None,
) -> tuple[list[Effect], list[dict[str, Any]], list[dict[str, Any]], NDArray[np.float64]]:
    """The effects the data can carry: identifiable (module docstring), plausible, and kept by
    backward elimination on the hybrid's own cross-validated error.

    Starting from every identifiable group, the group whose removal costs least is removed while
    that cost is within one standard error (the paired differences of the rings' cross-validated
    errors; the one-standard-error rule of Breiman et al.: of two models the data cannot tell
    apart, the simpler), or while what is left fits implausibly; the data part alone (no effect) is
    compared with what is left the same way: on touch noise alone nothing is kept. Returns the
    effects kept (in their given order), the path [{"effects": [labels], "cv_mae_um"}, ...] of every
    set tried, once each, the identifiability report of every candidate, and the training rings'
    out-of-sample curves of the hybrid with the effects kept (cross_validated_curves).
    """
    mask = training_mask(campaign, train)
    data_part = fixed_data_part(data_part, campaign, mask)
    fitted = campaign.subset(mask)
    check = identification if identification is not None else Identification(fitted, data_part=data_part)
    groups, report = check.groups(effects) if effects else ([], [])
    path: list[dict[str, Any]] = []
    tried: dict[tuple, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}  # labels -> curves, ring errors

    def flat(chosen: list[list[Effect]]) -> list[Effect]:
        members = [e for g in chosen for e in g]
        return [e for e in effects if any(m is e for m in members)]

    def errors(chosen: list[list[Effect]]) -> NDArray[np.float64]:
        terms = flat(chosen)
        key = tuple(effect_label(e) for e in terms)
        if key not in tried:  # a set reached twice (the data part alone) is cross-validated once
            curves = cross_validated_curves(terms, campaign, mask, data_part)
            tried[key] = curves, metrics.ring_mae(curves, campaign.deviations[mask])["mean"]
            path.append({"effects": list(key), "cv_mae_um": round(float(tried[key][1].mean()), 5)})
        return tried[key][1]

    kept = list(groups)
    current = errors(kept)
    while kept:
        admissible = plausible_fit(flat(kept), fitted, data_part)
        trials = [(errors(kept[:i] + kept[i + 1 :]), i) for i in range(len(kept))]
        gains = [gain_beyond_noise(without, current) for without, _ in trials]
        cheapest = int(np.argmin(gains))
        if gains[cheapest] > 1.0 and admissible:
            break
        current, index = trials[cheapest]
        kept = kept[:index] + kept[index + 1 :]
    # Elimination stops at a local minimum: the data part alone is compared with it too.
    if kept and len(kept) < len(groups) and gain_beyond_noise(errors([]), current) <= 1.0:
        kept = []
    terms = flat(kept)  # its set was cross-validated on the way (the start, a trial or the data part alone)
    return terms, path, report, tried[tuple(effect_label(e) for e in terms)][0]
