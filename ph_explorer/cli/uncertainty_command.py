"""`ph-explorer uncertainty`: each model's Monte Carlo band with every component, its budget and the
RONt of one measurement with U (k = 2), at any orientations (issue 17)."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ph_explorer.cli.train_command import parse_orientations
from ph_explorer.errors import InputError

A_RANGE, B_RANGE = (-115.0, 115.0), (-180.0, 180.0)  # the campaign files' ranges (docs/formats.md)


def checked_orientations(text: str) -> list[tuple[float, float]]:
    """--orientations 'A:B[,A:B...]', each inside the head's range."""
    pairs = parse_orientations(text, "--orientations")
    for a, b in pairs:
        if not (A_RANGE[0] <= a <= A_RANGE[1] and B_RANGE[0] <= b <= B_RANGE[1]):
            raise InputError(f"{a:g}:{b:g} is out of range (A in [-115, 115], B in [-180, 180] deg)", option="--orientations")
    return pairs


def uncertainty_report(model: Path, orientations: str, level: float = 0.95, seed: int | None = None, digits: int = 2) -> dict[str, Any]:
    """The JSON object of the command: {"level", "bands": [band per orientation and model]}; the
    Monte Carlo stops when its results are stable to `digits` significant digits (JCGM 101 7.9)."""
    pairs = checked_orientations(orientations)
    if not (math.isfinite(level) and 0.0 < level < 1.0):
        raise InputError(f"must be a probability in (0, 1), got {level:g}", option="--level")
    if digits not in (1, 2, 3):
        raise InputError(f"must be 1, 2 or 3 significant digits, got {digits}", option="--digits")
    # torch-bound: imported when the command runs.
    from ph_explorer.models.folder import load_models
    from ph_explorer.models.hybrid import SUBFOLDER, HybridModel
    from ph_explorer.uncertainty.bands import Sources, orientation_band
    from ph_explorer.uncertainty.model_error import FILE_NAME, load_errors
    from ph_explorer.uncertainty.task import task_uncertainty

    directory = Path(model)
    if not directory.is_dir():
        raise InputError("model folder not found", file=str(directory), option="--model")
    models = load_models(directory)  # one line when the folder holds no model
    if not (directory / FILE_NAME).is_file():
        raise InputError(
            f"the model folder has no {FILE_NAME} (each model's out-of-sample error): retrain it with ph-explorer train",
            file=str(directory),
            option="--model",
        )
    errors, repetitions = load_errors(directory, models)
    if (directory / SUBFOLDER / "hybrid.json").is_file() and "hybrid" in errors:
        models["hybrid"] = HybridModel.load(directory)
    rng = np.random.default_rng(seed)
    bands = []
    for a, b in pairs:
        for name, m in models.items():
            if name not in errors:
                continue
            sources = Sources(m, repetitions, errors[name])
            band = orientation_band(sources, (a, b), level, rng=rng, ndig=digits).as_dict()
            ront = task_uncertainty(sources, (a, b), level=level, rng=rng, ndig=digits)["ront_um"]
            bands.append({**band, "ront_um": {"value": ront["value"], "U": ront["U"]}})
    return {"level": level, "bands": bands}


def uncertainty_command(
    model: Path, orientations: str, level: float = 0.95, json_output: bool = False, seed: int | None = None, digits: int = 2
) -> int:
    report = uncertainty_report(model, orientations, level, seed, digits)  # every check before any output
    if json_output:
        print(json.dumps(report))
        return 0
    percent = f"{100 * report['level']:g} %"
    for band in report["bands"]:
        touch = 0.5 * np.mean(np.subtract(band["touch_upper_um"], band["touch_lower_um"]))
        mean = 0.5 * np.mean(np.subtract(band["mean_upper_um"], band["mean_lower_um"]))
        budget = ", ".join(f"{k} {v:.3f}" for k, v in band["budget_um"].items())
        print(
            f"A {band['A_deg']:g} B {band['B_deg']:g} {band['model']}: {percent} band half-width {touch:.3f} um (one touch), "
            f"{mean:.3f} um (mean of {band['mean_of_repetitions']}); budget um: {budget}; "
            f"RONt {band['ront_um']['value']:.3f} +- {band['ront_um']['U']:.3f} um (k = 2)"
        )
    return 0
