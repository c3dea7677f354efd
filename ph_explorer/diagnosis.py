"""See where a model fails, find the missing physical effect, add it, and watch the error fall.

1. Where it fails: the out-of-sample error at every orientation. Training orientations are
   predicted by leave-one-orientation-out (group-wise cross-validation) of the lattice interpolator,
   held-out (check) orientations by the model fitted on all training orientations. Each error is
   read against its own noise floor: a leave-one-out prediction carries the noise of the
   neighbours it is made of, so its floor is E|e| of that combined noise.
2. Which effect is missing: every catalog effect not yet in the model competes for what the
   baseline cannot predict out of sample. Its basis columns are put through the same
   out-of-sample smoother, so that an effect is only credited with what the baseline does not
   already capture (physics.md). Free parameters are scanned (cycles per revolution 1-40 for the
   cyclic errors). A candidate counts only when it explains more than the same scan explains on
   pure noise of the campaign's own repetition sigma (Monte Carlo), and when adding it would lower
   the out-of-sample rms error against the reference that exposes it materially (MATERIAL_REDUCTION).
3. Add it: a HybridModel with the chosen effects + the data-driven part.
4. Watch the error fall: the check-ring MAE of each step against both references and the floors.
"""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.effects import CATALOG, Effect
from ph_explorer.effects.base import joint_angle_deg, rotation_deviation_um_per_arcsec
from ph_explorer.errors import InputError
from ph_explorer.evaluation import MEAN_ABS_PER_SIGMA, noise_floor
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import Touches, campaign_touches
from ph_explorer.models.base import DeviationModel
from ph_explorer import outofsample
from ph_explorer.models.hybrid import HybridModel, fitted_basis
from ph_explorer.outofsample import Design, OutOfSampleSmoother

# Monte Carlo draws of pure noise for the significance of a candidate's scan.
NULL_DRAWS = 39
# A candidate must explain more than this multiple of the most that pure noise explained in the
# same scan (a look-elsewhere-corrected significance test) ...
NULL_MARGIN = 2.0
# ... and lower the out-of-sample rms error against the reference that exposes it by at least this
# fraction: less is within what a user would see as the model's normal scatter, not a missing effect.
MATERIAL_REDUCTION = 0.15
# Significant scan values of one effect tried for materiality, most explained first.
MAX_MATERIAL_TRIALS = 8
# Effects with no deterministic part cannot be "added".
NOT_CANDIDATES = {"noise"}
DIGITS = 5


@dataclass
class Candidate:
    """A catalog effect tested against the out-of-sample residual."""

    effect: str
    name: str
    explained_fraction: float  # share of the out-of-sample residual (single touches) it explains
    error_reduction: float  # relative fall of the out-of-sample rms error against the exposing reference
    noise_fraction: float  # the largest share the same scan explains on pure noise
    significant: bool
    params: dict[str, float]
    structural: dict[str, Any]
    teaching: str
    evidence: dict[str, Any] = field(default_factory=dict)
    note: str = ""  # why the effect could not be tested on this campaign, if it could not

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("explained_fraction", "error_reduction", "noise_fraction"):
            out[key] = round(out[key], DIGITS)
        out["params"] = _rounded(self.params)
        return out


