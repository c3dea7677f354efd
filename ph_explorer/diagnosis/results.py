"""The record of a diagnosis: one typed, frozen record built once by the loop (diagnosis.loop).

`Diagnosis.to_json()` is the `diagnose --json` object (its schema: docs/formats.md), and
`Diagnosis.from_json()` reads it back; figures are rounded to 0.01 nm and a figure that does not
exist (no noise floor with one repetition) is null, never NaN. Nothing here writes sentences: the
words are figures/diagnosis_text.py's. Method: docs/methods/diagnosis_loop.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import (
    Candidate,
    rounded,
)
from ph_explorer.diagnosis.replication import Replication
from ph_explorer.diagnosis.shapes import Shape
from ph_explorer.diagnosis.suspect import SuspectRing, judged_campaign
from ph_explorer.diagnosis.touch_outliers import TouchOutliers
from ph_explorer.diagnosis.within_noise import NoiseTest
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect
from ph_explorer.effects.error_functions import ErrorFunction
from ph_explorer.effects.shapes_file import shape_class
from ph_explorer.models.hybrid import HybridModel

SCHEMA_VERSION = 1  # of the diagnose --json object; a reader refuses another

Verdict = Literal["none", "missing", "suggested", "partial", "unexplained", "uncatalogued"]
# What the diagnosis can say of a campaign, and what each means.
VERDICTS: dict[Verdict, str] = {
    "none": "the campaign's within-noise test passes: what the model leaves of every ring but the worst is what its noise explains",
    "missing": "catalog effects found, replicated over rings, and with them the model is within noise",
    "suggested": "the model fails beyond noise; a catalog effect may explain it, but its gain is not replicated over rings",
    # A candidate whose gain is replicated but whose form breaks over the head explains nothing: `unexplained`.
    "partial": "catalog effects found, but the model still fails beyond noise with them",
    "unexplained": "the model fails beyond noise and no plausible catalog effect explains it",
    "uncatalogued": (
        "the model fails beyond noise where no catalog effect explains it, and an error function of the head's own "
        "variables does: a shape no catalog holds, replicated over rings"
    ),
}


@dataclass(frozen=True)
class ChainLink:
    """One effect of the model a study reached: at its scanned settings, with its joint fit +- U (k = 2)."""

    effect: str
    settings: dict[str, float]
    params: dict[str, float] = field(default_factory=dict)
    params_u: dict[str, float] = field(default_factory=dict)
    shape: dict[str, Any] | None = None  # a shape's table (its knots and values: it is in no catalog)

    def to_json(self) -> dict[str, Any]:
        out = {"effect": self.effect, "settings": self.settings, "params": self.params, "params_u": self.params_u}
        return out | ({"shape": self.shape} if self.shape is not None else {})

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> ChainLink:
        """A link of a record's JSON (a figure that does not exist is null there)."""
        figures = [{k: _number(v) for k, v in data.get(key, {}).items()} for key in ("params", "params_u")]
        return cls(data["effect"], dict(data["settings"]), *figures, data.get("shape"))


