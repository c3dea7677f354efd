"""`ph-explorer evaluate`: the paper's Tables 1-3 at every held-out orientation, as text or one JSON object."""

from __future__ import annotations

import json
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ph_explorer.errors import InputError
from ph_explorer.models.lattice_need import read_lattice_campaign
from ph_explorer.paper.tables import evaluation_report, mean_mae


def evaluate_command(
    model: Path, data: Path, json_output: bool = False, geometry: dict[str, float] | None = None, strict: bool = False
) -> int:
    """Evaluate the models of a folder on a campaign, at the card's holdout (else the campaign's own);
    a model trained on another file is said in one line on stderr (an error with strict)."""
    # The models' classes import torch: only when the command runs (inspect must work without it).
    from ph_explorer.models.folder import holdout_from_card, load_card, load_models, other_training_data

    campaign = read_lattice_campaign(data, geometry)
    card = load_card(Path(model))
    other = other_training_data(card, Path(data))
    if other is not None and strict:
        raise InputError(other, file=str(model), option="--strict")
    if other is not None:
        print(f"ph-explorer evaluate: warning: {other}", file=sys.stderr)
    models = load_models(Path(model))
    mask = holdout_from_card(campaign, card)
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


def format_report(report: Mapping[str, Any]) -> str:
    """Aligned text tables: Table 1 (range), Table 2 (max |deviation|), Table 3 (MAE of eps_s)."""
    rows = report["orientations"]
    if not rows:
        return "no held-out orientation to evaluate"
    floor = report["noise_floor_um"]
    names = list(rows[0]["mae_um"].keys())
    label = [f"A {row['A_deg']:g} B {row['B_deg']:g}" for row in rows]
    shown = ["measured", *names]
    references = ("mean", "single")
    out: list[str] = []

    def table(title: str, header: list[str], cells: list[list[str]]) -> None:
        widths = [max(len(h), *(len(c[j]) for c in cells)) for j, h in enumerate(header)]

        def line(items: list[str]) -> str:
            return "  ".join(s.rjust(w) if j else s.ljust(w) for j, (s, w) in enumerate(zip(items, widths)))

        out.extend([title, line(header), "  ".join("-" * w for w in widths)])
        out.extend(line(c) for c in cells)
        out.append("")

    table(
        "Table 1. Range of the deviation curve / um (measured: mean of the repetitions)",
        ["orientation", *shown],
        [[label[i], *(f"{row['range_um'][k]:.3f}" for k in shown)] for i, row in enumerate(rows)],
    )
    table(
        "Table 2. Maximum |deviation| / um",
        ["orientation", *shown],
        [[label[i], *(f"{row['max_abs_um'][k]:.3f}" for k in shown)] for i, row in enumerate(rows)],
    )
    header = ["orientation"] + [f"{n} vs {ref}" for n in names for ref in references]
    cells = [[label[i]] + [f"{row['mae_um'][n][ref]:.3f}" for n in names for ref in references] for i, row in enumerate(rows)]
    average = mean_mae(report)
    cells.append(["average"] + [f"{average[n][ref]:.3f}" for n in names for ref in references])
    cells.append(["noise floor"] + [_figure(floor[ref]) for n in names for ref in references])
    table("Table 3. Mean absolute prediction error (the paper's simulation error) eps_s = delta_model - delta_measured / um", header, cells)
    return "\n".join(out).rstrip() + "\n"


def _figure(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.3f}"