@dataclass
class Step:
    added: list[str]
    mae_um: dict[str, float]
    noise_floor_um: dict[str, float]
    params: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class Diagnosis:
    noise_floor_um: dict[str, float]
    baseline_model: str
    baseline_mae_um: dict[str, float]
    candidates: list[Candidate]
    verdict: str  # "missing" or "none"
    steps: list[Step]
    orientations: NDArray[np.float64]
    out_of_sample_mae_um: dict[str, NDArray[np.float64]]  # per orientation: "mean", "single"
    out_of_sample_floor_um: dict[str, NDArray[np.float64]]
    failing: NDArray[np.bool_]  # orientations significantly worse than their floor
    held_out: NDArray[np.bool_]
    hybrid: HybridModel | None = None

    def as_dict(self) -> dict[str, Any]:
        """The diagnose --json object."""
        return {
            "noise_floor_um": _rounded(self.noise_floor_um),
            "baseline": {"model": self.baseline_model, "mae_um": _rounded(self.baseline_mae_um)},
            "candidates": [c.as_dict() for c in self.candidates],
            "verdict": self.verdict,
            "steps": [
                {"added": s.added, "mae_um": _rounded(s.mae_um), "noise_floor_um": _rounded(s.noise_floor_um), "params": s.params}
                for s in self.steps
            ],
            "where_it_fails": [
                {
                    "A_deg": float(a),
                    "B_deg": float(b),
                    "held_out": bool(h),
                    "mae_um": _rounded({k: v[i] for k, v in self.out_of_sample_mae_um.items()}),
                    "floor_um": _rounded({k: v[i] for k, v in self.out_of_sample_floor_um.items()}),
                }
                for i, ((a, b), h) in enumerate(zip(self.orientations, self.held_out))
                if self.failing[i]
            ],
        }


# -- 1. where it fails -----------------------------------------------------------------------------
def check_mae(model: DeviationModel, campaign: Campaign, mask: NDArray[np.bool_]) -> dict[str, float]:
    """A model's MAE (um) over the held-out rings, against the repetition mean and single repetitions.

    The model predicts every touch (physical terms may depend on the touch order and time); a
    hybrid predicts each held-out ring with that ring left out of its physical fit.
    """
    rings = np.flatnonzero(mask)
    if isinstance(model, HybridModel):
        predicted = model.check_predictions(campaign, rings)
    else:
        predicted = model.predict_touches(campaign_touches(campaign.subset(rings)))
    measured = campaign.deviations[rings]
    return {
        "mean": float(np.abs(predicted.mean(axis=1) - measured.mean(axis=1)).mean()),
        "single": float(np.abs(predicted - measured).mean()),
    }


def repetition_sigma(campaign: Campaign, model: HybridModel | None = None) -> float:
    """Pooled repetition sigma per touch (um) of what the model's physical terms leave.

    Terms that change between repetitions (direction with an alternating scan, drift) inflate the
    raw repetition spread; once they are modelled, the noise floor is read from what remains.
    """
    if model is None or not model.effects:
        return campaign.noise_sigma_um()
    remainder = campaign.deviations - model.physical_part(campaign_touches(campaign))
    return float(np.sqrt(np.mean(remainder.var(axis=1, ddof=1)))) if campaign.n_repetitions > 1 else float("nan")


def failing_orientations(mae: NDArray[np.float64], floor: NDArray[np.float64], n_points: int) -> NDArray[np.bool_]:
    """Orientations whose MAE exceeds their floor by more than 4 standard errors of an N-point MAE.

    For Gaussian errors |e| has relative spread sqrt(pi/2 - 1) ~ 0.76; the MAE of N points has
    that spread over sqrt(N).
    """
    return mae > floor * (1.0 + 4.0 * math.sqrt(math.pi / 2.0 - 1.0) / math.sqrt(n_points))


# -- 2. which effect is missing --------------------------------------------------------------------
def _structural_grid(effect: Effect) -> list[dict[str, Any]]:
    names = list(effect.structural)
    if not names:
        return [{}]
    return [dict(zip(names, values)) for values in itertools.product(*(effect.structural[n] for n in names))]


