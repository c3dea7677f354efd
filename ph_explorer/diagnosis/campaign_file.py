"""A campaign diagnosed as `ph-explorer diagnose` does from its options, shared by the command and
by every task of a fleet (diagnosis.fleet), so that both give the same result to the last digit."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.loop import diagnose
from ph_explorer.diagnosis.results import Diagnosis, Headline
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect
from ph_explorer.errors import InputError
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.folder import baseline_of, load_models

DATA_PARTS = ("trilinear", "network", "gp")


def catalog_of(effects: Path | None) -> Catalog:
    """The catalog, with the user's effects file read in when one is given (--effects)."""
    return DEFAULT_CATALOG.with_file(effects) if effects is not None else DEFAULT_CATALOG


def parse_add(text: str | None, catalog: Catalog) -> list[str] | None:
    """The effect ids of --add 'ID[,ID]' (None when the option is not given); each must be addable
    (a candidate, or a shape of a shapes file)."""
    if text is None:
        return None
    ids = [a.strip() for a in text.split(",") if a.strip()]
    candidates = catalog.addable()
    if not ids:
        raise InputError(f"names no effect (expected 'ID[,ID]', e.g. {next(iter(candidates))})", option="--add")
    for effect_id in ids:
        if effect_id not in catalog:
            raise InputError(catalog.unknown(effect_id, column=None).message, option="--add")
        if effect_id not in candidates:
            raise InputError(
                f"effect {effect_id!r} cannot be added to a model: {catalog[effect_id].name} is not systematic", option="--add"
            )
    return ids


def check_data_part(data_part: str) -> str:
    if data_part not in DATA_PARTS:
        raise InputError(f"unknown data-driven part {data_part!r} ({', '.join(DATA_PARTS)})", option="--data-part")
    return data_part


def diagnose_campaign(
    campaign: Campaign,
    catalog: Catalog,
    add: list[str] | None = None,
    model: Path | Mapping[str, DeviationModel] | None = None,
    data_part: str = "trilinear",
    start: Sequence[Effect] = (),
    progress: Callable[[str], None] | None = None,
    network_progress: Callable[[int, float, float, float], None] | None = None,
    nested: bool = True,
    on_verdict: Callable[[Headline], None] | None = None,
) -> Diagnosis:
    """diagnose() with the command's options: a trained model folder's baseline (the folder, or its
    models already loaded by the caller, who shows them too), the data part by
    name (the network retrained on what the physical terms leave, reporting each epoch); nested and on_verdict: as diagnose's."""
    models = load_models(Path(model)) if isinstance(model, (str, Path)) else model
    baseline = baseline_of(models) if models is not None else None
    part: str | Callable[[], DeviationModel] = check_data_part(data_part)
    if data_part == "network":
        from ph_explorer.models.network import FourierNetwork  # torch: only when the network is asked for

        def part() -> DeviationModel:
            return FourierNetwork(progress=network_progress)

    return diagnose(
        campaign,
        add=add,
        baseline=baseline,
        data_part=part,
        catalog=catalog,
        progress=progress,
        start=start,
        nested=nested,
        on_verdict=on_verdict,
    )