@dataclass(frozen=True)
class Step:
    """One step of the error history: the effects added so far and the held-out MAE with its floor."""

    added: tuple[str, ...]
    mae_um: dict[str, float]
    noise_floor_um: dict[str, float]
    params: tuple[dict[str, Any], ...] = ()
    model: str = ""  # the model this step measures: the baseline's name, or the hybrid and its data part

    def to_json(self) -> dict[str, Any]:
        return {
            "added": list(self.added),
            "model": self.model,
            "mae_um": rounded(self.mae_um),
            "noise_floor_um": rounded(self.noise_floor_um),
            "params": list(self.params),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Step:
        """A step of the JSON; KeyError, TypeError or ValueError when it is malformed."""
        return cls(
            tuple(str(e) for e in data["added"]),
            {k: _number(data["mae_um"][k]) for k in ("mean", "single")},
            {k: _number(data["noise_floor_um"][k]) for k in ("mean", "single")},
            tuple(data.get("params", [])),
            str(data.get("model", "")),
        )


@dataclass(frozen=True)
class NestedAfter:
    """Before and after the claimed effects, each fold's rings predicted by them fitted on the others."""

    folds: int
    rings: int  # rings predicted (each once)
    before_um: dict[str, float]  # MAE of the starting model, {"mean", "single"}
    after_um: dict[str, float]  # MAE with the claims, each fold's at its settings
    noise_floor_um: dict[str, float]
    chosen: tuple[tuple[str, ...], ...] = ()  # per fold, the claims at the settings its scans chose ("id 22/rev")
    # The replication test over the predicted rings of their fall in error from before to after;
    # None in a record written before it was measured.
    gain: Replication | None = None
    check_rings: int = 0  # of `rings`, the check rings (0 in a record of the training rings alone)

    @property
    def gain_holds(self) -> bool:
        """The claims refitted in the folds lower the error of rings that took no part in fitting
        them, replicated over those rings: the condition of a claim (nested.held_out_claims)."""
        return self.gain is None or self.gain.replicated

    def chosen_counts(self) -> dict[str, int]:
        """How many folds chose each claim's setting, in the order first chosen."""
        counts: dict[str, int] = {}
        for fold in self.chosen:
            for label in fold:
                counts[label] = counts.get(label, 0) + 1
        return counts

    def to_json(self) -> dict[str, Any]:
        return {
            "folds": self.folds,
            "rings": self.rings,
            "before_um": rounded(self.before_um),
            "after_um": rounded(self.after_um),
            "noise_floor_um": rounded(self.noise_floor_um),
            "chosen": [list(fold) for fold in self.chosen],
            "gain": None if self.gain is None else self.gain.as_dict(),
            "check_rings": self.check_rings,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> NestedAfter:
        figures = {k: {r: _number(v) for r, v in data[k].items()} for k in ("before_um", "after_um", "noise_floor_um")}
        gain = None if data.get("gain") is None else Replication.from_json(data["gain"])
        chosen = tuple(tuple(fold) for fold in data.get("chosen", []))
        return cls(data["folds"], data["rings"], **figures, chosen=chosen, gain=gain, check_rings=int(data.get("check_rings", 0)))


RING_TEST = "the within-noise test of one ring (level 1 %)"
RING_VERDICTS = ("within its noise", "exceeds its noise")  # the within-noise test of one ring, 0 and 1


@dataclass(frozen=True)
class Ring:
    """One ring's out-of-sample error against its own floor, and the test that flagged it."""

    a_deg: float
    b_deg: float
    held_out: bool  # a check ring (predicted by the baseline), else predicted leave-one-out
    mae_um: dict[str, float]  # {"mean", "single"}
    floor_um: dict[str, float]
    exceeds: bool | None  # the ring's within-noise test; None: untestable (one repetition)
    by_scatter: bool = False  # exceeds by the scatter between its repetitions, not by its mean

    @property
    def ratio(self) -> float:
        floor = self.floor_um["mean"]
        return self.mae_um["mean"] / floor if floor > 0 else float("inf")

    @property
    def exceeds_by(self) -> Literal["repetition mean", "scatter between repetitions"]:
        """Which of the ring test's two statistics flags it (docs/methods/within_noise.md)."""
        return "scatter between repetitions" if self.by_scatter else "repetition mean"

    def to_json(self) -> dict[str, Any]:
        mae, floor = rounded(self.mae_um), rounded(self.floor_um)
        # The ratio of the figures as written, so that a record read back writes the same.
        ratio = mae["mean"] / floor["mean"] if mae["mean"] is not None and floor["mean"] else None
        return {"A_deg": self.a_deg, "B_deg": self.b_deg, "held_out": self.held_out, "mae_um": mae, "floor_um": floor} | {
            "ratio": round(ratio, 3) if ratio is not None else None,
            "exceeds": self.exceeds,
            "test": RING_TEST,
            "exceeds_by": self.exceeds_by if self.exceeds else None,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Ring:
        figures = [{k: _number(v) for k, v in data[key].items()} for key in ("mae_um", "floor_um")]
        by_scatter = data.get("exceeds_by") == "scatter between repetitions"
        return cls(data["A_deg"], data["B_deg"], data["held_out"], *figures, data["exceeds"], by_scatter)


@dataclass(frozen=True)
class Headline:
    """The verdict and what it names: known before the error history is measured, so that a front
    end can say it first (diagnosis.loop.diagnose's on_verdict); a Diagnosis's own is its headline."""

    verdict: Verdict
    found: tuple[Candidate, ...]
    candidates: tuple[Candidate, ...]  # the first ranking: the settings of the partners a claim is named with
    shapes: tuple[Shape, ...] = ()

    @property
    def claimed_shapes(self) -> tuple[Shape, ...]:
        return tuple(s for s in self.shapes if s.claimed)


@dataclass(frozen=True)
class Diagnosis:
    """Everything one diagnosis found, in one record (docs/formats.md, "The diagnosis record")."""

    verdict: Verdict
    noise_floor_um: dict[str, float]
    baseline_model: str
    baseline_mae_um: dict[str, float]
    candidates: tuple[Candidate, ...]  # the first ranking, best first
    found: tuple[Candidate, ...]  # the effects found, in the order the search added them (each re-ranked)
    suggested: tuple[Candidate, ...]  # candidates the search would take whose gain is not replicated over rings
    not_needed: tuple[Candidate, ...]  # significant, but the model is within noise without them
    signature: tuple[dict[str, Any], ...]  # what is left, in the head's variables (partial, unexplained)
    # "baseline", "after" (the effects found) and, with a base model, "base" (what the verdict judges); None: untestable
    within_noise: dict[str, NoiseTest | None]
    steps: tuple[Step, ...]
    rings: tuple[Ring, ...]  # every ring but the suspect ones, in the campaign's order
    # The rankings after each step of the search (before each next step, and after the last).
    reranked: tuple[tuple[Candidate, ...], ...] = ()
    nested: NestedAfter | None = None  # the honest "after" (ph_explorer.diagnosis.nested)
    chain: tuple[Effect, ...] = ()  # the last step's effects, at their settings
    started_from: int = 0  # how many of them were in the model before this run (the base, a resumed study's)
    base: tuple[ChainLink, ...] = ()  # the chain's first effects, fitted and never claimed (diagnose's base), +- U
    base_unused: tuple[str, ...] = ()  # the base model's effects these rings predict better without (choice.usable_base)
    suspect_rings: tuple[SuspectRing, ...] = ()  # rings measured badly: named, left out of everything above
    touch_outliers: TouchOutliers | None = None  # touches read far off (None: too few repetitions to tell)
    # Shapes no catalog holds (diagnosis.shapes): those claimed, then the best tried and not claimed.
    shapes: tuple[Shape, ...] = ()
    # The last step's fitted model: the process's, never in the JSON.
    hybrid: HybridModel | None = field(default=None, compare=False, repr=False)

    schema_version = SCHEMA_VERSION

    def judged(self, campaign: Campaign) -> Campaign:
        """The campaign as this diagnosis judged it (suspect.judged_campaign): what its model was fitted on."""
        return judged_campaign(campaign, self.suspect_rings, self.touch_outliers)

    @property
    def rankings(self) -> tuple[tuple[Candidate, ...], ...]:
        """The candidate table before every step of the search and after its last."""
        return (self.candidates, *self.reranked)

    @property
    def orientations(self) -> NDArray[np.float64]:
        return np.array([[r.a_deg, r.b_deg] for r in self.rings], dtype=float).reshape(-1, 2)

    @property
    def held_out(self) -> NDArray[np.bool_]:
        return np.array([r.held_out for r in self.rings], dtype=bool)

    @property
    def failing(self) -> NDArray[np.bool_]:
        """The rings the within-noise test finds beyond their noise (none when untestable)."""
        return np.array([bool(r.exceeds) for r in self.rings], dtype=bool)

    @property
    def tested(self) -> bool:
        """Whether the rings could be tested against their noise (more than one repetition)."""
        return self.within_noise.get("baseline") is not None

    @property
    def out_of_sample_mae_um(self) -> dict[str, NDArray[np.float64]]:
        return {k: np.array([r.mae_um[k] for r in self.rings]) for k in ("mean", "single")}

    @property
    def out_of_sample_floor_um(self) -> dict[str, NDArray[np.float64]]:
        return {k: np.array([r.floor_um[k] for r in self.rings]) for k in ("mean", "single")}

    @property
    def leaves_open(self) -> bool:
        """Whether rings could decide something this diagnosis leaves open: a claimed or suggested
        candidate its rings do not tell from a confounded partner, a claim from its rival setting,
        or a suggested one (planning.deciding)."""
        untold = any(c.untold for c in (*self.found, *self.open_suggestions))
        return bool(self.open_suggestions) or untold or any(c.rival_setting is not None for c in self.found)

    @property
    def open_suggestions(self) -> tuple[Candidate, ...]:
        """The suggestions more rings could confirm: all but those whose form breaks over the head."""
        return tuple(c for c in self.suggested if not c.form_broken)

    @property
    def headline(self) -> Headline:
        return Headline(self.verdict, self.found, self.candidates, self.shapes)

    @property
    def claimed_shapes(self) -> tuple[Shape, ...]:
        return self.headline.claimed_shapes

    @property
    def model_effects(self) -> tuple[Effect, ...]:
        """The effects of the last step's model: the chain, then the shapes claimed and added as a step."""
        added = self.steps[-1].added if self.steps else ()
        return (*self.chain, *(shape.effect() for shape in self.claimed_shapes if shape.id in added[len(self.chain) :]))

    def failing_rings(self) -> list[Ring]:
        """The rings that exceed their noise (the within-noise test), worst first: by how far their
        out-of-sample MAE is above its own floor, not by their roundness (a round ring may be badly predicted)."""
        return sorted((r for r in self.rings if r.exceeds), key=lambda ring: -ring.ratio)

    def to_json(self) -> dict[str, Any]:
        """The diagnose --json object (docs/formats.md)."""
        return {
            "schema_version": SCHEMA_VERSION,
            "verdict": self.verdict,
            "noise_floor_um": rounded(self.noise_floor_um),
            "baseline": {"model": self.baseline_model, "mae_um": rounded(self.baseline_mae_um)},
            "candidates": [c.to_json() for c in self.candidates],
            "found": [c.to_json() for c in self.found],
            "suggested": [c.to_json() for c in self.suggested],
            "not_needed": [c.to_json() for c in self.not_needed],
            "reranked": [[c.to_json() for c in ranking] for ranking in self.reranked],
            "signature": list(self.signature),
            "within_noise": {k: None if t is None else t.as_dict() for k, t in self.within_noise.items()},
            "nested_after": None if self.nested is None else self.nested.to_json(),
            "steps": [s.to_json() for s in self.steps],
            "chain": [chain_entry(e) for e in self.chain],
            "started_from": self.started_from,
            "base": [link.to_json() | {"params": rounded(link.params), "params_u": rounded(link.params_u)} for link in self.base],
            "base_unused": list(self.base_unused),
            "suspect_rings": [r.to_json() for r in self.suspect_rings],
            "touch_outliers": None if self.touch_outliers is None else self.touch_outliers.to_json(),
            "shapes": [shape.to_json() for shape in self.shapes],
            "where_it_fails": [r.to_json() for r in self.rings if r.exceeds],
            "rings": [r.to_json() for r in self.rings],
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any], catalog: Catalog = DEFAULT_CATALOG) -> Diagnosis:
        """The record of a diagnose --json object (its chain's effects from the catalog); a
        ValueError when its schema_version is not this version's."""
        if data.get("schema_version") != SCHEMA_VERSION:
            raise ValueError(f"schema_version {data.get('schema_version')!r} is not {SCHEMA_VERSION}")
        rankings = [tuple(Candidate.from_json(c) for c in data[key]) for key in ("candidates", "found", "suggested", "not_needed")]
        return cls(
            verdict=data["verdict"],
            noise_floor_um={k: _number(v) for k, v in data["noise_floor_um"].items()},
            baseline_model=data["baseline"]["model"],
            baseline_mae_um={k: _number(v) for k, v in data["baseline"]["mae_um"].items()},
            candidates=rankings[0],
            found=rankings[1],
            suggested=rankings[2],
            not_needed=rankings[3],
            reranked=tuple(tuple(Candidate.from_json(c) for c in ranking) for ranking in data["reranked"]),
            signature=tuple(data["signature"]),
            within_noise={k: None if t is None else NoiseTest.from_json(t) for k, t in data["within_noise"].items()},
            nested=None if data["nested_after"] is None else NestedAfter.from_json(data["nested_after"]),
            steps=tuple(Step.from_json(s) for s in data["steps"]),
            chain=tuple(chain_effect(e, catalog) for e in data["chain"]),
            started_from=data["started_from"],
            base=tuple(ChainLink.from_json(link) for link in data.get("base", [])),
            base_unused=tuple(data.get("base_unused", [])),
            suspect_rings=tuple(SuspectRing.from_json(r) for r in data.get("suspect_rings", [])),
            touch_outliers=None if data.get("touch_outliers") is None else TouchOutliers.from_json(data["touch_outliers"]),
            shapes=tuple(Shape.from_json(shape) for shape in data.get("shapes", [])),
            rings=tuple(Ring.from_json(r) for r in data["rings"]),
        )


def chain_entry(effect: Effect) -> dict[str, Any]:
    """A chain's effect in a record or a study: its id and settings; a shape also its table (its knots
    and values: it is in no catalog)."""
    entry: dict[str, Any] = {"effect": effect.id, "settings": {k: float(v) for k, v in effect.settings().items()}}
    return entry | ({"shape": effect.table()} if isinstance(effect, ErrorFunction) else {})


def chain_effect(entry: Mapping[str, Any], catalog: Catalog) -> Effect:
    """The effect of a chain entry (chain_entry): from the catalog at its settings, or a shape from its
    table; ValueError when the table is not one."""

    def bad(message: str, column: str | None = None) -> ValueError:
        return ValueError(f"chain entry {entry.get('effect')!r}, {column}: {message}")

    if "shape" in entry:
        return shape_class(entry["shape"], bad)()
    return catalog[entry["effect"]]().with_settings(**entry["settings"])


def flagged_in(rankings: Sequence[Sequence[Candidate]], flag: str) -> tuple[Candidate, ...]:
    """The candidates of these rankings with this flag set (suggested, not_needed), each effect once (as first seen)."""
    seen: dict[str, Candidate] = {}
    for ranking in rankings:
        for c in ranking:
            if getattr(c, flag):
                seen.setdefault(c.effect, c)
    return tuple(seen.values())


def _number(value: float | None) -> float:
    """A JSON figure back as a float: null is NaN (a figure that does not exist)."""
    return float("nan") if value is None else float(value)