class CandidateSearch:
    """Scores catalog effects against what the baseline cannot predict out of sample."""

    def __init__(self, campaign: Campaign, train: NDArray[np.bool_], seed: int = 0) -> None:
        self.campaign = campaign
        self.train = np.asarray(train, dtype=bool)
        self.held_out = np.flatnonzero(~self.train)
        # Every ring's out-of-sample residual: leave-one-out at training rings, the whole training
        # set at held-out rings (whose measurements never enter a data-driven fit).
        self.touches = campaign_touches(campaign)
        self.smoother = OutOfSampleSmoother(campaign.orientations, self.train)
        self.residual = self.smoother.residual(campaign.deviations)
        sigma = campaign.noise_sigma_um()
        self.sigma = sigma if np.isfinite(sigma) and sigma > 0 else float(np.std(self.residual))
        n_o, n_rep, n_pt = campaign.deviations.shape
        rng = np.random.default_rng(seed)
        # Pure touch noise with the campaign's post-fit spread, through the same circle fit and smoother.
        inflate = math.sqrt(n_pt / max(n_pt - 3, 1))
        noise = remove_size_and_centre(rng.standard_normal((n_o, n_rep, NULL_DRAWS, n_pt)) * self.sigma * inflate)
        noise = np.moveaxis(self.smoother.residual(noise), 2, -1)  # (n_o, n_rep, n_pt, draws)
        # Column 0: the data's residual; the others: what noise alone would leave.
        self.targets = Design(np.concatenate([self.residual[..., None], noise], axis=-1), None)

    def design(self, effect: Effect, structural: dict[str, Any]) -> Design:
        return Design(fitted_basis(effect, self.touches, structural)[0], self.smoother)

    def score(self, effect: Effect, fixed: Design | None = None) -> Candidate:
        """The candidate's best scan value, beyond the columns `fixed` already in the model.

        Every scan value is tested against pure noise; among the significant ones (most explained
        first, at most MAX_MATERIAL_TRIALS) the first that also lowers the held-out error
        materially is chosen, so that a large but harmless component of the same effect (a
        low-order cyclic error the grid resolves) does not hide a short-period one that it does not.
        """
        total_all = self.targets.total()
        base = outofsample.fit(fixed, self.targets)[1] if fixed is not None else np.zeros_like(total_all)
        total = float(total_all[0] - base[0])
        scanned: list[tuple[float, dict[str, Any]]] = []
        null_best = np.zeros(NULL_DRAWS)
        for structural in _structural_grid(effect):
            design = self.design(effect, structural)
            if not design.n_columns:
                continue
            joint = design if fixed is None else fixed.stacked(design)
            explained = outofsample.fit(joint, self.targets)[1] - base
            null_best = np.maximum(null_best, explained[1:])
            scanned.append((float(explained[0]), structural))
        if not scanned:
            return Candidate(effect.id, effect.name, 0.0, 0.0, 0.0, False, {}, {}, effect.teaching)
        scanned.sort(key=lambda item: item[0], reverse=True)
        threshold = NULL_MARGIN * float(null_best.max())
        trials = [item for item in scanned if item[0] > threshold][:MAX_MATERIAL_TRIALS] or scanned[:1]
        before = self.check_residual(fixed)
        chosen = None
        for explained, structural in trials:
            design = self.design(effect, structural)
            joint = design if fixed is None else fixed.stacked(design)
            reduction = self.check_reduction(joint, before)
            if chosen is None or (reduction >= MATERIAL_REDUCTION and chosen[2] < MATERIAL_REDUCTION):
                chosen = (explained, structural, reduction, design, joint)
            if reduction >= MATERIAL_REDUCTION:
                break
        explained, structural, reduction, design, joint = chosen
        own = outofsample.fit(joint, self.targets)[0][-design.n_columns :, 0]
        significant = bool(explained > threshold and reduction >= MATERIAL_REDUCTION)
        params = effect.from_coefficients(own, **structural)
        return Candidate(
            effect=effect.id,
            name=effect.name,
            explained_fraction=explained / max(total, 1e-300),
            error_reduction=reduction,
            noise_fraction=float(null_best.max() / max(total, 1e-300)),
            significant=significant,
            params={k: float(v) for k, v in params.items()},
            structural=structural,
            teaching=effect.teaching,
            evidence=self.evidence(effect, design, own, structural),
        )

    def check_residual(self, design: Design | None) -> tuple[NDArray, NDArray]:
        """The held-out rings' residual (mean, single touches) left by design, each ring left out of its fit."""
        residual = self.residual[self.held_out]
        if design is not None and design.n_columns:
            coef = outofsample.jackknife(design, self.targets, self.held_out)  # (m, c)
            mean = np.einsum("opc,oc->op", design.mean[self.held_out], coef)
            within = 0.0 if design.within is None else np.einsum("orpc,oc->orp", design.within[self.held_out], coef)
            residual = residual - mean[:, None, :] - within
        return residual.mean(axis=1), residual

    def check_reduction(self, joint: Design, before: tuple[NDArray, NDArray]) -> float:
        """How much the joint design lowers the held-out rings' rms error from `before` (a
        check_residual), against the reference that exposes it: the repetition mean, or single
        repetitions for what changes between them."""
        mean_before, single_before = before
        mean_after, single_after = self.check_residual(joint)
        rms = lambda x: float(np.sqrt(np.mean(x**2)))
        by_mean = 1.0 - rms(mean_after) / max(rms(mean_before), 1e-300)
        by_single = 1.0 - rms(single_after) / max(rms(single_before), 1e-300)
        return float(max(by_mean, by_single, 0.0))

    def evidence(self, effect: Effect, design: Design, coef: NDArray[np.float64], structural: dict[str, Any]) -> dict[str, Any]:
        """Residual and the candidate's fitted terms, binned against the variable the effect depends on.

        A cyclic axis error is shown as what it is, an angle: against its phase (cycles per
        revolution x joint angle, mod 360), each bin's angular error in arcsec is the lever-weighted
        least squares of the radial residual (a touch's lever: um of deviation per arcsec).
        """
        mean, within = design.apply(coef)
        fitted = np.broadcast_to(mean[:, None, :] + (0.0 if within is None else within), self.residual.shape)
        axis = getattr(effect, "axis", None)
        if axis in ("A", "B") and "cycles_per_rev" in structural:
            m = float(structural["cycles_per_rev"])
            x = np.mod(m * joint_angle_deg(self.touches, axis), 360.0)
            weight = rotation_deviation_um_per_arcsec(self.touches, axis)
            x_label, y_label, edges = f"{m:g} x {axis} joint angle, mod 360 (deg)", "out-of-sample angular residual (arcsec)", np.linspace(0, 360, 37)
        else:
            x_label, x = evidence_axis(effect.id, self.touches)
            weight, y_label = None, "out-of-sample residual (um)"
            flat = np.ravel(x)
            edges = np.linspace(flat.min(), flat.max() + 1e-9, 49)
        x = np.broadcast_to(x, self.residual.shape).ravel()
        which = np.clip(np.digitize(x, edges) - 1, 0, len(edges) - 2)
        w = np.ones_like(x) if weight is None else np.broadcast_to(weight, self.residual.shape).ravel()
        norm = np.bincount(which, w * w, minlength=len(edges) - 1)
        used = norm > 1e-12 * max(norm.max(), 1e-300)
        binned = lambda v: np.bincount(which, w * np.ravel(v), minlength=len(edges) - 1)[used] / norm[used]
        centre = 0.5 * (edges[:-1] + edges[1:])
        return {
            "x_label": x_label,
            "y_label": y_label,
            "x": np.round(centre[used], 3).tolist(),
            "residual": np.round(binned(self.residual), DIGITS).tolist(),
            "fitted": np.round(binned(fitted), DIGITS).tolist(),
        }


