"""The paper's Tables 1-3 at held-out orientations, with the noise floor each figure is read against.

For each held-out orientation: the range and the maximum |deviation| of the measured mean curve
and of each model's curve (Tables 1 and 2), and the mean absolute prediction error (the paper's "simulation error")
eps_s = delta_model - delta_measured (Table 3) against two references: the mean of the
repetitions, and single repetitions (averaged over them). The MAE and the noise floor come from
ph_explorer.metrics; cli/evaluate_command.py prints the tables. `tables_at` gives them at one orientation
(measured or only predicted) and `tables_markdown` writes them as the explorer's Tables tab and a
report show them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer import metrics
from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.models.deviation_model import DeviationModel

DIGITS = 5  # 0.01 nm: far below anything measured, keeps the JSON readable
RONT_HEADER = "| um | RONt ± U (k = 2) |"


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


def tables_at(
    campaign: Campaign, models: Mapping[str, DeviationModel], index: int | None, curves: Mapping[str, NDArray[np.float64]]
) -> dict[str, Any]:
    """Tables 1-3 at one orientation: {"range_um", "max_abs_um", "mae_um"} as an orientation_tables
    row when it was measured (index in the campaign); else range and max |dev| of each predicted curve only."""
    if index is not None:
        mask = np.zeros(campaign.n_orientations, dtype=bool)
        mask[index] = True
        row = orientation_tables(campaign, models, mask)[0]
        return {"range_um": row["range_um"], "max_abs_um": row["max_abs_um"], "mae_um": row["mae_um"]}
    # Not measured: there is nothing to compare with.
    return {
        "range_um": {k: float(np.ptp(v)) for k, v in curves.items()},
        "max_abs_um": {k: float(np.abs(v).max()) for k, v in curves.items()},
        "mae_um": {},
    }


def _fmt(value: float | None) -> str:
    return "—" if value is None or (isinstance(value, float) and not np.isfinite(value)) else f"{value:.2f}"


def tables_markdown(
    tables: Mapping[str, Any],
    a_deg: float,
    b_deg: float,
    model_names: list[str],
    noise_floor_um: Mapping[str, float],
    measured: bool,
    held_out: bool,
    ront: Mapping[str, str] | None = None,
    ront_note: str = "",
) -> str:
    """Tables 1-3 at one orientation (a `tables_at` result) as markdown: what the ring is (a training
    ring, a check ring, or not measured), range and max |dev| per curve, each model's MAE and the floor.
    ront: a table under Table 1, one row per curve (curve -> cell text, e.g. the task's RONt +- U),
    with its note: one figure a row stays on one line in a narrow panel, beside the curve it is of."""
    t = tables
    names = ["measured", *model_names] if measured else list(model_names)
    heading = orientation_label(a_deg, b_deg)
    if not measured:
        heading += " — not measured: model **predictions** only"
    elif held_out:
        heading += " — measured, held out of training (check ring)"
    else:
        heading += " — measured, a training ring"
    lines = [f"**{heading}**", ""]
    header = "| um | " + " | ".join(names) + " |"
    rule = "|---|" + "---|" * len(names)
    lines += ["Table 1 — range, Table 2 — max |deviation|", "", header, rule]
    lines.append("| range | " + " | ".join(_fmt(t["range_um"].get(n)) for n in names) + " |")
    lines.append("| max abs | " + " | ".join(_fmt(t["max_abs_um"].get(n)) for n in names) + " |")
    if ront is not None:
        # Its own table, a curve a row: as a row of Table 1, "1.111 ± 0.327" per column ran together.
        lines += ["", RONT_HEADER, "|---|---|"] + [f"| {n} | {ront.get(n, '-')} |" for n in names]
        lines += ["", ront_note] if ront_note else []
    lines.append("")
    if t["mae_um"]:
        models = list(t["mae_um"])
        lines += [
            "Table 3 — mean absolute prediction error (the paper's simulation error)",
            "",
            "| um | " + " | ".join(models) + " |",
            "|---|" + "---|" * len(models),
        ]
        lines.append("| vs mean | " + " | ".join(_fmt(t["mae_um"][m]["mean"]) for m in models) + " |")
        lines.append("| vs single | " + " | ".join(_fmt(t["mae_um"][m]["single"]) for m in models) + " |")
        if noise_floor_um:
            floor = noise_floor_um
            lines += ["", f"Noise floor: {floor['mean']:.3f} um vs mean, {floor['single']:.3f} um vs single repetitions."]
        if not held_out:
            lines += ["", "_A training ring: the models saw it, so Table 3 here is in sample._"]
    else:
        lines.append("Table 3 needs a measurement at this orientation.")
    return "\n".join(lines)


def evaluation_report(campaign: Campaign, models: Mapping[str, DeviationModel], mask: ArrayLike | None = None) -> dict[str, Any]:
    """The evaluate --json object: the noise floors and the per-orientation tables."""
    floor = campaign.noise_floor_um()
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
    return {n: {ref: _r(np.mean([row["mae_um"][n][ref] for row in rows])) for ref in metrics.REFERENCES} for n in names}


def _r(x: float) -> float:
    return round(float(x), DIGITS)
