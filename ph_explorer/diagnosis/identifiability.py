"""What a campaign's design lets head touches see of each catalog effect, from the bases alone.

For every effect of a catalog (at its defaults and over its scan) and the campaign's touches: the
share the circle fit absorbs (absorbed_by_circle_fit), whether what it leaves can stand above the
noise at its largest plausible size (visible), the share the lattice interpolator already learns
out of sample (learnable_by_data_model), the effects it is confounded with (confounded_with), and
the rank of the stacked bases. Nothing is printed here.

Method: docs/methods/identifiability.md.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.blas import one_blas_thread
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.separation import CONFOUNDED, span_share
from ph_explorer.effects import Effect
from ph_explorer.kinematics import Touches, campaign_touches
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.models.hybrid import fitted_basis
from ph_explorer.models.least_squares import Design

# A share the circle fit leaves below this is the fit's rounding, not a term that survives it.
SURVIVES = 1e-6
# A combination of unit-rms columns whose sum of squares is below this is not in the span (rank).
RANK_TOL = 1e-10
# Bisection range for the plausible size, as multiples of the default coefficients.
SCALE_RANGE = (1e-9, 1e9)
VISIBLE_RULE = (
    "visible: the circle fit leaves more than 1e-6 of the term's sum of squares, and at its largest "
    "plausible size (or its default size when no range bounds it) its rms over one ring's touches "
    "reaches the noise of that ring's mean curve, sigma / sqrt(repetitions), at some ring: its sum of "
    "squares there then exceeds the noise's expected N sigma^2 / n by N, a chi-square excess of "
    "sqrt(N/2) standard deviations (5.7 for 64 points)"
)


def describe_effect(cls: type[Effect]) -> dict[str, Any]:
    """id, name, axis, kind, symbol, parameters (name, unit, plausible) and scan of an effect class."""
    return {
        "id": cls.id,
        "name": cls.name,
        "axis": cls.axis,
        "kind": cls.kind,
        "symbol": cls.symbol,
        "parameters": [
            {"name": p.name, "unit": p.unit, "plausible": list(p.plausible) if p.plausible is not None else None} for p in cls.parameters
        ],
        "scan": {name: [float(min(values)), float(max(values)), len(values)] for name, values in cls.scan.items()},
    }


@dataclass
class Bases:
    """One effect at one setting over a campaign's touches: its Gram matrices before the fit, after
    it and after the smoother, and an orthonormal basis of what the smoother leaves."""

    effect: Effect
    before: NDArray[np.float64]
    after: NDArray[np.float64]
    out_of_sample: NDArray[np.float64]
    fitted: NDArray[np.float64] | None  # (n_o, n_rep, n_pt, c) after the circle fit (dropped once judged)
    q_mean: NDArray[np.float64]  # (n_o * n_pt, k): sqrt(n_rep) * mean part, orthonormalised with ...
    q_within: NDArray[np.float64] | None  # ... (n_o * n_rep * n_pt, k) the part that changes between repetitions


def effect_bases(effect: Effect, touches: Touches, smoother: OutOfSampleSmoother) -> Bases:
    """The effect's bases over the touches (see Bases)."""
    raw, _ = effect.basis(touches)
    raw = np.broadcast_to(raw, touches.shape + raw.shape[3:])
    if not raw.shape[-1]:  # pure noise: nothing to fit
        empty = np.zeros((0, 0))
        return Bases(effect, empty, empty, empty, None, np.zeros((touches.shape[0] * touches.shape[2], 0)), None)
    fitted, _ = fitted_basis(effect, touches)
    after = Design(fitted, None)
    oos = Design(fitted, smoother)
    q_mean, q_within = orthonormal(oos, after)
    return Bases(effect, Design(raw, None).gram(), after.gram(), oos.gram(), fitted, q_mean, q_within)


def orthonormal(design: Design, reference: Design) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """An orthonormal basis of design's columns over single touches (as separation.shared_variance
    builds it), split into its mean and within rows; directions that keep less than SURVIVES of
    their size in `reference` (what the smoother reproduces exactly) are dropped."""
    mean, within = design.touch_blocks()
    rows = mean if within is None else np.concatenate([mean, within])
    u, singular, vt = np.linalg.svd(rows, full_matrices=False)
    if not singular.size:
        return u[: mean.shape[0]], None
    # What the direction v had before the smoother: v^T G_ref v, against what it keeps, s^2.
    kept_before = np.einsum("kc,cd,kd->k", vt, reference.gram(), vt)
    keep = singular**2 > SURVIVES * np.maximum(kept_before, 1e-300)
    u = u[:, keep]
    return u[: mean.shape[0]], (u[mean.shape[0] :] if within is not None else None)