def evidence_axis(effect_id: str, touches: Touches) -> tuple[str, NDArray[np.float64]]:
    """The variable an effect's signature is read against, for every touch."""
    if effect_id == "b_axis_cyclic":
        return "B joint angle at the touch (deg)", touches.b_deg
    if effect_id == "a_axis_cyclic":
        return "A joint angle at the touch (deg)", touches.a_deg
    if effect_id in ("lobing",):
        return "force azimuth psi in the probe frame (deg)", touches.psi_deg
    if effect_id == "gravity":
        return "nominal A0 (deg)", np.broadcast_to(touches.orientations[:, :1, None], touches.a_deg.shape)
    if effect_id == "drift" and touches.times_s is not None:
        return "time of the touch (s)", touches.times_s
    if effect_id == "direction":
        return "B joint approach sign x point angle (deg)", touches.b_approach * touches.theta_deg
    return "point angle theta (deg)", np.broadcast_to(touches.theta_deg, touches.a_deg.shape)


def rank_candidates(
    search: CandidateSearch,
    effects: Sequence[Effect],
    exclude: Sequence[str] = (),
    fixed: Design | None = None,
    progress: Callable[[str], None] | None = None,
) -> list[Candidate]:
    """Every effect not excluded, best first (by the share of the residual it explains)."""
    out = []
    for effect in effects:
        if effect.id in exclude or effect.id in NOT_CANDIDATES:
            continue
        if progress is not None:
            progress(effect.id)
        try:
            candidate = search.score(effect, fixed)
        except InputError as error:  # e.g. drift on a campaign without touch times
            candidate = Candidate(effect.id, effect.name, 0.0, 0.0, 0.0, False, {}, {}, effect.teaching, note=error.message)
        out.append(candidate)
    out.sort(key=lambda c: (c.significant, c.explained_fraction), reverse=True)
    return out


