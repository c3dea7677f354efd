"""The paper's Tables 1-3 at held-out orientations, and the noise floor each figure must be read against.

For each held-out orientation: the range and the maximum |deviation| of the measured mean curve
and of each model's curve (Tables 1 and 2), and the mean absolute simulation error
eps_s = delta_model - delta_measured (Table 3) against two references: the mean of the
repetitions, and single repetitions (averaged over them).

Noise floor. A perfect model predicts the systematic curve exactly; what remains against a
reference is the reference's own touch noise, Gaussian with the campaign's pooled repetition
sigma (per touch, after the circle fit). For e ~ N(0, s^2), E|e| = sqrt(2/pi) s ~ 0.80 s. So no
model can beat, on average, 0.80 sigma against single repetitions, nor 0.80 sigma / sqrt(n)
against the mean of n repetitions.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign, orientation_match
from ph_explorer.errors import InputError
from ph_explorer.models.base import DeviationModel

# E|e| / sigma for a zero-mean Gaussian error e.
MEAN_ABS_PER_SIGMA = math.sqrt(2.0 / math.pi)
DIGITS = 5  # 0.01 nm: far below anything measured, keeps the JSON readable


def noise_floor(sigma_um: float, n_repetitions: int) -> dict[str, float]:
    """The lowest MAE (um) a perfect model can reach against the mean of n repetitions and a single one."""
    single = MEAN_ABS_PER_SIGMA * float(sigma_um)
    return {"mean": single / math.sqrt(max(int(n_repetitions), 1)), "single": single}


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
    measured_mean = measured.mean(axis=1)
    curves = {"measured": measured_mean}
    mae: dict[str, tuple[NDArray, NDArray]] = {}
    for name, model in models.items():
        predicted = model.predict(orientations, n_points=campaign.n_points)
        curves[name] = predicted
        mae[name] = (
            np.abs(predicted - measured_mean).mean(axis=1),
            np.abs(predicted[:, None, :] - measured).mean(axis=(1, 2)),
        )
    rows = []
    for i, (a, b) in enumerate(orientations):
        rows.append(
            {
                "A_deg": float(a),
                "B_deg": float(b),
                "range_um": {k: _r(np.ptp(c[i])) for k, c in curves.items()},
                "max_abs_um": {k: _r(np.abs(c[i]).max()) for k, c in curves.items()},
                "mae_um": {k: {"mean": _r(m[0][i]), "single": _r(m[1][i])} for k, m in mae.items()},
            }
        )
    return rows


def evaluation_report(
    campaign: Campaign, models: Mapping[str, DeviationModel], mask: ArrayLike | None = None
) -> dict[str, Any]:
    """The evaluate --json object: the noise floors and the per-orientation tables."""
    floor = noise_floor(campaign.noise_sigma_um(), campaign.n_repetitions)
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
        n: {ref: _r(np.mean([row["mae_um"][n][ref] for row in rows])) for ref in ("mean", "single")} for n in names
    }


def format_report(report: Mapping[str, Any]) -> str:
    """Aligned text tables: Table 1 (range), Table 2 (max |deviation|), Table 3 (MAE of eps_s)."""
    rows = report["orientations"]
    if not rows:
        return "no held-out orientation to evaluate"
    floor = report["noise_floor_um"]
    names = list(rows[0]["mae_um"].keys())
    label = [f"A {row['A_deg']:g} B {row['B_deg']:g}" for row in rows]
    out = []

    def table(title: str, header: list[str], cells: list[list[str]]) -> None:
        widths = [max(len(h), *(len(c[j]) for c in cells)) for j, h in enumerate(header)]
        line = lambda items: "  ".join(s.rjust(w) if j else s.ljust(w) for j, (s, w) in enumerate(zip(items, widths)))
        out.extend([title, line(header), "  ".join("-" * w for w in widths)])
        out.extend(line(c) for c in cells)
        out.append("")

    table(
        "Table 1. Range of the deviation curve / um (measured: mean of the repetitions)",
        ["orientation", "measured", *names],
        [[label[i], *(f"{row['range_um'][k]:.3f}" for k in ["measured", *names])] for i, row in enumerate(rows)],
    )
    table(
        "Table 2. Maximum |deviation| / um",
        ["orientation", "measured", *names],
        [[label[i], *(f"{row['max_abs_um'][k]:.3f}" for k in ["measured", *names])] for i, row in enumerate(rows)],
    )
    header = ["orientation"] + [f"{n} vs {ref}" for n in names for ref in ("mean", "single")]
    cells = [[label[i]] + [f"{row['mae_um'][n][ref]:.3f}" for n in names for ref in ("mean", "single")] for i, row in enumerate(rows)]
    average = mean_mae(report)
    cells.append(["average"] + [f"{average[n][ref]:.3f}" for n in names for ref in ("mean", "single")])
    cells.append(["noise floor"] + [_f(floor[ref]) for n in names for ref in ("mean", "single")])
    table("Table 3. Mean absolute simulation error eps_s = delta_model - delta_measured / um", header, cells)
    return "\n".join(out).rstrip() + "\n"


def holdout_from_card(campaign: Campaign, card: Mapping[str, Any]) -> NDArray[np.bool_]:
    """The card's held-out orientations present in the campaign; if none is, the campaign's own default."""
    held = np.asarray(card.get("holdout", []), dtype=float).reshape(-1, 2)
    if held.size:
        mask = orientation_match(campaign.orientations, held).any(axis=1)
        if mask.any():
            return mask
    return campaign.holdout_mask()


def evaluate_command(model: Path, data: Path, json_output: bool = False, geometry: dict[str, float] | None = None) -> int:
    """`ph-explorer evaluate`: Tables 1-3 at every held-out orientation, as text or one JSON object."""
    from ph_explorer.io import read_campaign
    from ph_explorer.training import load_card, load_models

    campaign = read_campaign(Path(data), geometry or {})
    models = load_models(Path(model))
    mask = holdout_from_card(campaign, load_card(Path(model)))
    if not mask.any():
        raise InputError(
            "no held-out orientation to evaluate: the model's holdout is not in the data and the data has "
            "no check orientations nor off-grid orientations",
            file=str(data),
        )
    report = evaluation_report(campaign, models, mask)
    if json_output:
        print(json.dumps(report))
    else:
        print(format_report(report), end="")
    return 0


def _f(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3f}"


def _r(x: float) -> float:
    return round(float(x), DIGITS)
