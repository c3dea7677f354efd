"""The paper's Tables 1-3 at held-out orientations, with the noise floor each figure is read against.

For each held-out orientation: the range and the maximum |deviation| of the measured mean curve
and of each model's curve (Tables 1 and 2), and the mean absolute simulation error
eps_s = delta_model - delta_measured (Table 3) against two references: the mean of the
repetitions, and single repetitions (averaged over them). The MAE and the noise floor come from
ph_explorer.metrics; cli/evaluate.py prints the tables.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer import metrics
from ph_explorer.campaign import Campaign, orientation_match
from ph_explorer.models.base import DeviationModel

DIGITS = 5  # 0.01 nm: far below anything measured, keeps the JSON readable


def orientation_tables(
    campaign: Campaign,
    models: Mapping[str, DeviationModel],
    mask: ArrayLike | None = None,
) -> list[dict[str, Any]]:
    """Tables 1-3 for each selected orientation (default: campaign.holdout_mask()).

    Returns one dict per orientation: {"A_deg", "B_deg", "range_um": {"measured", <model>...},
    "max_abs_um": {...}, "mae_um": {<model>: {"mean", "single"}}}, values in um.
    """
    selected = campaign.holdout_mask() if mask is None else np.asarray(mask)
    index = np.arange(campaign.n_orientations)[selected]
    orientations = campaign.orientations[index]
    measured = campaign.deviations[index]  # (m, n_rep, n_pt)
    curves = {"measured": measured.mean(axis=1)}
    mae: dict[str, dict[str, NDArray[np.float64]]] = {}
    for name, model in models.items():
        curves[name] = model.predict(orientations, n_points=campaign.n_points)
        mae[name] = metrics.ring_mae(curves[name], measured)
    return [
        {
            "A_deg": float(a),
            "B_deg": float(b),
            "range_um": {k: _r(np.ptp(c[i])) for k, c in curves.items()},
            "max_abs_um": {k: _r(np.abs(c[i]).max()) for k, c in curves.items()},
            "mae_um": {k: {ref: _r(m[ref][i]) for ref in metrics.REFERENCES} for k, m in mae.items()},
        }
        for i, (a, b) in enumerate(orientations)
    ]


def evaluation_report(
    campaign: Campaign, models: Mapping[str, DeviationModel], mask: ArrayLike | None = None
) -> dict[str, Any]:
    """The evaluate --json object: the noise floors and the per-orientation tables."""
    floor = metrics.noise_floor(campaign.noise_sigma_um(), campaign.n_repetitions)
    # A campaign of single repetitions has no measured noise: its floor is unknown (null).
    return {
        "noise_floor_um": {k: (_r(v) if math.isfinite(v) else None) for k, v in floor.items()},
        "orientations": orientation_tables(campaign, models, mask),
    }


def mean_mae(report: Mapping[str, Any]) -> dict[str, dict[str, float]]:
    """Each model's MAE averaged over the report's orientations, {model: {"mean", "single"}}."""
    rows = report["orientations"]
    if not rows:
        return {}
    names = rows[0]["mae_um"].keys()
    return {
        n: {ref: _r(np.mean([row["mae_um"][n][ref] for row in rows])) for ref in metrics.REFERENCES} for n in names
    }


def holdout_from_card(campaign: Campaign, card: Mapping[str, Any]) -> NDArray[np.bool_]:
    """The card's held-out orientations present in the campaign; if none is, the campaign's own default."""
    held = np.asarray(card.get("holdout", []), dtype=float).reshape(-1, 2)
    if held.size:
        mask = orientation_match(campaign.orientations, held).any(axis=1)
        if mask.any():
            return mask
    return campaign.holdout_mask()


def _r(x: float) -> float:
    return round(float(x), DIGITS)
