"""A study: the history of a diagnosis that lasts beyond one run, to be continued later, as one
typed record with load, save and resume in one place (the CLI, the report and the app use it).

A study is one JSON object ("format": "ph-explorer study 2"; format 1 still reads), written by
`diagnose --save STUDY` and read by `--resume STUDY` and the app's study buttons: its campaign (the
sha256 must match to resume, or be a merge of it), the `chain` of effects the study has reached
(resuming starts from it), the last run's `steps`, `nested_after` and whole `diagnosis` record,
and every run in `runs`. Method: docs/methods/study_file.md.
"""

from __future__ import annotations

import datetime
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.results import ChainLink, Diagnosis, NestedAfter, Step, chain_effect, chain_entry
from ph_explorer.effects import Catalog, Effect, effect_label
from ph_explorer.effects.shapes_file import shape_class
from ph_explorer.errors import InputError
from ph_explorer.io import read_json_object, write_json_object

STUDY_FORMAT = "ph-explorer study 2"
READABLE_FORMATS = ("ph-explorer study 1", STUDY_FORMAT)  # 1: no diagnosis record, its verdict beside the runs
STUDY_KEYS = ("format", "campaign", "baseline", "data_part", "chain", "runs")


def study_campaign(file_name: str, sha256: str, campaign: Campaign) -> dict[str, Any]:
    """The study's `campaign` object: the file it was made on, its bytes' sha256 and its size."""
    return {"file": file_name, "sha256": sha256, "orientations": campaign.n_orientations, "repetitions": campaign.n_repetitions}


@dataclass(frozen=True)
class Run:
    """One run of a study: when, from which step of the chain, what it added, its verdict, and the
    rings merged into the campaign since the run before."""

    date: str
    started_from: int
    added: tuple[str, ...]
    verdict: str
    rings_added: tuple[dict[str, Any], ...] = ()

    def to_json(self) -> dict[str, Any]:
        out = {"date": self.date, "started_from": self.started_from, "added": list(self.added), "verdict": self.verdict}
        return out | ({"rings_added": list(self.rings_added)} if self.rings_added else {})


@dataclass(frozen=True)
class Study:
    """A study (module docstring); `source` names it in error lines."""

    campaign: dict[str, Any]  # {"file", "sha256", "orientations", "repetitions"}
    baseline: str
    data_part: str
    chain: tuple[ChainLink, ...]
    runs: tuple[Run, ...]
    steps: tuple[Step, ...] = ()
    nested_after: NestedAfter | None = None
    diagnosis: Diagnosis | None = None  # the last run's record (none in a study of format 1)
    effects_file: str | None = None
    source: str = field(default="study", compare=False)

    @property
    def verdict(self) -> str | None:
        """The last run's verdict."""
        return self.runs[-1].verdict if self.runs else None

    @classmethod
    def of_run(
        cls,
        result: Diagnosis,
        chain: Sequence[Effect],
        campaign: dict[str, Any],
        data_part: str,
        effects_file: str | None = None,
        previous: Study | None = None,
        steps: Sequence[Step] | None = None,
        rings_added: Sequence[dict[str, Any]] = (),
    ) -> Study:
        """The study after this run: the chain the run reached (start + what it added), the run's
        record, and the runs before it (`previous`, the study it resumed). steps: the error history
        when it is not the diagnosis's own (the app's refits); its last step's parameters are the
        chain's. rings_added: the rings merged into the campaign since the study's last run."""
        steps = tuple(result.steps if steps is None else steps)
        # Parameters: the joint fit of the whole chain (the last step); their uncertainty from the
        # search that found each effect (this run's, or the study's it resumed).
        joint = steps[-1].params if steps and steps[-1].added else ()
        uncertainty = {(link.effect, _key(link.settings)): link.params_u for link in (previous.chain if previous else ())}
        uncertainty |= {(c.effect, _key(c.settings)): c.params_u for c in result.found}
        links = []
        for index, effect in enumerate(chain):
            settings = {k: float(v) for k, v in effect.settings().items()}
            params = joint[index]["params"] if index < len(joint) else {}
            shape = chain_entry(effect).get("shape")
            links.append(ChainLink(effect.id, settings, params, uncertainty.get((effect.id, _key(settings)), {}), shape))
        started_from = 0 if previous is None else len(previous.chain)
        date = datetime.datetime.now().isoformat(timespec="seconds")
        run = Run(date, started_from, tuple(effect_label(e) for e in chain[started_from:]), result.verdict, tuple(rings_added))
        # A run that chose nothing new has no nested figures of its own: the chain's choice is still
        # the one the study's last nested figures measured.
        nested = result.nested if result.nested is not None else (previous.nested_after if previous else None)
        runs = (*(previous.runs if previous else ()), run)
        return cls(campaign, result.baseline_model, data_part, tuple(links), runs, steps, nested, result, effects_file)

    def to_json(self) -> dict[str, Any]:
        return {
            "format": STUDY_FORMAT,
            "campaign": self.campaign,
            "baseline": self.baseline,
            "data_part": self.data_part,
            "effects_file": self.effects_file,
            "chain": [link.to_json() for link in self.chain],
            "steps": [s.to_json() for s in self.steps],
            "nested_after": None if self.nested_after is None else self.nested_after.to_json(),
            "runs": [run.to_json() for run in self.runs],
            "diagnosis": None if self.diagnosis is None else self.diagnosis.to_json(),
        }

    def save(self, path: Path) -> None:
        """Write the study atomically: the old file stays whole until the new one is complete."""
        write_json_object(Path(path), self.to_json())

    @classmethod
    def load(cls, path: Path, catalog: Catalog) -> Study:
        """The study in a file, checked whole (parse); an InputError line naming what is wrong."""
        return cls.parse(read_json_object(Path(path), "study"), str(path), catalog)

    @classmethod
    def parse(cls, data: Mapping[str, Any], source: str, catalog: Catalog) -> Study:
        """The study of a JSON object, checked whole: every key, the format, the campaign, a chain of
        the catalog's candidates at their settings, the steps and the record; else an InputError line."""
        for key in STUDY_KEYS:
            if key not in data:
                raise InputError(f"not a study: no {key!r} key", file=source)
        if data["format"] not in READABLE_FORMATS:
            raise InputError(f"format {data['format']!r} is not {STUDY_FORMAT!r}", file=source, column="format")
        campaign = data["campaign"]
        if not isinstance(campaign, dict) or not isinstance(campaign.get("sha256"), str):
            raise InputError("campaign must be an object with the campaign file's sha256", file=source, column="campaign")
        if not isinstance(data["chain"], list) or not isinstance(data["runs"], list):
            raise InputError("chain and runs must be lists", file=source, column="chain")
        chain = tuple(
            _link(entry, f"chain[{index}]", source, catalog, data.get("effects_file")) for index, entry in enumerate(data["chain"])
        )
        steps = tuple(_parsed(Step.from_json, entry, source, f"steps[{index}]") for index, entry in enumerate(data.get("steps") or []))
        nested = data.get("nested_after")
        record = data.get("diagnosis")
        # Format 1 kept the last run's verdict beside its runs; format 2 in each run.
        runs = tuple(
            _parsed(lambda r: _run(r, data.get("verdict")), entry, source, f"runs[{index}]") for index, entry in enumerate(data["runs"])
        )
        return cls(
            campaign,
            str(data["baseline"]),
            str(data["data_part"]),
            chain,
            runs,
            steps,
            None if nested is None else _parsed(NestedAfter.from_json, nested, source, "nested_after"),
            None if record is None else _parsed(lambda r: Diagnosis.from_json(r, catalog), record, source, "diagnosis"),
            data.get("effects_file"),
            source,
        )

    def effects(self, catalog: Catalog) -> list[Effect]:
        """The effects of the chain, each at its settings, from the catalog, or a shape from its table
        (parse checked them)."""
        return [chain_effect(link.to_json(), catalog) for link in self.chain]

    def rings_added_on(self, sha256: str, data: str, merges: Sequence[dict[str, Any]] = ()) -> list[dict[str, Any]]:
        """A study continues on the campaign it was made on (the same bytes), or on a merge of it with
        new rings (merges: the campaign's record of them, io.merge). Returns the merges since the
        study's campaign: the rings added, and from which file ([] on the same campaign)."""
        made = self.campaign["sha256"]
        if made == sha256:
            return []
        bases = [m.get("base_sha256") for m in merges]
        if made in bases:
            since = merges[bases.index(made) :]
            return [{"from": m.get("added_from"), "added": m.get("added", []), "replaced": m.get("replaced", [])} for m in since]
        made_on = self.campaign.get("file") or "another campaign"
        raise InputError(
            f"the study was made on {made_on} (sha256 {made[:12]}), not on {data} (sha256 {sha256[:12]}) nor on a campaign merged from it",
            file=self.source,
        )