# -- 3 + 4. add effects, watch the error fall ------------------------------------------------------
def add_effects(
    campaign: Campaign,
    effects: Sequence[Effect],
    structural: Sequence[dict[str, Any]] | None = None,
    data_model: str | Callable[[], DeviationModel] = "trilinear",
    progress: Callable[[str, float], None] | None = None,
) -> tuple[HybridModel, Step]:
    """Fit the hybrid with these physical effects on the campaign and measure it on the held-out rings.

    structural: each effect's scanned values (e.g. from a Candidate); default the effect's own.
    Returns the fitted model and its Step (MAE against both references, and the noise floor of
    what its physical terms leave).
    """
    held_out = campaign.holdout_mask()
    hybrid = HybridModel(list(effects), data_model, structural, progress=progress).fit(campaign, ~held_out)
    floor = noise_floor(repetition_sigma(campaign, hybrid), campaign.n_repetitions)
    step = Step([e.id for e in effects], check_mae(hybrid, campaign, held_out), floor, hybrid.effect_parameters())
    return hybrid, step


def diagnose(
    campaign: Campaign,
    add: Sequence[str] | None = None,
    baseline: DeviationModel | None = None,
    data_model: str | Callable[[], DeviationModel] = "trilinear",
    catalog: dict[str, type[Effect]] | None = None,
    max_steps: int = 3,
    progress: Callable[[str], None] | None = None,
    seed: int = 0,
) -> Diagnosis:
    """Run the whole loop on a campaign; the check rings (campaign.holdout_mask()) are never fitted.

    add: effect ids to add in that order; None adds the best significant candidate, then searches
    again, until no candidate is left (at most max_steps effects).
    baseline: a trained model to start from (default: the trilinear model fitted on the training
    orientations).
    """
    catalog = dict(CATALOG if catalog is None else catalog)
    held_out = campaign.holdout_mask()
    train = ~held_out
    if train.sum() < 4:
        raise InputError("too few training orientations to diagnose (need at least 4 off the held-out set)", file=campaign.source)
    if not held_out.any():
        raise InputError(
            "no held-out orientation to measure the error on: give check orientations in the sidecar or off-grid rings",
            file=campaign.source,
        )
    unknown = [a for a in (add or []) if a not in catalog]
    if unknown:
        raise InputError(f"unknown effect {unknown[0]!r} (known: {', '.join(sorted(catalog))})", column="--add")

    effects = [cls() for cls in catalog.values()]
    by_id = {e.id: e for e in effects}
    sigma = campaign.noise_sigma_um()
    floor = noise_floor(sigma, campaign.n_repetitions)
    check_touches = campaign_touches(campaign.subset(held_out))

    if baseline is None:
        baseline = HybridModel([], data_model).fit(campaign, train)
        baseline_name = baseline.data_model.name
    else:
        baseline_name = baseline.name
    baseline_mae = check_mae(baseline, campaign, held_out)

    # 1. where it fails: leave-one-out residuals at training rings, the training fit at check rings.
    search = CandidateSearch(campaign, train, seed)
    residual = search.residual
    # A prediction made of neighbours carries their noise: E|e| of both together is the floor.
    weights_sq = (search.smoother.weights**2).sum(axis=1)
    n_rep = campaign.n_repetitions
    mae = {"mean": np.abs(residual.mean(axis=1)).mean(axis=1), "single": np.abs(residual).mean(axis=(1, 2))}
    floors = {
        "mean": MEAN_ABS_PER_SIGMA * sigma * np.sqrt((1 + weights_sq) / n_rep),
        "single": MEAN_ABS_PER_SIGMA * sigma * np.sqrt(1 + weights_sq / n_rep),
    }
    if baseline_name != "trilinear":
        # A trained baseline of another kind speaks for itself at the check rings.
        predicted = baseline.predict_touches(check_touches)
        measured = campaign.deviations[held_out]
        mae["mean"][held_out] = np.abs(predicted.mean(axis=1) - measured.mean(axis=1)).mean(axis=1)
        mae["single"][held_out] = np.abs(predicted - measured).mean(axis=(1, 2))
        floors["mean"][held_out] = floor["mean"]
        floors["single"][held_out] = floor["single"]
    failing = failing_orientations(mae["mean"], floors["mean"], campaign.n_points) | failing_orientations(
        mae["single"], floors["single"], campaign.n_points
    )

    # 2. which effect is missing
    candidates = rank_candidates(search, effects, progress=progress)
    verdict = "missing" if candidates and candidates[0].significant else "none"

    # 3 + 4. add effects one at a time, each step refitted and measured on the check rings
    steps = [Step([], baseline_mae, floor)]
    chosen: list[Effect] = []
    structural: list[dict[str, Any]] = []
    hybrid = None
    scan = {c.effect: c for c in candidates}
    remaining = list(candidates)
    for position in range(len(add) if add is not None else max_steps):
        if add is not None:
            pick = scan.get(add[position]) or Candidate(add[position], "", 0, 0, 0, False, {}, {}, "")
        else:
            if not remaining or not remaining[0].significant:
                break
            pick = remaining[0]
        chosen.append(by_id[pick.effect])
        structural.append(pick.structural or by_id[pick.effect].structural_values())
        hybrid, step = add_effects(campaign, chosen, structural, data_model)
        steps.append(step)
        if add is None:
            # Search again with the chosen columns in the model.
            fixed = Design(
                np.concatenate([fitted_basis(e, search.touches, s)[0] for e, s in zip(chosen, structural)], axis=-1),
                search.smoother,
            )
            remaining = rank_candidates(search, effects, exclude=[c.id for c in chosen], fixed=fixed, progress=progress)

    return Diagnosis(
        # The touch noise once the modelled effects that change between repetitions are taken out.
        noise_floor_um=steps[-1].noise_floor_um,
        baseline_model=baseline_name,
        baseline_mae_um=baseline_mae,
        candidates=candidates,
        verdict=verdict,
        steps=steps,
        orientations=campaign.orientations,
        out_of_sample_mae_um=mae,
        out_of_sample_floor_um=floors,
        failing=failing,
        held_out=held_out,
        hybrid=hybrid,
    )


