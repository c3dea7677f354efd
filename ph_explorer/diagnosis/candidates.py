"""A candidate effect in the record of a diagnosis (diagnosis.results): its fit, its standing,
its replication over rings and the partners this campaign cannot tell it from, typed and frozen.

Each stage of the search returns new candidates (dataclasses.replace); none changes another's.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any, Literal, get_args

import numpy as np

from ph_explorer.diagnosis.replication import Replication

DIGITS = 5
NULL_MARGIN = 2.0  # a candidate is beyond noise when it explains more than this multiple of the noise null

# A candidate's standing, from its flags (Candidate.status).
Status = Literal[
    "found",
    "suggested",
    "not needed",
    "beyond noise, not material",
    "implausible",
    "not significant",
    "not tested",
]
STATUSES: tuple[Status, ...] = get_args(Status)


@dataclass(frozen=True)
class PairTest:
    """Whether the rings prefer one candidate to a partner, rings as units (diagnosis.telling_apart)."""

    told_apart: bool
    p_value: float
    p_without_top: float
    rings_better: int
    rings: int


@dataclass(frozen=True)
class Separation:
    """The measurement that would best separate two confounded candidates (diagnosis.separation):
    empty when none tried lowers what their columns share."""

    measurement: str
    shared: float  # what their columns would share with it
    shared_now: float  # what they share over this campaign's touches


@dataclass(frozen=True)
class Partner:
    """A candidate this campaign's columns confound with another: what they share, what would
    separate them, and (for a claim or suggestion) whether the rings tell them apart."""

    effect: str
    shared: float  # the largest squared canonical correlation of their columns over the touches
    separated_by: Separation | None = None
    test: PairTest | None = None
    # The partner's settings that share that much, the closest first (partners.partner_settings: an
    # n/rev error seen through a lever turning once a revolution reads as n - 1 and n + 1).
    settings: tuple[dict[str, float], ...] = ()
    params: dict[str, float] = field(default_factory=dict)  # fitted at its first settings, when the rings were asked

    @property
    def told_apart(self) -> bool | None:
        """True or False when the rings were asked; None when they were not."""
        return None if self.test is None else self.test.told_apart

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"effect": self.effect, "shared": self.shared, "settings": list(self.settings)}
        if self.params:
            out["params"] = rounded(self.params)
        if self.separated_by is not None:
            out["separated_by"] = plain(self.separated_by)
        return out | (plain(self.test) if self.test is not None else {})

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Partner:
        test = PairTest(**{k: data[k] for k in names_of(PairTest)}) if "told_apart" in data else None
        separated = data.get("separated_by")
        return cls(
            data["effect"],
            data["shared"],
            Separation(**separated) if separated is not None else None,
            test,
            tuple(data.get("settings", ())),
            {k: v for k, v in data.get("params", {}).items() if v is not None},
        )


@dataclass(frozen=True)
class RivalSetting:
    """Of the settings the rings cannot exclude beside a claim's own (a period two off), the closest,
    fitted, with the rings' test (telling_apart.settings_told_apart)."""

    settings: dict[str, Any]
    params: dict[str, float]
    shared: float
    test: PairTest

    def to_json(self) -> dict[str, Any]:
        return {"settings": self.settings, "params": self.params, "shared": self.shared} | plain(self.test)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> RivalSetting:
        return cls(dict(data["settings"]), dict(data["params"]), data["shared"], PairTest(**{k: data[k] for k in names_of(PairTest)}))


@dataclass(frozen=True)
class UntoldShape:
    """A shape of a variable other than a claim's own (diagnosis.rival_shapes.untold_shape) that its
    rings cannot tell the claim from: the claim's gain over the shape's in its place, rings as units."""

    group: str  # error_functions.SHAPE_GROUPS key, e.g. "probe_time"
    words: str
    test: PairTest

    def to_json(self) -> dict[str, Any]:
        return {"group": self.group, "words": self.words} | plain(self.test)

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> UntoldShape:
        return cls(data["group"], data["words"], PairTest(**{k: data[k] for k in names_of(PairTest)}))


