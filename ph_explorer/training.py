"""`ph-explorer train`: fit the paper's network and the trilinear + Monte Carlo model, write a model folder.

The folder holds network.safetensors, trilinear.npz and card.json (the data's sha256, the
holdout, hyperparameters, epochs, training times, geometry and the evaluation at the holdout).
It is written atomically: everything goes to a temporary folder beside DIR, which then replaces
DIR; an interrupted training leaves an existing DIR as it was.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign, orientation_match
from ph_explorer.errors import InputError
from ph_explorer.evaluation import evaluation_report, mean_mae
from ph_explorer.models import network as network_module
from ph_explorer.models.base import DeviationModel
from ph_explorer.models.network import FourierNetwork, NetworkConfig, ProgressCallback
from ph_explorer.models.trilinear import TrilinearModel

CARD_NAME = "card.json"
CARD_FORMAT = 1

# name -> (class, file); a folder holds the models whose files are present.
MODEL_TYPES: dict[str, tuple[type[DeviationModel], str]] = {
    "network": (FourierNetwork, "network.safetensors"),
    "trilinear": (TrilinearModel, "trilinear.npz"),
}


# -- holdout ---------------------------------------------------------------------------------------
def parse_holdout(text: str, campaign: Campaign) -> NDArray[np.bool_]:
    """The mask of the orientations named by 'A:B,A:B' (each must be in the campaign)."""
    pairs = []
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        parts = item.split(":")
        try:
            if len(parts) != 2:
                raise ValueError
            a, b = float(parts[0]), float(parts[1])
            if not (np.isfinite(a) and np.isfinite(b)):
                raise ValueError
        except ValueError:
            raise InputError(f"--holdout: {item!r} is not an orientation A:B in degrees (e.g. 43:91)") from None
        pairs.append((a, b))
    if not pairs:
        raise InputError("--holdout names no orientation (expected 'A:B,A:B', e.g. 15:-20,43:91)")
    match = orientation_match(campaign.orientations, np.array(pairs))
    missing = [f"{a:g}:{b:g}" for (a, b), hit in zip(pairs, match.any(axis=0)) if not hit]
    if missing:
        raise InputError(f"--holdout: orientation(s) {', '.join(missing)} not in the campaign", file=campaign.source)
    return match.any(axis=1)


def holdout_source(campaign: Campaign, option: str | None) -> str:
    if option:
        return "option"
    if campaign.check_orientations is not None and len(campaign.check_orientations):
        return "sidecar check orientations"
    return "off-grid orientations"


# -- training --------------------------------------------------------------------------------------
def train_models(
    campaign: Campaign,
    train: NDArray[np.bool_],
    seed: int = 0,
    progress: ProgressCallback | None = None,
    network_config: NetworkConfig | None = None,
) -> tuple[dict[str, DeviationModel], dict[str, float]]:
    """Fit both models on the training orientations; return them and their training times (s)."""
    config = network_config or NetworkConfig()
    config = NetworkConfig.from_dict({**config.as_dict(), "seed": seed})
    seconds = {}
    start = time.perf_counter()
    trilinear = TrilinearModel().fit(campaign, train)
    seconds["trilinear"] = time.perf_counter() - start
    start = time.perf_counter()
    network = FourierNetwork(config, progress=progress).fit(campaign, train)
    seconds["network"] = time.perf_counter() - start
    return {"network": network, "trilinear": trilinear}, seconds


def file_sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def save_models(models: Mapping[str, DeviationModel], out: Path, card: dict[str, Any]) -> Path:
    """Write the models and the card into out, atomically (temp folder beside out, then a rename)."""
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".tmp", dir=out.parent))
    try:
        for model in models.values():
            model.save(tmp)
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
    path = Path(directory) / CARD_NAME
    if not path.is_file():
        raise InputError("not a model folder (no card.json)", file=str(directory))
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"unreadable model card: {error}", file=str(path)) from None


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


def build_card(
    campaign: Campaign,
    data: Path | None,
    holdout: NDArray[np.bool_],
    source: str,
    seed: int,
    models: Mapping[str, DeviationModel],
    seconds: Mapping[str, float],
    evaluated: Mapping[str, DeviationModel] | None = None,
) -> dict[str, Any]:
    """The model card: provenance, hyperparameters, training record and the evaluation at the holdout.

    evaluated: the models to evaluate, default `models` (train passes the models as re-read from
    their files, so that evaluate reproduces the card's figures exactly).
    """
    network = models["network"]
    trilinear = models["trilinear"]
    assert isinstance(network, FourierNetwork) and isinstance(trilinear, TrilinearModel)
    report = evaluation_report(campaign, evaluated or models, holdout)
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
        "metrics": {**report, "average_mae_um": mean_mae(report)},
    }


def train_command(
    data: Path,
    out: Path,
    holdout: str | None = None,
    seed: int = 0,
    geometry: dict[str, float] | None = None,
    network_config: NetworkConfig | None = None,
    quiet: bool = False,
) -> int:
    """`ph-explorer train`: train both models on a campaign CSV and write the model folder."""
    from ph_explorer.evaluation import format_report
    from ph_explorer.io import read_campaign

    if Path(out).exists() and not Path(out).is_dir():
        raise InputError("--out must be a folder (it exists as a file)", file=str(out))
    campaign = read_campaign(Path(data), geometry or {})
    mask = parse_holdout(holdout, campaign) if holdout else campaign.holdout_mask()
    if mask.all():
        raise InputError("the holdout leaves no orientation to train on", file=str(data))
    if not mask.any():
        print("ph-explorer train: no check and no off-grid orientation: nothing held out", file=sys.stderr)
    source = holdout_source(campaign, holdout)
    config = network_config or NetworkConfig()

    with _progress_bar(config.max_epochs, quiet) as progress:
        models, seconds = train_models(campaign, ~mask, seed, progress, config)
    # The card's figures come from the files as saved, so evaluate reproduces them exactly.
    with tempfile.TemporaryDirectory() as scratch:
        for model in models.values():
            model.save(scratch)
        saved = load_models(Path(scratch))
    card = build_card(campaign, Path(data), mask, source, seed, models, seconds, evaluated=saved)
    save_models(models, Path(out), card)
    if not quiet:
        net = card["network"]
        print(
            f"trained on {int((~mask).sum())} orientations, held out {int(mask.sum())} ({source}); "
            f"network {net['epochs']} epochs (best {net['best_epoch']}), "
            f"{card['training_seconds']['total']:.1f} s; wrote {out}"
        )
        if mask.any():
            print(format_report(card["metrics"]), end="")
    return 0


class _progress_bar:
    """A rich progress bar on stderr (epoch, loss, validation MAE), or nothing when quiet."""

    def __init__(self, total: int, quiet: bool):
        self.total, self.quiet, self.bar, self.task = total, quiet, None, None

    def __enter__(self) -> ProgressCallback | None:
        if self.quiet:
            return None
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        self.bar = Progress(
            TextColumn("network epoch {task.completed:>4}"),
            BarColumn(),
            TextColumn("loss {task.fields[loss]:.4f}  val MAE {task.fields[mae]:.4f} um  lr {task.fields[lr]:.1e}"),
            TimeElapsedColumn(),
            console=Console(stderr=True),
            transient=False,
        )
        self.bar.start()
        self.task = self.bar.add_task("train", total=self.total, loss=float("nan"), mae=float("nan"), lr=float("nan"))

        def update(epoch: int, loss: float, mae: float, lr: float) -> None:
            self.bar.update(self.task, completed=epoch, loss=loss, mae=mae, lr=lr)

        return update

    def __exit__(self, *exc: object) -> None:
        if self.bar is not None:
            self.bar.stop()