def _rounded(figures: dict[str, float]) -> dict[str, float | None]:
    """Figures for JSON: rounded, and null where a figure does not exist (one repetition has no floor)."""
    return {k: round(float(v), DIGITS) if np.isfinite(v) else None for k, v in figures.items()}


# -- the command ---------------------------------------------------------------------------------
def format_diagnosis(result: Diagnosis) -> str:
    """A plain-text report: where it fails, the ranked candidates, the verdict, the error history."""
    floor = result.noise_floor_um
    lines = [
        f"Noise floor (touch noise after the modelled effects): {floor['mean']:.3f} um against the repetition mean, "
        f"{floor['single']:.3f} um against single repetitions.",
        f"Baseline ({result.baseline_model}) on the {int(result.held_out.sum())} held-out rings: "
        f"MAE {result.baseline_mae_um['mean']:.3f} um (mean), {result.baseline_mae_um['single']:.3f} um (single).",
        "",
        f"Where it fails: {int(result.failing.sum())} of {len(result.failing)} orientations are worse than their "
        "noise floor by more than 4 standard errors (out of sample).",
    ]
    worst = np.argsort(-(result.out_of_sample_mae_um["mean"] / result.out_of_sample_floor_um["mean"]))[:5]
    for i in worst:
        if not result.failing[i]:
            continue
        a, b = result.orientations[i]
        kind = "held out" if result.held_out[i] else "leave-one-out"
        ratio = result.out_of_sample_mae_um["mean"][i] / result.out_of_sample_floor_um["mean"][i]
        lines.append(f"  A {a:g} B {b:g} ({kind}): MAE {result.out_of_sample_mae_um['mean'][i]:.3f} um, {ratio:.1f}x its floor")
    lines += ["", "Candidate effects (best first): share of the out-of-sample residual explained, fall of the held-out error"]
    width = max([len(c.effect) for c in result.candidates] + [6])
    for c in result.candidates:
        params = ", ".join(f"{k}={v:.3g}" for k, v in c.params.items()) if c.significant else ""
        flag = "*" if c.significant else " "
        if c.note:
            lines.append(f"   {c.effect.ljust(width)}  not tested: {c.note}")
            continue
        lines.append(
            f" {flag} {c.effect.ljust(width)}  explains {100 * c.explained_fraction:5.1f} %  (noise alone {100 * c.noise_fraction:5.2f} %)"
            f"  error -{100 * c.error_reduction:4.1f} %  {params}"
        )
    lines.append("")
    if result.verdict == "missing":
        best = result.candidates[0]
        lines += [f"Verdict: a missing effect: {best.effect} ({best.name}).", f"  {best.teaching}"]
    else:
        lines.append("Verdict: no missing effect found: no candidate explains more than noise would and lowers the held-out error materially.")
    lines += ["", "Error history on the held-out rings (MAE / um, and the noise floor):"]
    for step in result.steps:
        name = "baseline" if not step.added else "+ " + " + ".join(step.added)
        lines.append(
            f"  {name:40s} mean {step.mae_um['mean']:.3f} (floor {step.noise_floor_um['mean']:.3f})   "
            f"single {step.mae_um['single']:.3f} (floor {step.noise_floor_um['single']:.3f})"
        )
    return "\n".join(lines) + "\n"


