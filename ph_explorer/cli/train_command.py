"""`ph-explorer train`: train both models on a campaign CSV and write the model folder, with a progress bar."""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from ph_explorer.campaign import Campaign, orientation_match
from ph_explorer.cli.evaluate_command import format_report
from ph_explorer.errors import InputError
from ph_explorer.io import checked_output_file
from ph_explorer.models.lattice_need import read_lattice_campaign

if TYPE_CHECKING:  # torch-bound: imported for real only when the command runs
    from ph_explorer.models.network import NetworkConfig, ProgressCallback


def train_command(
    data: Path,
    out: Path,
    holdout: str | None = None,
    seed: int = 0,
    geometry: dict[str, float] | None = None,
    network_config: NetworkConfig | None = None,
    quiet: bool = False,
    max_epochs: int | None = None,
    data_part: str | None = None,
) -> int:
    """Train on every orientation but the holdout, write the folder (models + card), print the tables;
    with data_part gp, the Gaussian process beside them (trilinear and network are always trained)."""
    # torch: imported when the command runs, so that the CLI (and inspect) works without it.
    from ph_explorer.diagnosis.campaign_file import check_data_part
    from ph_explorer.models.network import NetworkConfig
    from ph_explorer.paper.training import build_card, model_errors, save_models, train_models

    part = check_data_part(data_part) if data_part else None
    parts = (part,) if part not in (None, "trilinear", "network") else ()  # the two are always trained
    if Path(out).exists() and not Path(out).is_dir():
        raise InputError("must be a folder (it exists as a file)", file=str(out), option="--out")
    if not Path(out).is_dir():  # made, in a folder that exists: as every command's output, no folders on the way
        checked_output_file(Path(out), "--out", "the model folder", "head_3_models")
    campaign = read_lattice_campaign(data, geometry)
    mask = parse_holdout(holdout, campaign) if holdout else campaign.holdout_mask()
    if mask.all():
        raise InputError("the holdout leaves no orientation to train on", file=str(data))
    if not mask.any():
        print("ph-explorer train: no check and no off-grid orientation: nothing held out", file=sys.stderr)
    source = holdout_source(campaign, holdout)
    config = network_config or NetworkConfig()
    if max_epochs is not None:
        config = replace(config, max_epochs=max_epochs)

    with progress_bar(config.max_epochs, quiet) as progress:
        models, seconds = train_models(campaign, ~mask, seed, progress, config, parts)
    card = build_card(campaign, Path(data), mask, source, seed, models, seconds)
    if not quiet:
        print(
            "estimating each model's out-of-sample error (5-fold cross-validation and A values left out in turn, "
            "the network retrained each time; "
            "its size calibrated on the held-out rings)",
            file=sys.stderr,
        )
    errors = model_errors(campaign, ~mask, models, seed, config)
    save_models(models, Path(out), card, errors)
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


def parse_orientations(text: str, option: str) -> list[tuple[float, float]]:
    """The orientations of an option 'A:B,A:B' in degrees; InputError naming the option otherwise."""
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
            raise InputError(f"{item!r} is not an orientation A:B in degrees (e.g. 43:91)", option=option) from None
        pairs.append((a, b))
    if not pairs:
        raise InputError("names no orientation (expected 'A:B,A:B', e.g. 15:-20,43:91)", option=option)
    return pairs


def parse_holdout(text: str, campaign: Campaign) -> NDArray[np.bool_]:
    """The mask of the orientations named by --holdout 'A:B,A:B' (each must be in the campaign)."""
    pairs = parse_orientations(text, "--holdout")
    match = orientation_match(campaign.orientations, np.array(pairs))
    missing = [f"{a:g}:{b:g}" for (a, b), hit in zip(pairs, match.any(axis=0)) if not hit]
    if missing:
        raise InputError(f"orientation(s) {', '.join(missing)} not in the campaign", file=campaign.source, option="--holdout")
    return match.any(axis=1)


def holdout_source(campaign: Campaign, option: str | None) -> str:
    """Where the holdout came from, for the card."""
    if option:
        return "option"
    if campaign.check_orientations is not None and len(campaign.check_orientations):
        return "sidecar check orientations"
    return "off-grid orientations"


@contextmanager
def progress_bar(total_epochs: int, quiet: bool) -> Iterator[ProgressCallback | None]:
    """A rich progress bar on stderr (epoch, loss, validation MAE, learning rate); None when quiet."""
    if quiet:
        yield None
        return
    bar = Progress(
        TextColumn("network epoch {task.completed:>4}"),
        BarColumn(),
        TextColumn("loss {task.fields[loss]:.4f}  val MAE {task.fields[mae]:.4f} um  lr {task.fields[lr]:.1e}"),
        TimeElapsedColumn(),
        console=Console(stderr=True),
        transient=False,
    )
    task = bar.add_task("train", total=total_epochs, loss=float("nan"), mae=float("nan"), lr=float("nan"))

    def update(epoch: int, loss: float, mae: float, lr: float) -> None:
        bar.update(task, completed=epoch, loss=loss, mae=mae, lr=lr)

    with bar:
        yield update