def plausible_scale(effect: Effect, coef: NDArray[np.float64]) -> float | None:
    """The largest multiple of coef whose parameters (from_coefficients) every declared plausible
    range admits; None when no range bounds it."""
    low, high = SCALE_RANGE
    if not effect.implausible(effect.from_coefficients(high * coef)):
        return None
    for _ in range(80):  # geometric bisection: magnitudes grow with the scale
        middle = np.sqrt(low * high)
        low, high = (middle, high) if not effect.implausible(effect.from_coefficients(middle * coef)) else (low, middle)
    return float(low)


def judged_combination(bases: Bases) -> tuple[NDArray[np.float64], float, float | None]:
    """The combination of the effect's columns that the circle fit removes least, the share of its
    sum of squares that survives the fit, and the multiple of it that is the largest plausible size.

    The combination is sized like the effect's default term (basis @ coefficients(), the effect as
    its author sized it) before the fit, and the plausible multiple is that of the default term
    (plausible_scale); an effect whose default term is zero is sized by its own coefficients. A
    default phase is arbitrary, so the effect is judged at the phase (or mix of columns) that shows
    best: a 1/rev A-axis error in sin A is exactly one-fold, in cos A it is not.
    """
    values, vectors = np.linalg.eigh(bases.before)
    keep = values > 1e-12 * max(values.max(initial=0.0), 1e-300)
    if not keep.any():
        return np.zeros(bases.before.shape[0]), 0.0, None
    whiten = vectors[:, keep] / np.sqrt(values[keep])
    survival, directions = np.linalg.eigh(whiten.T @ bases.after @ whiten)
    best = whiten @ directions[:, -1]  # unit sum of squares before the fit
    default = np.asarray(bases.effect.coefficients(), dtype=float)
    size = float(default @ bases.before @ default) if default.size else 0.0
    if size > 0.0:
        return best * np.sqrt(size), float(survival[-1]), plausible_scale(bases.effect, default)
    best = best / max(float(np.linalg.norm(best)), 1e-300)
    return best, float(survival[-1]), plausible_scale(bases.effect, best)


def figures(bases: Bases, noise_floor_um: float | None) -> dict[str, Any]:
    """absorbed_by_circle_fit, learnable_by_data_model, visible and its rms for one effect at one setting."""
    coef, survives_share, scale = judged_combination(bases)
    after = float(coef @ bases.after @ coef)
    if not coef.any():
        return {"absorbed_by_circle_fit": None, "learnable_by_data_model": None, "visible": None, "visible_rms_um": None, "magnitude": None}
    survives = survives_share > SURVIVES
    # The smoother may add error where it interpolates badly (a term that changes faster than the
    # lattice): the share it reproduces is then 0, not negative.
    learnable = float(np.clip(1.0 - float(coef @ bases.out_of_sample @ coef) / after, 0.0, 1.0)) if survives else None
    term = bases.fitted @ (coef * (1.0 if scale is None else scale))
    rms = float(np.sqrt((term**2).mean(axis=(1, 2))).max()) if survives else 0.0
    visible = None if noise_floor_um is None else bool(survives and rms >= noise_floor_um)
    return {
        "absorbed_by_circle_fit": round(float(np.clip(1.0 - survives_share, 0.0, 1.0)), 6),
        "learnable_by_data_model": None if learnable is None else round(learnable, 6),
        "visible": visible,
        "visible_rms_um": round(rms, 6),
        "magnitude": "default" if scale is None else "plausible",
    }


def shared_between(a: Bases, b: Bases) -> float:
    """separation.shared_variance of two effects' designs through the smoother, from their orthonormal
    bases (the same number; computed once per basis so that every pair of two scans is affordable)."""
    return span_share((a.q_mean, a.q_within), (b.q_mean, b.q_within))


def stacked_rank(gram: NDArray[np.float64], size: NDArray[np.float64]) -> int:
    """Numerical rank of side-by-side columns from their Gram matrix, each column scaled by 1/size
    (columns of size 0 left out)."""
    keep = size > 0
    if not keep.any():
        return 0
    d = 1.0 / size[keep]
    values = np.linalg.eigvalsh(gram[np.ix_(keep, keep)] * d[:, None] * d[None, :])
    return int((values > RANK_TOL).sum())


def design_ranks(defaults: list[Bases], touches: Touches, smoother: OutOfSampleSmoother) -> dict[str, int]:
    """Columns and rank of every effect's basis at its default settings, stacked: after the circle
    fit, and after the smoother too (what the diagnosis can still fit)."""
    fitted = [b.fitted for b in defaults if b.fitted is not None and b.fitted.shape[-1]]
    if not fitted:
        return {"columns": 0, "rank_after_fit": 0, "rank_out_of_sample": 0}
    columns = np.concatenate(fitted, axis=-1)
    after = Design(columns, None).gram()
    size = np.sqrt(np.diag(after))  # unit after-fit size: a column the smoother reproduces drops out
    oos = Design(columns, smoother).gram()
    return {
        "columns": int(columns.shape[-1]),
        "rank_after_fit": stacked_rank(after, size),
        "rank_out_of_sample": stacked_rank(oos, size),
    }


