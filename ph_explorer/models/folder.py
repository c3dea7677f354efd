"""A model folder: the trained models' files and their card, written atomically, read back by name.

A folder written by `ph-explorer train` holds network.safetensors, trilinear.npz, card.json
(the data's sha256, the holdout, hyperparameters, epochs, training times, geometry and the
evaluation at the holdout) and uncertainty.npz (each model's out-of-sample error, models.model_error). Writing goes to a temporary folder beside DIR, which then replaces
DIR: an interrupted training leaves an existing DIR as it was.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.evaluation import holdout_from_card
from ph_explorer.models import network, trilinear
from ph_explorer.models.base import DeviationModel
from ph_explorer.models.model_error import OutOfSampleError, save_errors

CARD_NAME = "card.json"
CARD_FORMAT = 1

# name -> (class, file); a folder holds the models whose files are present.
MODEL_TYPES: dict[str, tuple[type[DeviationModel], str]] = {
    "network": (network.FourierNetwork, network.FILE_NAME),
    "trilinear": (trilinear.TrilinearModel, trilinear.FILE_NAME),
    "mean_curve": (trilinear.MeanCurveModel, trilinear.MeanCurveModel.file_name),  # a hybrid's data part
}


def save_models(
    models: Mapping[str, DeviationModel],
    out: Path,
    card: dict[str, Any],
    errors: Mapping[str, OutOfSampleError] | None = None,
) -> Path:
    """Write the models, the card and (if given) the models' out-of-sample errors into out, atomically
    (temp folder beside out, then a rename)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    try:
        for model in models.values():
            model.save(tmp)
        if errors:
            save_errors(errors, tmp, int(card["data"]["n_repetitions"]))
        (tmp / CARD_NAME).write_text(json.dumps(card, indent=2) + "\n", encoding="utf-8")
        os.chmod(tmp, 0o755)  # mkdtemp's 0700 and safetensors' 0600 would hide a shipped model
        for path in tmp.iterdir():
            os.chmod(path, 0o644)
        if out.exists():
            # Directories cannot be replaced in one rename: move the old one aside first, so a
            # crash between the two renames leaves it recoverable beside DIR.
            old = out.parent / f".{out.name}.old-{os.getpid()}"
            os.replace(out, old)
            os.replace(tmp, out)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, out)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return out


def load_card(directory: Path) -> dict[str, Any]:
    """The card.json of a model folder; InputError when there is none or it is unreadable."""
    path = Path(directory) / CARD_NAME
    if not path.is_file():
        raise InputError("not a model folder (no card.json)", file=str(directory))
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"unreadable model card: {error}", file=str(path)) from None


def baseline_of(models: Mapping[str, DeviationModel]) -> DeviationModel | None:
    """The model a diagnosis starts from: the first of MODEL_TYPES (the network, then the
    trilinear tables) among these models; the CLI and the app take the same one."""
    return next((models[name] for name in MODEL_TYPES if name in models), None)


def load_models(directory: Path) -> dict[str, DeviationModel]:
    """The models of a folder written by train (name -> model), in MODEL_TYPES order."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError("model folder not found", file=str(directory))
    models = {}
    for name, (cls, file_name) in MODEL_TYPES.items():
        if (directory / file_name).is_file():
            try:
                models[name] = cls.load(directory)
            except Exception as error:  # a damaged or foreign file: one line, not a traceback
                raise InputError(f"cannot load the {name} model: {error}", file=str(directory / file_name)) from None
    if not models:
        raise InputError("the model folder holds no model file", file=str(directory))
    return models


def campaign_models(
    campaign: Campaign, model_dir: Path | None
) -> tuple[dict[str, DeviationModel], NDArray[np.bool_], list[str]]:
    """The models to show a campaign with, its training rings, and notes saying where they came from.

    The models of model_dir when given, with the card's held-out rings (what the models never saw),
    else the campaign's own check orientations; the trilinear tables are fitted now on the training
    rings when the folder has none (or there is no folder).
    """
    notes: list[str] = []
    models: dict[str, DeviationModel] = {}
    train = ~campaign.holdout_mask()
    if model_dir is not None:
        models = dict(load_models(Path(model_dir)))
        train = ~np.asarray(holdout_from_card(campaign, load_card(Path(model_dir))), dtype=bool)
        notes.append(f"models from {model_dir}")
    if "trilinear" not in models and train.any():
        models["trilinear"] = trilinear.TrilinearModel().fit(campaign, train)
        notes.append("trilinear tables fitted on the training rings")
    if "network" not in models:
        notes.append("no trained network for this campaign (ph-explorer train makes one)")
    return models, train, notes