@dataclass(frozen=True)
class Candidate:
    """A catalog effect tested against the out-of-sample residual, with everything the diagnosis
    learnt of it. Frozen: each stage of the search returns a new one (dataclasses.replace)."""

    effect: str  # the effect's id
    name: str
    explained_fraction: float  # share of the out-of-sample residual (single touches) it explains
    error_reduction: float  # relative fall of the out-of-sample rms error against the exposing reference
    noise_fraction: float  # the largest share the same scan explains on pure noise
    significant: bool
    params: dict[str, float]
    params_u: dict[str, float]  # expanded uncertainty (k = 2, jackknife over orientations) of each parameter
    settings: dict[str, Any]  # the chosen values of the effect's scanned parameters
    teaching: str
    evidence: dict[str, Any] = field(default_factory=dict)
    note: str = ""  # in words: why it could not be tested, why its fit is not the explanation, ...
    beyond_noise: bool = False  # explains more than noise would, with a plausible fit (material or not)
    implausible: bool = False  # its best fit lies outside the effect's plausible ranges
    tested: bool = True  # False: the campaign cannot test it (note says why)
    confounded_with: tuple[Partner, ...] = ()  # the closest first
    # Significant, but its gain is not replicated over rings (diagnosis.replication): not a claim.
    suggested: bool = False
    replication: Replication | None = None  # for a candidate the search would take
    # Significant, but the model is within noise without it: nothing is missing that the campaign shows.
    not_needed: bool = False
    # Other scanned settings the data cannot exclude, e.g. a period one off: the touches' profile
    # likelihood (search.SETTINGS_NOT_EXCLUDED) or the rings as units (telling_apart.settings_told_apart).
    settings_not_excluded: tuple[dict[str, Any], ...] = ()
    rival_setting: RivalSetting | None = None
    # A shape of another variable its rings cannot tell a claim from (diagnosis.rival_shapes.untold_shape).
    untold_shape: UntoldShape | None = None
    # The shape group whose look carried the claim (diagnosis.catalog_behind; its note says how); "" for the search's own.
    on_shape: str = ""

    @classmethod
    def untested(cls, effect_id: str, name: str, teaching: str, note: str = "") -> Candidate:
        """An effect that explains nothing here, or could not be tested (note says why)."""
        return cls(effect_id, name, 0.0, 0.0, 0.0, False, {}, {}, {}, teaching, note=note, tested=not note)

    @property
    def status(self) -> Status:
        """Suggested (significant but not replicated over rings), not needed (significant, but the
        model is within noise without it), found (significant and replicated), beyond noise but
        not material (beyond the search's noise null with a plausible fit, but it lowers the error
        less than search.MATERIAL_REDUCTION: no claim), implausible (beyond
        twice the noise null only with an implausible fit), not significant, or not tested."""
        if self.suggested:
            return "suggested"
        if self.not_needed:
            return "not needed"
        if self.significant:
            return "found"
        if self.beyond_noise:
            return "beyond noise, not material"
        if self.implausible and self.explained_fraction > NULL_MARGIN * self.noise_fraction:
            return "implausible"
        return "not significant" if self.tested else "not tested"

    @property
    def form_broken(self) -> bool:
        """Its gain over rings is there, but its parameters differ over the head (diagnosis.form) or
        a shape of another variable predicts the rings better (rival_shapes.outpredicting_shape): no ring
        decides it, for no catalog effect has the head's form."""
        return self.replication is not None and (self.replication.form_breaks is not None or self.replication.outpredicted is not None)

    @property
    def untold(self) -> tuple[Partner, ...]:
        """The partners the rings were asked about and do not tell it from."""
        return tuple(p for p in self.confounded_with if p.told_apart is False)

    def to_json(self) -> dict[str, Any]:
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out |= {
            "status": self.status,
            "explained_fraction": round(self.explained_fraction, DIGITS),
            "error_reduction": round(self.error_reduction, DIGITS),
            "noise_fraction": round(self.noise_fraction, DIGITS),
            "params": rounded(self.params),
            "params_u": rounded(self.params_u),
            "confounded_with": [p.to_json() for p in self.confounded_with],
            "replication": {} if self.replication is None else self.replication.as_dict(),
            "settings_not_excluded": list(self.settings_not_excluded),
            "rival_setting": {} if self.rival_setting is None else self.rival_setting.to_json(),
            "untold_shape": {} if self.untold_shape is None else self.untold_shape.to_json(),
        }
        return out

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Candidate:
        plain = {name: data[name] for name in names_of(cls) if name in data}
        plain["params"] = {k: v for k, v in data["params"].items() if v is not None}
        plain["params_u"] = {k: v for k, v in data["params_u"].items() if v is not None}
        plain["confounded_with"] = tuple(Partner.from_json(p) for p in data.get("confounded_with", []))
        plain["replication"] = Replication.from_json(data["replication"]) if data.get("replication") else None
        plain["settings_not_excluded"] = tuple(data.get("settings_not_excluded", []))
        plain["rival_setting"] = RivalSetting.from_json(data["rival_setting"]) if data.get("rival_setting") else None
        plain["untold_shape"] = UntoldShape.from_json(data["untold_shape"]) if data.get("untold_shape") else None
        return cls(**plain)


def rounded(figures: Mapping[str, float | None]) -> dict[str, float | None]:
    """Figures for JSON: rounded, and null where a figure does not exist (one repetition has no floor)."""
    return {k: round(float(v), DIGITS) if v is not None and np.isfinite(v) else None for k, v in figures.items()}


def names_of(cls: type) -> list[str]:
    return [f.name for f in fields(cls)]


def plain(record: Any) -> dict[str, Any]:
    """A flat frozen record's fields as a JSON object."""
    return {f.name: getattr(record, f.name) for f in fields(record)}