@one_blas_thread
def identifiability(campaign: Campaign, effects: Iterable[type[Effect]], train: NDArray[np.bool_] | None = None) -> dict[str, Any]:
    """{"effects": [...], "design": {...}} for the campaign's design (docs/methods/identifiability.md).

    train: the rings the data model learns from (default: all but campaign.holdout_mask()).
    """
    classes = list(effects)
    train = ~campaign.holdout_mask() if train is None else np.asarray(train, dtype=bool)
    touches = campaign_touches(campaign)
    smoother = OutOfSampleSmoother(campaign.orientations, train)
    sigma = campaign.noise_sigma_um()
    floor = float(sigma / np.sqrt(campaign.n_repetitions)) if np.isfinite(sigma) and sigma > 0 else None

    rows: list[dict[str, Any]] = []
    instances: dict[str, list[Bases]] = {}
    defaults: list[Bases] = []
    for cls in classes:
        row = describe_effect(cls)
        effect = cls()
        row["evaluated_at"] = effect.settings()
        unmet = effect.unmet_needs(touches)
        own = None if unmet else effect_bases(effect, touches, smoother)
        if own is None or not own.before.shape[0]:
            row.update(
                columns=0,
                rank_after_fit=None,
                absorbed_by_circle_fit=None,
                learnable_by_data_model=None,
                visible=None,
                visible_rms_um=None,
                magnitude=None,
                confounded_with=[],
                over_scan=None,
                note="; ".join(unmet) if unmet else "no basis columns: nothing a model can fit",
            )
            rows.append(row)
            continue
        defaults.append(own)
        row.update(columns=own.before.shape[0], rank_after_fit=stacked_rank(own.after, np.sqrt(np.diag(own.before))))
        row.update(figures(own, floor))
        scanned, judged = [own], [figures(own, floor)]
        for settings in cls.scan_grid():
            if settings != effect.settings():
                other = effect_bases(effect.with_settings(**settings), touches, smoother)
                judged.append(figures(other, floor))
                other.fitted = None  # judged: only its orthonormal basis is kept, for confounding
                scanned.append(other)
        instances[cls.id] = scanned
        row["over_scan"] = scan_range(judged) if cls.scan else None
        row["note"] = ""
        rows.append(row)

    shared = pair_sharing(instances)
    for row in rows:
        if row["id"] in instances:
            row["confounded_with"] = confounded(row["id"], shared)
    design = {
        "rings": campaign.n_orientations,
        "held_out_rings": int((~train).sum()),
        "repetitions": campaign.n_repetitions,
        "points": campaign.n_points,
        "noise_sigma_um": round(float(sigma), 6) if floor is not None else None,
        "noise_floor_um": None if floor is None else round(floor, 6),
        "visible_rule": VISIBLE_RULE,
        "evaluated_at": "each effect's default settings; over_scan gives the range over its scan",
        "confounding": f"largest squared canonical correlation through the out-of-sample smoother, over both scans, above {CONFOUNDED}",
        **design_ranks(defaults, touches, smoother),
    }
    return {"effects": rows, "design": design}


def scan_range(scanned: list[dict[str, Any]]) -> dict[str, Any]:
    """How many settings of a scan are visible, and the range of the shares over them."""

    def span(key: str) -> list[float] | None:
        values = [f[key] for f in scanned if f[key] is not None]
        return [min(values), max(values)] if values else None

    return {
        "settings": len(scanned),
        "visible": sum(1 for f in scanned if f["visible"]),
        "absorbed_by_circle_fit": span("absorbed_by_circle_fit"),
        "learnable_by_data_model": span("learnable_by_data_model"),
    }


Sharing = dict[tuple[str, str], tuple[float, dict[str, float], dict[str, float]]]


def pair_sharing(instances: Mapping[str, list[Bases]]) -> Sharing:
    """For every ordered pair of effects, the most they share over both scans, with the settings."""
    out: Sharing = {}
    ids = list(instances)
    for i, a in enumerate(ids):
        for b in ids[i + 1 :]:
            best: tuple[float, dict[str, float], dict[str, float]] = (0.0, {}, {})
            for mine in instances[a]:
                for theirs in instances[b]:
                    shared = shared_between(mine, theirs)
                    if shared > best[0]:
                        best = (shared, mine.effect.settings(), theirs.effect.settings())
            out[(a, b)] = best
            out[(b, a)] = (best[0], best[2], best[1])
    return out


def confounded(effect_id: str, sharing: Sharing) -> list[dict[str, Any]]:
    """The other effects that share more than CONFOUNDED with this one at some pair of their settings."""
    out = [
        {"effect": other, "shared": round(shared, 3), "settings": mine, "other_settings": theirs}
        for (one, other), (shared, mine, theirs) in sharing.items()
        if one == effect_id and shared > CONFOUNDED
    ]
    return sorted(out, key=lambda item: item["shared"], reverse=True)