def _key(settings: Mapping[str, Any]) -> tuple:
    return tuple(sorted((k, float(v)) for k, v in settings.items()))


def _link(entry: Any, where: str, source: str, catalog: Catalog, effects_file: str | None) -> ChainLink:
    """One chain entry, checked: a candidate of the catalog at settings of its own parameters."""
    if not isinstance(entry, dict) or not isinstance(entry.get("effect"), str) or not isinstance(entry.get("settings", {}), dict):
        raise InputError("each entry must be {'effect': id, 'settings': {name: value}}", file=source, column=where)
    settings = entry.get("settings", {})
    for name, value in settings.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"setting {name!r} must be a number, got {value!r}", file=source, column=where)
    effect_id = entry["effect"]
    if "shape" in entry:  # a shape no catalog holds: its table, checked as a shapes file's
        shape = shape_class(
            entry["shape"], lambda message, key=None: InputError(f"shape {effect_id!r}: {message}", file=source, column=where)
        )
        params, params_u = entry.get("params") or {}, entry.get("params_u") or {}
        return ChainLink(shape.id, {}, dict(params), dict(params_u), dict(entry["shape"]))
    if effect_id not in catalog.candidates():
        hint = f" (the study was made with --effects {effects_file})" if effects_file else ""
        raise InputError(f"effect {effect_id!r} is not a candidate of the catalog{hint}", file=source, column=where)
    unknown = sorted(set(settings) - {p.name for p in catalog[effect_id].parameters})
    if unknown:
        raise InputError(f"effect {effect_id!r} has no parameter {unknown[0]!r}", file=source, column=where)
    params, params_u = entry.get("params") or {}, entry.get("params_u") or {}
    return ChainLink(effect_id, {k: float(v) for k, v in settings.items()}, dict(params), dict(params_u))


def _run(entry: Mapping[str, Any], verdict: str | None) -> Run:
    rings = tuple(entry.get("rings_added", []))
    return Run(str(entry["date"]), int(entry["started_from"]), tuple(entry["added"]), str(entry.get("verdict", verdict)), rings)


def _parsed(read: Any, entry: Any, source: str, where: str) -> Any:
    """read(entry), or one InputError line saying where the study is malformed."""
    try:
        return read(entry)
    except (KeyError, TypeError, ValueError, AttributeError):
        raise InputError(f"{where} is not as ph-explorer writes it (docs/methods/study_file.md)", file=source, column=where) from None
