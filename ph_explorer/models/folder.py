"""A model folder read back by name: the trained models' files and their card.

A folder written by `ph-explorer train` (paper.training.save_models, atomically) holds
network.safetensors, trilinear.npz, card.json (the data's sha256, the holdout, hyperparameters,
epochs, training times, geometry and the evaluation at the holdout) and uncertainty.npz (each
model's out-of-sample error, uncertainty.model_error). Format: docs/formats.md.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign, orientation_match
from ph_explorer.errors import InputError
from ph_explorer.io.files import file_sha256
from ph_explorer.models import trilinear
from ph_explorer.models.deviation_model import DeviationModel

CARD_NAME = "card.json"
CARD_FORMAT = 1

# name -> (module, class, file); a folder holds the models whose files are present. A module is
# imported only when its model is used: the network's torch takes seconds to import.
MODEL_TYPES: dict[str, tuple[str, str, str]] = {
    "network": ("ph_explorer.models.network", "FourierNetwork", "network.safetensors"),
    "trilinear": ("ph_explorer.models.trilinear", "TrilinearModel", trilinear.FILE_NAME),
    "mean_curve": ("ph_explorer.models.trilinear", "MeanCurveModel", trilinear.MeanCurveModel.file_name),  # a hybrid's data part
    "gp": ("ph_explorer.models.gaussian_process", "GaussianProcessModel", "gp.npz"),  # scikit-learn's
}


def model_class(name: str) -> type[DeviationModel]:
    """The class of a model type of MODEL_TYPES, its module imported now."""
    module, cls, _ = MODEL_TYPES[name]
    return getattr(importlib.import_module(module), cls)


def holdout_from_card(campaign: Campaign, card: Mapping[str, Any]) -> NDArray[np.bool_]:
    """The card's held-out orientations present in the campaign; if none is, the campaign's own default."""
    held = np.asarray(card.get("holdout", []), dtype=float).reshape(-1, 2)
    if held.size:
        mask = orientation_match(campaign.orientations, held).any(axis=1)
        if mask.any():
            return mask
    return campaign.holdout_mask()


def load_card(directory: Path) -> dict[str, Any]:
    """The card.json of a model folder; InputError when there is none or it is unreadable."""
    path = Path(directory) / CARD_NAME
    if not path.is_file():
        raise InputError("not a model folder (no card.json)", file=str(directory))
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"unreadable model card: {error}", file=str(path)) from None


def other_training_data(card: Mapping[str, Any], data: Path) -> str | None:
    """A line when the models were trained on another file than `data` (the card's sha256 differs
    from the file's), naming both; None when it is the same file or the card records none."""
    trained = card.get("data") or {}
    if not trained.get("sha256") or not Path(data).is_file():
        return None
    sha256 = file_sha256(Path(data))
    if sha256 == trained["sha256"]:
        return None
    return (
        f"the model was trained on {trained.get('file', 'another file')} (sha256 {trained['sha256'][:12]}), "
        f"not on {Path(data).name} (sha256 {sha256[:12]}): its figures here are a prediction for another campaign"
    )


def baseline_of(models: Mapping[str, DeviationModel]) -> DeviationModel | None:
    """The model a diagnosis starts from: the first of MODEL_TYPES (the network, then the
    trilinear tables) among these models; the CLI and the app take the same one."""
    return next((models[name] for name in MODEL_TYPES if name in models), None)


def check_model_folder(directory: Path) -> Path:
    """The folder, or one line when there is none (before anything is loaded from it)."""
    directory = Path(directory)
    if not directory.is_dir():
        raise InputError("model folder not found", file=str(directory))
    return directory


def load_models(directory: Path) -> dict[str, DeviationModel]:
    """The models of a folder written by train (name -> model), in MODEL_TYPES order."""
    directory = check_model_folder(directory)
    models = {}
    for name, (_, _, file_name) in MODEL_TYPES.items():
        if (directory / file_name).is_file():
            try:
                models[name] = model_class(name).load(directory)
            except Exception as error:  # a damaged or foreign file: one line, not a traceback
                raise InputError(f"cannot load the {name} model: {error}", file=str(directory / file_name)) from None
    if not models:
        raise InputError("the model folder holds no model file", file=str(directory))
    return models


def campaign_models(
    campaign: Campaign, model_dir: Path | None, loaded: Mapping[str, DeviationModel] | None = None
) -> tuple[dict[str, DeviationModel], NDArray[np.bool_], list[str]]:
    """The models to show a campaign with, its training rings, and notes saying where they came from
    (loaded: model_dir's models when the caller has loaded them already).

    The models of model_dir when given, with the card's held-out rings (what the models never saw),
    else the campaign's own check orientations; the trilinear tables are fitted now on the training
    rings when the folder has none (or there is no folder).
    """
    notes: list[str] = []
    models: dict[str, DeviationModel] = {}
    train = ~campaign.holdout_mask()
    if model_dir is not None:
        models = dict(loaded if loaded is not None else load_models(Path(model_dir)))
        card = load_card(Path(model_dir))
        train = ~np.asarray(holdout_from_card(campaign, card), dtype=bool)
        notes.append(f"models from {model_dir}")
        other = other_training_data(card, Path(campaign.source)) if campaign.source else None
        if other is not None:
            notes.append(f"warning: {other}")
    if "trilinear" not in models and train.any():
        models["trilinear"] = trilinear.TrilinearModel().fit(campaign, train)
        notes.append("trilinear tables fitted on the training rings")
    if "network" not in models:
        notes.append("no trained network for this campaign (ph-explorer train makes one)")
    return models, train, notes