def diagnose_command(
    data: Path,
    model: Path | None = None,
    add: str | None = None,
    effects: Path | None = None,
    json_output: bool = False,
    geometry: dict[str, float] | None = None,
    data_part: str = "trilinear",
) -> int:
    """`ph-explorer diagnose`: where the model fails, which effect is missing, add it, the error history."""
    from rich.progress import Progress

    from ph_explorer.effects import load_user_effects
    from ph_explorer.io import read_campaign

    if data_part not in ("trilinear", "network"):
        raise InputError(f"unknown data-driven part {data_part!r} (trilinear or network)", column="--data-part")
    campaign = read_campaign(Path(data), geometry or {})
    catalog = dict(CATALOG)
    if effects is not None:
        catalog.update({cls.id: cls for cls in load_user_effects(effects)})
    ids = [a.strip() for a in add.split(",") if a.strip()] if add else None
    baseline = None
    if model is not None:
        from ph_explorer.training import load_models

        if not Path(model).is_dir():
            raise InputError("model folder not found", file=str(model))
        trained = load_models(Path(model))
        baseline = trained.get("network") or next(iter(trained.values()))
    with Progress(transient=True, disable=json_output) as bar:
        task = bar.add_task("scanning candidate effects", total=None)
        data_model: str | Callable[[], DeviationModel] = data_part
        if data_part == "network":
            from ph_explorer.models.network import FourierNetwork

            def data_model() -> DeviationModel:
                # Retraining the network on what the physical terms leave: epochs, loss, validation MAE.
                network_task = bar.add_task("network on the residual", total=None)
                return FourierNetwork(
                    progress=lambda epoch, loss, mae, lr: bar.update(
                        network_task, description=f"network epoch {epoch}: loss {loss:.4f}, val MAE {mae:.4f} um"
                    )
                )

        result = diagnose(
            campaign,
            add=ids,
            baseline=baseline,
            data_model=data_model,
            catalog=catalog,
            progress=lambda effect_id: bar.update(task, description=f"scanning {effect_id}"),
        )
    if json_output:
        print(json.dumps(result.as_dict()))
    else:
        print(format_diagnosis(result), end="")
    return 0
