"""`ph-explorer diagnose`: where the model fails, which effect is missing, add it, and the error history."""

from __future__ import annotations

import json
import sys
from pathlib import Path

from rich.console import Console
from rich.progress import Progress

from ph_explorer.errors import InputError
from ph_explorer.io import checked_output_file, file_sha256
from ph_explorer.io.writer import atomic_write
from ph_explorer.models.lattice_need import read_lattice_campaign

PROGRESS_CONSOLE = Console(stderr=True)  # the bars on stderr: stdout holds the report alone, streamed

DETAILS = ("short", "full")


def diagnose_command(
    data: Path,
    model: Path | None = None,
    add: str | None = None,
    effects: Path | None = None,
    json_output: bool = False,
    geometry: dict[str, float] | None = None,
    data_part: str | None = None,
    save: Path | None = None,
    resume: Path | None = None,
    detail: str = "short",
    export_shapes: Path | None = None,
) -> int:
    """Diagnose the campaign (from a trained model's baseline if given) and print the report or its JSON;
    with --save or --resume, write the study."""
    from ph_explorer.diagnosis.campaign_file import catalog_of, check_data_part, diagnose_campaign, parse_add
    from ph_explorer.diagnosis.results import Headline
    from ph_explorer.diagnosis.study import Study, study_campaign
    from ph_explorer.effects import DEFAULT_CATALOG
    from ph_explorer.effects.shapes_file import shapes_file_text
    from ph_explorer.figures.diagnosis_text import report_text, verdict_headline
    from ph_explorer.planning.deciding import DECIDE_BUDGET, rings_that_decide

    if detail not in DETAILS:
        raise InputError(f"unknown detail {detail!r} ({', '.join(DETAILS)})", option="--detail")
    catalog = catalog_of(effects)
    previous = Study.load(resume, catalog) if resume is not None else None
    data_part = check_data_part(data_part or (previous.data_part if previous else "trilinear"))
    if save is not None:
        checked_output_file(save, "--save", "the study", "study.json")
    if export_shapes is not None:
        checked_output_file(export_shapes, "--export-shapes", "the shapes file", "shapes.toml")
    if model is not None and not Path(model).is_dir():  # said before the progress bar, which would leave a blank line
        what = "is a file: give the folder train --out wrote" if Path(model).exists() else "model folder not found"
        raise InputError(what, file=str(model), option="--model")
    ids = parse_add(add, catalog)
    if effects is not None and not json_output:
        read = [effect_id for effect_id in catalog if effect_id not in DEFAULT_CATALOG]
        added = "" if ids is None else f"; added to the model: {', '.join(ids)}"
        PROGRESS_CONSOLE.print(f"Read {effects}: {', '.join(read) or 'no effect'}{added}.", highlight=False, soft_wrap=True)
    start = previous.effects(catalog) if previous else []
    sha256 = file_sha256(Path(data)) if Path(data).is_file() else ""
    campaign = read_lattice_campaign(data, geometry)
    rings_added = previous.rings_added_on(sha256, str(data), campaign.scenario.get("merges", [])) if previous else []
    with Progress(transient=True, disable=json_output, console=PROGRESS_CONSOLE) as bar:
        task = bar.add_task("scanning candidate effects", total=None)
        network_task = bar.add_task("network on the residual", total=None, visible=False)

        def say_verdict(headline: Headline) -> None:
            # The verdict as soon as it stands (the report's first line); the rest follows it.
            bar.stop()
            # said before the record exists: its rings are tested against noise with more than one repetition (Diagnosis.tested)
            print(verdict_headline(headline, catalog, tested=campaign.n_repetitions > 1), flush=True)
            bar.update(task, description="describing what is left, measuring the error history")
            bar.start()

        result = diagnose_campaign(
            campaign,
            catalog,
            ids,
            model,
            data_part,
            start,
            progress=lambda activity: bar.update(task, description=activity),
            # Retraining the network on what the physical terms leave: epochs, loss, validation MAE.
            network_progress=lambda epoch, loss, mae, lr: bar.update(
                network_task, visible=True, description=f"network epoch {epoch}: loss {loss:.4f}, val MAE {mae:.4f} um"
            ),
            on_verdict=None if json_output else say_verdict,
        )
    # The verdict line as soon as it stands (say_verdict), then the report (the same text as one print at the end).
    if not json_output:
        # What rings can decide of what the verdict leaves open, said with the verdict (design --decide lists them).
        decision = rings_that_decide(campaign, result, catalog, DECIDE_BUDGET) if result.leaves_open else None
        print(report_text(result, catalog, detail, decision, headline=False, data_file=str(data)), end="", flush=True)
    target = save if save is not None else resume
    if target is not None:
        described = study_campaign(Path(data).name, sha256, campaign)
        effects_file = None if effects is None else str(effects)
        study = Study.of_run(result, result.model_effects, described, data_part, effects_file, previous, rings_added=rings_added)
        study.save(target)
        PROGRESS_CONSOLE.print(
            f"Saved the study to {target} (run {len(study.runs)}): --resume {target} continues it, report --study {target} draws it.",
            highlight=False,
            soft_wrap=True,
        )
    if export_shapes is not None:
        if result.shapes:
            atomic_write([(Path(export_shapes), shapes_file_text([shape.table() for shape in result.shapes]))])
            ids = " ".join(shape.id for shape in result.shapes)
            PROGRESS_CONSOLE.print(
                f"Wrote {len(result.shapes)} shape{'s' * (len(result.shapes) > 1)} to {export_shapes}: {ids}; --effects {export_shapes} --add ID adds one.",
                highlight=False,
                soft_wrap=True,
            )
        else:
            print(
                f"No shape to export: none was searched or found (the verdict is {result.verdict}); {export_shapes} not written.",
                file=sys.stderr,
            )
    if json_output:
        print(json.dumps(result.to_json()))
    return 0
