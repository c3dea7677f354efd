"""`ph-explorer diagnose`: where the model fails, which effect is missing, add it, and the error history."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import Progress

from ph_explorer.effects import DEFAULT_CATALOG, Catalog
from ph_explorer.io import checked_output_file, file_sha256, read_campaign, read_json_object, write_json_object

PROGRESS_CONSOLE = Console(stderr=True)  # the bars on stderr: stdout holds the report alone, streamed

if TYPE_CHECKING:  # torch-bound: imported for real only when the command runs
    from ph_explorer.diagnosis import Candidate, Diagnosis
    from ph_explorer.diagnosis.results import NestedAfter


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
) -> int:
    """Diagnose the campaign (from a trained model's baseline if given) and print the report or its JSON;
    with --save or --resume, write the study."""
    from ph_explorer.diagnosis.campaign_file import catalog_of, check_data_part, diagnose_campaign, parse_add
    from ph_explorer.diagnosis.loop import honest_after
    from ph_explorer.diagnosis.study import check_campaign, check_study, study_campaign, study_chain, study_record

    previous = check_study(read_json_object(resume, "study"), str(resume)) if resume is not None else None
    data_part = check_data_part(data_part or (previous["data_part"] if previous else "trilinear"))
    if save is not None:
        checked_output_file(save, "--save", "the study", "study.json")
    catalog = catalog_of(effects)
    ids = parse_add(add, catalog)
    start = study_chain(previous, catalog, str(resume)) if previous else []
    sha256 = file_sha256(Path(data)) if Path(data).is_file() else ""
    campaign = read_campaign(Path(data), geometry or {})
    rings_added = check_campaign(previous, sha256, str(resume), str(data), campaign.scenario.get("merges", [])) if previous else []
    with Progress(transient=True, disable=json_output, console=PROGRESS_CONSOLE) as bar:
        task = bar.add_task("scanning candidate effects", total=None)
        network_task = bar.add_task("network on the residual", total=None, visible=False)
        result = diagnose_campaign(
            campaign,
            catalog,
            ids,
            model,
            data_part,
            start,
            progress=lambda effect_id: bar.update(task, description=f"scanning {effect_id}"),
            # Retraining the network on what the physical terms leave: epochs, loss, validation MAE.
            network_progress=lambda epoch, loss, mae, lr: bar.update(
                network_task, visible=True, description=f"network epoch {epoch}: loss {loss:.4f}, val MAE {mae:.4f} um"
            ),
            nested=False,
        )
    # The report up to the error history as soon as the verdict stands; the nested figures, its last
    # lines, when they are measured (the same text as one print at the end).
    if not json_output:
        print(format_diagnosis(result, catalog), end="", flush=True)
    with Progress(transient=True, disable=json_output, console=PROGRESS_CONSOLE) as bar:
        bar.add_task("measuring the chosen effects on rings that took no part in choosing them", total=None)
        result.nested = honest_after(campaign, result, catalog)
    target = save if save is not None else resume
    if target is not None:
        described = study_campaign(Path(data).name, sha256, campaign)
        study = study_record(
            result, result.chain, described, data_part, None if effects is None else str(effects), previous, rings_added=rings_added
        )
        write_json_object(target, study)
    if json_output:
        print(json.dumps(result.as_dict()))
    elif result.nested is not None:
        print("\n".join(_nested_lines(result.nested)))
    return 0


def format_diagnosis(result: Diagnosis, catalog: Catalog = DEFAULT_CATALOG) -> str:
    """A plain-text report: where it fails, the ranked candidates, the verdict, the error history."""
    return (
        "\n".join(
            _floor_and_baseline(result)
            + [""]
            + _where_it_fails(result)
            + [""]
            + _candidates(result, catalog)
            + [""]
            + _verdict(result, catalog)
            + [""]
            + _history(result)
        )
        + "\n"
    )


def _floor_and_baseline(result: Diagnosis) -> list[str]:
    floor, baseline = result.noise_floor_um, result.baseline_mae_um
    return [
        f"Noise floor (touch noise after the modelled effects): {floor['mean']:.3f} um against the repetition mean, "
        f"{floor['single']:.3f} um against single repetitions.",
        f"Baseline ({result.baseline_model}) on the {int(result.held_out.sum())} held-out rings: "
        f"MAE {baseline['mean']:.3f} um (mean), {baseline['single']:.3f} um (single).",
    ]


def _where_it_fails(result: Diagnosis) -> list[str]:
    """The count of failing orientations, then the worst five (by MAE over their own floor)."""
    lines = [
        f"Rings that exceed their noise: {int(result.failing.sum())} of {len(result.failing)} orientations "
        "(out of sample; the within-noise test, ring level 1 %)."
    ]
    for ring in result.failing_rings()[:5]:
        kind = "held out" if ring.held_out else "leave-one-out"
        lines.append(
            f"  A {ring.a_deg:g} B {ring.b_deg:g} ({kind}): MAE {ring.mae_um:.3f} um, {ring.ratio:.1f}x its floor; exceeds {ring.reason}"
        )
    return lines


def _candidates(result: Diagnosis, catalog: Catalog) -> list[str]:
    from ph_explorer.effects import effect_label

    lines = ["Candidate effects (best first): share of the out-of-sample residual explained, fall of the held-out error"]
    lines += _ranking(result.candidates, catalog)
    chain: list[str] = []
    for found, ranking in zip(result.found, result.rankings[1:]):
        chain.append(effect_label(catalog[found.effect]().with_settings(**found.settings)))
        lines += ["", f"Re-ranked with {' + '.join(chain)} in the model (top {RERANKED_SHOWN}):"]
        lines += _ranking(ranking[:RERANKED_SHOWN], catalog)
    return lines


RERANKED_SHOWN = 5  # rows of each table re-ranked after a step


def _ranking(candidates: list[Candidate], catalog: Catalog) -> list[str]:
    lines = []
    width = max([len(c.effect) for c in candidates] + [6])
    for c in candidates:
        if c.note and not c.explained_fraction:
            lines.append(f"   {c.effect.ljust(width)}  not tested: {c.note}")
            continue
        shown = c.significant or c.beyond_noise  # a fit of noise describes nothing
        params = catalog[c.effect].parameters_text(c.params, c.params_u) if shown else ""
        flag = "*" if c.significant else " "
        lines.append(
            f" {flag} {c.effect.ljust(width)}  explains {100 * c.explained_fraction:5.1f} %  (noise alone {100 * c.noise_fraction:5.2f} %)"
            f"  error -{100 * c.error_reduction:4.1f} %  {c.status}"
            + (f": {params}" if params else "")
            + (f"  ({c.note})" if c.note and c.status != "not significant" else "")
        )
    return lines


def _verdict(result: Diagnosis, catalog: Catalog) -> list[str]:
    from ph_explorer.diagnosis import verdict_text  # torch-bound, like the command itself

    headline, lines = verdict_text(result, catalog)
    return [headline] + [f"  {line}" for line in lines]


def _history(result: Diagnosis) -> list[str]:
    lines = ["Error history on the held-out rings (MAE / um, and the noise floor):"]
    for step in result.steps:
        name = f"baseline ({step.model})" if not step.added else "+ " + " + ".join(step.added) + f" ({step.model})"
        lines.append(f"  {name:50s} " + _mae_text(step.mae_um, step.noise_floor_um))
    return lines + (_nested_lines(result.nested) if result.nested is not None else [])


def _nested_lines(nested: NestedAfter) -> list[str]:
    """The nested cross-validation's lines: the error history's last."""
    lines = [
        f"The same, measured honestly: the effects and periods chosen without the rings measured ({nested.folds}-fold "
        f"cross-validation over the {nested.rings} training rings, trilinear data part; the check rings above took part in the choice):",
        f"  {'before':50s} " + _mae_text(nested.before_um, nested.noise_floor_um),
        f"  {'after':50s} " + _mae_text(nested.after_um, nested.noise_floor_um),
    ]
    counts: dict[str, int] = {}
    for fold in nested.chosen:
        for label in fold:
            counts[label] = counts.get(label, 0) + 1
    chosen = ", ".join(f"{label} ({n} of {nested.folds})" for label, n in counts.items()) or "nothing"
    lines.append(f"  chosen in the folds: {chosen}")
    return lines


def _mae_text(mae: dict[str, float], floor: dict[str, float]) -> str:
    return f"mean {mae['mean']:.3f} (floor {floor['mean']:.3f})   single {mae['single']:.3f} (floor {floor['single']:.3f})"
