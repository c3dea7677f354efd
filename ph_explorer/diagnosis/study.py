"""A study: the history of a diagnosis that lasts beyond one run, to be continued later.

A study is one JSON object ("format": "ph-explorer study 1"), written by `diagnose --save STUDY`
and read by `--resume STUDY` and the app's study buttons: its campaign (the sha256 must match to
resume), the `chain` of effects the study has reached (resuming starts from it), the last run's
`steps`, `verdict`, `within_noise` and `nested_after`, and every run in `runs`.

Method: docs/methods/study_file.md.
"""

from __future__ import annotations

import datetime
from collections.abc import Sequence
from typing import Any

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.results import Diagnosis, Step
from ph_explorer.effects import Catalog, Effect, effect_label
from ph_explorer.errors import InputError

STUDY_FORMAT = "ph-explorer study 1"
STUDY_KEYS = ("format", "campaign", "baseline", "data_part", "chain", "runs")


def study_campaign(file_name: str, sha256: str, campaign: Campaign) -> dict[str, Any]:
    """The study's `campaign` object: the file it was made on, its bytes' sha256 and its size."""
    return {"file": file_name, "sha256": sha256, "orientations": campaign.n_orientations, "repetitions": campaign.n_repetitions}


def study_record(
    result: Diagnosis,
    chain: list[Effect],
    campaign: dict[str, Any],
    data_part: str,
    effects_file: str | None = None,
    previous: dict[str, Any] | None = None,
    steps: list[Step] | None = None,
    rings_added: list[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The study after this run: the chain the run reached (start + what it added), its figures,
    and the runs before it (from `previous`, the study it resumed, if any). rings_added: the rings
    merged into the campaign since the study's last run (check_campaign), recorded with the run.

    steps: the error history when it is not the diagnosis's own (the app's refits); its last
    step's parameters are the chain's.
    """
    figures = result.to_json()
    if steps is not None:
        figures["steps"] = [s.to_json() for s in steps]
    else:
        steps = result.steps
    # Parameters: the joint fit of the whole chain (the last step); their uncertainty from the
    # search that found each effect (this run's, or the study's it resumed).
    joint = steps[-1].params if steps and steps[-1].added else []

    def key(effect_id: str, settings: dict[str, Any]) -> tuple:
        return effect_id, tuple(sorted((k, float(v)) for k, v in settings.items()))

    uncertainty = {key(e["effect"], e.get("settings", {})): e.get("params_u", {}) for e in (previous or {}).get("chain", [])}
    uncertainty.update({key(c.effect, c.settings): c.params_u for c in result.found})
    entries = []
    for index, effect in enumerate(chain):
        settings = {k: float(v) for k, v in effect.settings().items()}
        entries.append(
            {
                "effect": effect.id,
                "settings": settings,
                "params": joint[index]["params"] if index < len(joint) else {},
                "params_u": uncertainty.get(key(effect.id, settings), {}),
            }
        )
    started_from = 0 if previous is None else len(previous["chain"])
    run = {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "started_from": started_from,
        "added": [effect_label(e) for e in chain[started_from:]],
        "verdict": result.verdict,
    }
    if rings_added:
        run["rings_added"] = rings_added
    return {
        "format": STUDY_FORMAT,
        "campaign": campaign,
        "baseline": result.baseline_model,
        "data_part": data_part,
        "effects_file": effects_file,
        "chain": entries,
        "verdict": result.verdict,
        "steps": figures["steps"],
        "within_noise": figures["within_noise"],
        # A run that chose nothing new has no nested figures of its own: the chain's choice is still
        # the one the study's last nested figures measured.
        "nested_after": figures["nested_after"] if figures["nested_after"] is not None else (previous or {}).get("nested_after"),
        "runs": [*(previous or {}).get("runs", []), run],
        # What the last run found, whole (diagnosis.results, its JSON): the report's ranking and signature.
        "diagnosis": figures,
    }


def check_study(study: dict[str, Any], source: str) -> dict[str, Any]:
    """The study if it is one (every key, the format, a well-formed chain); else an InputError line."""
    for key in STUDY_KEYS:
        if key not in study:
            raise InputError(f"not a study: no {key!r} key", file=source)
    if study["format"] != STUDY_FORMAT:
        raise InputError(f"format {study['format']!r} is not {STUDY_FORMAT!r}", file=source, column="format")
    campaign = study["campaign"]
    if not isinstance(campaign, dict) or not isinstance(campaign.get("sha256"), str):
        raise InputError("campaign must be an object with the campaign file's sha256", file=source, column="campaign")
    if not isinstance(study["chain"], list) or not isinstance(study["runs"], list):
        raise InputError("chain and runs must be lists", file=source, column="chain")
    for index, entry in enumerate(study["chain"]):
        where = f"chain[{index}]"
        if not isinstance(entry, dict) or not isinstance(entry.get("effect"), str) or not isinstance(entry.get("settings", {}), dict):
            raise InputError("each entry must be {'effect': id, 'settings': {name: value}}", file=source, column=where)
        for name, value in entry.get("settings", {}).items():
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise InputError(f"setting {name!r} must be a number, got {value!r}", file=source, column=where)
    return study


def study_chain(study: dict[str, Any], catalog: Catalog, source: str) -> list[Effect]:
    """The effects of a (checked) study's chain, each at its settings, from the catalog."""
    candidates = catalog.candidates()
    chain = []
    for index, entry in enumerate(study["chain"]):
        effect_id = entry["effect"]
        if effect_id not in candidates:
            hint = " (the study was made with --effects " + str(study["effects_file"]) + ")" if study.get("effects_file") else ""
            raise InputError(f"effect {effect_id!r} is not a candidate of the catalog{hint}", file=source, column=f"chain[{index}]")
        effect = candidates[effect_id]()
        known = {p.name for p in effect.parameters}
        unknown = sorted(set(entry.get("settings", {})) - known)
        if unknown:
            raise InputError(f"effect {effect_id!r} has no parameter {unknown[0]!r}", file=source, column=f"chain[{index}]")
        chain.append(effect.with_settings(**entry.get("settings", {})))
    return chain


def check_campaign(
    study: dict[str, Any], sha256: str, source: str, data: str, merges: Sequence[dict[str, Any]] = ()
) -> list[dict[str, Any]]:
    """A study continues on the campaign it was made on (the same bytes), or on a merge of it with
    new rings (merges: the campaign's record of them, io.merge). Returns the merges since the
    study's campaign: the rings added, and from which file ([] on the same campaign)."""
    made = study["campaign"]["sha256"]
    if made == sha256:
        return []
    bases = [m.get("base_sha256") for m in merges]
    if made in bases:
        since = merges[bases.index(made) :]
        return [{"from": m.get("added_from"), "added": m.get("added", []), "replaced": m.get("replaced", [])} for m in since]
    made_on = study["campaign"].get("file") or "another campaign"
    raise InputError(
        f"the study was made on {made_on} (sha256 {made[:12]}), not on {data} (sha256 {sha256[:12]}) nor on a campaign merged from it",
        file=source,
    )


def study_steps(study: dict[str, Any] | None, source: str = "study") -> list[Step]:
    """The study's error history as Step objects (the JSON's `steps`); an InputError line when a step is malformed."""
    steps = []
    for index, entry in enumerate((study or {}).get("steps", [])):
        try:
            steps.append(Step.from_json(entry))
        except (KeyError, TypeError, ValueError, AttributeError):
            raise InputError(
                "each step must hold added, mae_um {mean, single} and noise_floor_um {mean, single}", file=source, column=f"steps[{index}]"
            ) from None
    return steps
