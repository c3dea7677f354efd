"""Training: fit the paper's network and the trilinear + Monte Carlo model, and write their card.

`train_models` fits both on the training orientations; `build_card` records provenance,
hyperparameters, the training record and the evaluation at the holdout; `save_models` writes the
folder atomically (models/folder.py reads it back); cli/train_command.py is the command (options, progress bar, printing).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from collections.abc import Mapping
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.io.files import file_sha256
from ph_explorer.models import network as network_module
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.folder import CARD_FORMAT, CARD_NAME, load_models, model_class
from ph_explorer.models.network import FourierNetwork, NetworkConfig, ProgressCallback
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.paper.tables import evaluation_report, mean_mae
from ph_explorer.uncertainty.bands import calibrated_model_error
from ph_explorer.uncertainty.model_error import OutOfSampleError, save_errors


def train_models(
    campaign: Campaign,
    train: NDArray[np.bool_],
    seed: int = 0,
    progress: ProgressCallback | None = None,
    network_config: NetworkConfig | None = None,
    data_parts: tuple[str, ...] = (),
) -> tuple[dict[str, DeviationModel], dict[str, float]]:
    """Fit both models on the training orientations, and the data parts asked for beside them (gp:
    the Gaussian process); return them and their training times (s)."""
    config = network_config or NetworkConfig()
    config = NetworkConfig.from_dict({**config.as_dict(), "seed": seed})
    seconds = {}
    start = time.perf_counter()
    trilinear = TrilinearModel().fit(campaign, train)
    seconds["trilinear"] = time.perf_counter() - start
    start = time.perf_counter()
    network = FourierNetwork(config, progress=progress).fit(campaign, train)
    seconds["network"] = time.perf_counter() - start
    models: dict[str, DeviationModel] = {"network": network, "trilinear": trilinear}
    for name in data_parts:
        start = time.perf_counter()
        models[name] = model_class(name)().fit(campaign, train)
        seconds[name] = time.perf_counter() - start
    return models, seconds


def model_errors(
    campaign: Campaign,
    train: NDArray[np.bool_],
    models: Mapping[str, DeviationModel],
    seed: int = 0,
    network_config: NetworkConfig | None = None,
) -> dict[str, OutOfSampleError]:
    """Each model's own error out of sample (models.model_error: the cross-validation of the training
    rings in folds and along A), for the model uncertainty of its Monte Carlo bands; the network is
    retrained per group left out.
    Its size is calibrated on the rings left out of training (bands.calibrate_model_error), with
    `models` fitted on `train`; with none left out it stays the cross-validation's."""
    config = NetworkConfig.from_dict({**(network_config or NetworkConfig()).as_dict(), "seed": seed})
    makers = {"network": partial(FourierNetwork, config), "trilinear": TrilinearModel}
    makers |= {name: model_class(name) for name in models if name not in makers}  # a GP's error is its posterior's
    return {name: calibrated_model_error(make, models[name], campaign, train) for name, make in makers.items()}


def as_saved(models: Mapping[str, DeviationModel]) -> dict[str, DeviationModel]:
    """The models as their files give them back: exactly what evaluate will load."""
    with tempfile.TemporaryDirectory() as scratch:
        for model in models.values():
            model.save(scratch)
        return load_models(Path(scratch))


def build_card(
    campaign: Campaign,
    data: Path | None,
    holdout: NDArray[np.bool_],
    source: str,
    seed: int,
    models: Mapping[str, DeviationModel],
    seconds: Mapping[str, float],
) -> dict[str, Any]:
    """The model card: provenance, hyperparameters, training record and the evaluation at the holdout.

    source says where the holdout came from ("option", "sidecar check orientations", ...). The
    evaluation is of the models as re-read from their files, so that evaluate reproduces the
    card's figures exactly.
    """
    network = models["network"]
    trilinear = models["trilinear"]
    assert isinstance(network, FourierNetwork) and isinstance(trilinear, TrilinearModel)
    report = evaluation_report(campaign, as_saved(models), holdout)
    return {
        "format": CARD_FORMAT,
        "data": {
            "file": None if data is None else Path(data).name,
            "sha256": None if data is None else file_sha256(Path(data)),
            "n_orientations": campaign.n_orientations,
            "n_repetitions": campaign.n_repetitions,
            "n_points": campaign.n_points,
            "scenario": campaign.scenario.get("name") if campaign.scenario else None,
        },
        "geometry": campaign.geometry.as_dict(),
        "holdout": campaign.orientations[holdout].tolist(),
        "holdout_source": source,
        "seed": seed,
        "training_seconds": {**{k: round(v, 2) for k, v in seconds.items()}, "total": round(sum(seconds.values()), 2)},
        "torch_threads": network_module.MAX_THREADS,
        "network": {
            "K": network.config.k_max,
            "hyperparameters": network.config.as_dict(),
            "epochs": network.log.epochs,
            "best_epoch": network.log.best_epoch,
            "validation_orientations": network.log.validation_orientations,
            "diagnostics_um": network.log.diagnostics,
            "sigma_um": network.sigma_um,
        },
        "trilinear": {
            "a_axis_deg": trilinear.a_axis.tolist(),
            "b_axis_deg": trilinear.b_axis.tolist(),
            "filled_nodes": int((~trilinear.measured).sum()),
        },
        **({"gp": {"kernel": str(models["gp"].regressor_.kernel_)}} if "gp" in models else {}),  # type: ignore[attr-defined]
        "metrics": {**report, "average_mae_um": mean_mae(report)},
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
