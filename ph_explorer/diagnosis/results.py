"""What a diagnosis finds, as data: candidates, steps of the error history, and the whole result.

`Diagnosis.as_dict()` is the `diagnose --json` object; figures are rounded to 0.01 nm and a figure
that does not exist (no noise floor with one repetition) is null, never NaN.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.diagnosis.within_noise import NoiseTest
from ph_explorer.effects import Catalog, Effect, effect_label, settings_text
from ph_explorer.models.hybrid import HybridModel

DIGITS = 5
NULL_MARGIN = 2.0  # a candidate is beyond noise when it explains more than this multiple of the noise null
# What the diagnosis can say of a campaign, and what each means.
VERDICTS = {
    "none": "the campaign's within-noise test passes: what the model leaves of every ring but the worst is what its noise explains",
    "missing": "catalog effects found, replicated over rings, and with them the model is within noise",
    "suggested": "the model fails beyond noise; a catalog effect may explain it, but its gain is not replicated over rings",
    "partial": "catalog effects found, but the model still fails beyond noise with them",
    "unexplained": "the model fails beyond noise and no plausible catalog effect explains it",
}


@dataclass
class Candidate:
    """A catalog effect tested against the out-of-sample residual."""

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
    note: str = ""  # why the effect could not be tested on this campaign, or why its fit is not the explanation
    beyond_noise: bool = False  # explains more than noise would, with a plausible fit (material or not)
    # Other candidates this campaign cannot tell it from: [{"effect": id, "shared": squared canonical correlation}]
    confounded_with: list[dict[str, Any]] = field(default_factory=list)
    # Significant, but its gain is not replicated over rings (diagnosis.replication): not a claim.
    suggested: bool = False
    replication: dict[str, Any] = field(default_factory=dict)  # Replication.as_dict(), for a candidate the search would take
    # Significant, but the model is within noise without it: nothing is missing that the campaign shows.
    not_needed: bool = False
    # Other scanned settings the data cannot exclude, e.g. a period one off: the touches' profile
    # likelihood (search.SETTINGS_NOT_EXCLUDED) or the rings as units (telling_apart.settings_told_apart).
    settings_not_excluded: list[dict[str, Any]] = field(default_factory=list)
    # Of those the rings cannot exclude, the closest (telling_apart.settings_told_apart), fitted, and its test.
    rival_setting: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def untested(cls, effect_id: str, name: str, teaching: str, note: str = "") -> Candidate:
        """An effect that explains nothing here (or could not be tested: note says why)."""
        return cls(effect_id, name, 0.0, 0.0, 0.0, False, {}, {}, {}, teaching, note=note)

    @property
    def status(self) -> str:
        """In words: suggested (significant but not replicated over rings), not needed (significant,
        but the model is within noise without it), found (significant and replicated), present but
        already captured by the data model (beyond noise and plausible, not material), implausible,
        not significant, or not tested."""
        if self.suggested:
            return "suggested"
        if self.not_needed:
            return "not needed"
        if self.significant:
            return "found"
        if self.beyond_noise:
            return "present, already captured by the data model"
        if self.note.startswith("best catalog fit implausible") and self.explained_fraction > NULL_MARGIN * self.noise_fraction:
            return "implausible"
        return "not tested" if self.note and not self.explained_fraction else "not significant"

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["status"] = self.status
        for key in ("explained_fraction", "error_reduction", "noise_fraction"):
            out[key] = round(out[key], DIGITS)
        out["params"] = rounded(self.params)
        out["params_u"] = rounded(self.params_u)
        return out


@dataclass
class Step:
    """One step of the error history: the effects added so far and the held-out MAE with its floor."""

    added: list[str]
    mae_um: dict[str, float]
    noise_floor_um: dict[str, float]
    params: list[dict[str, Any]] = field(default_factory=list)
    model: str = ""  # the model this step measures: the baseline's name, or the hybrid and its data part


@dataclass
class NestedAfter:
    """Before and after the search's effects, each fold's rings predicted by what the others chose."""

    folds: int
    rings: int  # training rings predicted (each once)
    before_um: dict[str, float]  # MAE of the starting model, {"mean", "single"}
    after_um: dict[str, float]  # MAE with the effects each fold's search chose
    noise_floor_um: dict[str, float]
    chosen: list[list[str]] = field(default_factory=list)  # per fold, the effects chosen ("id 22/rev")

    def as_dict(self) -> dict[str, Any]:
        return {
            "folds": self.folds,
            "rings": self.rings,
            "before_um": rounded(self.before_um),
            "after_um": rounded(self.after_um),
            "noise_floor_um": rounded(self.noise_floor_um),
            "chosen": self.chosen,
        }


@dataclass(frozen=True)
class FailingRing:
    """A ring the within-noise test finds beyond its noise: its out-of-sample MAE and floor (vs the mean)."""

    a_deg: float
    b_deg: float
    mae_um: float
    floor_um: float
    held_out: bool  # a check ring (predicted by the baseline), else predicted leave-one-out
    by_scatter: bool = False  # exceeds by the scatter between its repetitions, not by its mean

    @property
    def ratio(self) -> float:
        return self.mae_um / self.floor_um if self.floor_um > 0 else float("inf")

    @property
    def reason(self) -> str:
        """By which of the test's two statistics the ring exceeds (docs/methods/within_noise.md)."""
        return "by the scatter between its repetitions (harmonics 2-8)" if self.by_scatter else "by its repetition mean"


RING_VERDICTS = ("within its noise", "exceeds its noise")  # the within-noise test of one ring, 0 and 1


@dataclass
class Diagnosis:
    noise_floor_um: dict[str, float]
    baseline_model: str
    baseline_mae_um: dict[str, float]
    candidates: list[Candidate]
    verdict: str  # a key of VERDICTS
    found: list[Candidate]  # the effects found, in the order the search added them (each re-ranked)
    signature: list[dict[str, Any]]  # what is left, in the head's variables (partial, unexplained)
    within_noise: dict[str, NoiseTest | None]  # "baseline" and "after" (the effects found); None: untestable
    steps: list[Step]
    orientations: NDArray[np.float64]
    out_of_sample_mae_um: dict[str, NDArray[np.float64]]  # per orientation: "mean", "single"
    out_of_sample_floor_um: dict[str, NDArray[np.float64]]
    failing: NDArray[np.bool_]  # orientations significantly worse than their floor
    held_out: NDArray[np.bool_]
    hybrid: HybridModel | None = None
    # The candidate table before every step of the search and after its last (the first is `candidates`).
    rankings: list[list[Candidate]] = field(default_factory=list)
    nested: NestedAfter | None = None  # the honest "after" (ph_explorer.diagnosis.nested)
    chain: list[Effect] = field(default_factory=list)  # the last step's effects, at their settings
    started_from: int = 0  # how many of them were in the model before this run (a resumed study)

    @staticmethod
    def steps_dict(steps: list[Step]) -> list[dict[str, Any]]:
        """Steps as the JSON gives them."""
        return [
            {
                "added": s.added,
                "model": s.model,
                "mae_um": rounded(s.mae_um),
                "noise_floor_um": rounded(s.noise_floor_um),
                "params": s.params,
            }
            for s in steps
        ]

    @property
    def suggested(self) -> list[Candidate]:
        """Candidates the search would have taken whose gain is not replicated over rings."""
        return flagged_in(self.rankings or [self.candidates], "suggested")

    @property
    def leaves_open(self) -> bool:
        """Whether rings could decide something this diagnosis leaves open: a claimed or suggested
        candidate its rings do not tell from a confounded partner, a claim from its rival setting,
        or a suggested one (planning.deciding)."""
        candidates = [*self.found, *self.suggested]
        untold = any(o.get("told_apart") is False for c in candidates for o in c.confounded_with)
        return bool(self.suggested) or untold or any(c.rival_setting for c in self.found)

    @property
    def not_needed(self) -> list[Candidate]:
        """Significant candidates the search did not take because the model was within noise without them."""
        return flagged_in(self.rankings or [self.candidates], "not_needed")

    def failing_rings(self) -> list[FailingRing]:
        """The rings that exceed their noise (the within-noise test), worst first: by how far their
        out-of-sample MAE is above its own floor, not by their roundness (a round ring may be badly predicted)."""
        mae, floor = self.out_of_sample_mae_um["mean"], self.out_of_sample_floor_um["mean"]
        test = self.within_noise.get("baseline")
        by_scatter = test.ring_by_scatter if test is not None else np.zeros(len(self.failing), dtype=bool)
        rings = [
            FailingRing(
                float(self.orientations[i, 0]),
                float(self.orientations[i, 1]),
                float(mae[i]),
                float(floor[i]),
                bool(self.held_out[i]),
                bool(by_scatter[i]),
            )
            for i in np.flatnonzero(self.failing)
        ]
        return sorted(rings, key=lambda ring: -ring.ratio)

    def as_dict(self) -> dict[str, Any]:
        """The diagnose --json object."""
        return {
            "noise_floor_um": rounded(self.noise_floor_um),
            "baseline": {"model": self.baseline_model, "mae_um": rounded(self.baseline_mae_um)},
            "candidates": [c.as_dict() for c in self.candidates],
            "verdict": self.verdict,
            "found": [
                {k: c.as_dict()[k] for k in ("effect", "params", "params_u", "settings", "settings_not_excluded", "replication")}
                for c in self.found
            ],
            "suggested": [
                {k: c.as_dict()[k] for k in ("effect", "params", "params_u", "settings", "replication", "note")} for c in self.suggested
            ],
            "not_needed": [
                {k: c.as_dict()[k] for k in ("effect", "params", "params_u", "settings", "error_reduction")} for c in self.not_needed
            ],
            "signature": self.signature,
            "within_noise": {k: None if t is None else t.as_dict() for k, t in self.within_noise.items()},
            "nested_after": None if self.nested is None else self.nested.as_dict(),
            "steps": self.steps_dict(self.steps),
            "where_it_fails": [
                {
                    "A_deg": float(a),
                    "B_deg": float(b),
                    "held_out": bool(h),
                    "mae_um": rounded({k: v[i] for k, v in self.out_of_sample_mae_um.items()}),
                    "floor_um": rounded({k: v[i] for k, v in self.out_of_sample_floor_um.items()}),
                }
                for i, ((a, b), h) in enumerate(zip(self.orientations, self.held_out))
                if self.failing[i]
            ],
        }


def flagged_in(rankings: list[list[Candidate]], flag: str) -> list[Candidate]:
    """The candidates of these rankings with this flag set (suggested, not_needed), each effect once (as first seen)."""
    seen: dict[str, Candidate] = {}
    for ranking in rankings:
        for c in ranking:
            if getattr(c, flag):
                seen.setdefault(c.effect, c)
    return list(seen.values())


def verdict_text(result: Diagnosis, catalog: Catalog) -> tuple[str, list[str]]:
    """The verdict as a headline and its explanation, in words (the CLI and the app show the same)."""
    before, after = result.within_noise["baseline"], result.within_noise["after"]
    found = "; ".join(f"{c.effect} ({catalog[c.effect].parameters_text(c.params, c.params_u)})" for c in result.found)
    headline = f"Verdict: {result.verdict} - {VERDICTS[result.verdict]}."
    lines = []
    if result.started_from:
        already = ", ".join(effect_label(e) for e in result.chain[: result.started_from])
        lines.append(f"Resumed with {already} in the model; the search continued from there.")
    if result.verdict in ("missing", "partial") and result.found:
        lines.append(f"Found: {found} (+- expanded uncertainty, k = 2).")
        for c in result.found:
            effect = catalog[c.effect]().with_settings(**c.settings)
            if c.settings_not_excluded:
                others = settings_text(effect, c.settings_not_excluded)
                lines.append(f"{c.effect}: the campaign cannot exclude {others} beside the setting found (95 %).")
            if r := c.rival_setting:
                lines.append(
                    f"{effect_label(effect)}: the rings cannot tell it from {settings_text(effect, [r['settings']])} ({told_apart_text(r)}); "
                    "which rings would: Rings that would decide (explorer), or ph-explorer design --data FILE.csv --decide."
                )
    test = after if result.verdict in ("missing", "partial") else before
    if test is None:
        lines.append("One repetition: no repetition spread, so 'within noise' could not be tested.")
    else:
        model = "with them" if result.verdict in ("missing", "partial") else "the baseline"
        lines.append(
            f"Within-noise test ({model}): {test.failing_rings} of {len(test.ring_p_value)} rings exceed their noise; "
            f"by how much, summed over all rings but the worst: {test.statistic:.1f}, and the campaign fails above "
            f"{test.critical:.1f} (p = {test.p_value:.3g}; false-alarm rate {100 * test.as_dict()['false_alarm_rate']:.0f} %)"
            + (
                ": the campaign is within noise, though a few rings exceed at the ring level (1 %), as noise alone makes some."
                if test.failing_rings and not test.fails
                else "."
            )
        )
    for candidate in result.suggested:
        lines.append(
            f"Suggested, not claimed: {candidate.effect} ({catalog[candidate.effect].parameters_text(candidate.params, candidate.params_u)}); "
            f"{candidate.note}. More rings where it predicts the largest difference would confirm or refute it."
        )
    for candidate in result.not_needed:
        lines.append(
            f"Not needed: {candidate.effect} ({catalog[candidate.effect].parameters_text(candidate.params, candidate.params_u)}) "
            f"would lower the check rings' error by {100 * candidate.error_reduction:.0f} %, but the model is within noise "
            "without it: nothing the campaign shows is missing, so it is not claimed."
        )
    if result.verdict == "unexplained":
        implausible = [f"{c.effect}: {c.note}" for c in result.candidates if c.note.startswith("best catalog fit implausible")]
        lines += implausible or ["No candidate explains more than noise would and lowers the held-out error materially."]
    significant = [entry for entry in result.signature if entry["significant"]]
    if result.verdict in ("partial", "unexplained"):
        lines.append(
            "What is left, in the head's own variables (share of the residual explained; noise alone): "
            + (
                "; ".join(signature_text(entry) for entry in significant[:5])
                if significant
                else "nothing beyond noise in any single variable"
            )
            + "."
        )
    for candidate in result.found or [c for c in result.candidates if c.beyond_noise]:
        told = [o for o in candidate.confounded_with if o.get("told_apart")]
        untold = [o for o in candidate.confounded_with if not o.get("told_apart")]
        for other in told:
            lines.append(f"{shared_text(candidate.effect, other)}, yet the rings tell them apart: {told_apart_text(other)}.")
        for other in untold:
            told = f" ({told_apart_text(other)})" if "told_apart" in other else ""
            lines.append(
                f"{shared_text(candidate.effect, other)}: this campaign cannot tell them apart{told}; the credit is not theirs to split."
            )
        if untold:
            if any("told_apart" in o for o in untold):
                lines.append(
                    "Which rings would tell them apart: Rings that would decide (explorer), or ph-explorer design --data FILE.csv --decide."
                )
            lines += [text for other in untold if (text := separation_text(candidate.effect, other))]
    if result.verdict in ("missing", "partial") and result.found:
        lines.append(result.found[0].teaching)
    return headline, lines


def exceeding_text(count: int) -> str:
    """'1 ring exceeds its noise', '3 rings exceed their noise'."""
    return "1 ring exceeds its noise" if count == 1 else f"{count} rings exceed their noise"


def shared_text(effect: str, other: Mapping[str, Any]) -> str:
    """What a confounded partner's share means: '93 % of what this campaign shows of X is also
    explained by Y' (the largest squared canonical correlation of their columns over the touches)."""
    return f"{percent(other['shared'])} of what this campaign shows of {effect} is also explained by {other['effect']}"


def percent(share: float) -> str:
    """'83 %', '99.6 %': a share near 1 keeps a decimal (rounded to 100 % it would read as identical)."""
    return f"{100 * share:.1f} %" if 0.995 <= share < 1.0 else f"{100 * share:.0f} %"


def told_apart_text(other: dict[str, Any]) -> str:
    """'better on 10 of 12 rings, p = 0.002 (0.004 without the top ring)': diagnosis.telling_apart in words."""
    return f"better on {other['rings_better']} of {other['rings']} rings, p = {other['p_value']:.3g} ({other['p_without_top']:.3g} without the top ring)"


def separation_text(effect: str, other: dict[str, Any]) -> str:
    """What would tell an effect from a confounded one (search.confounding, diagnosis.separation)."""
    separated = other.get("separated_by")
    if separated is None:
        return ""
    now = f"{100 * separated['shared_now']:.0f} %"
    if not separated["measurement"]:
        return (
            f"To tell {effect} from {other['effect']}: none of the measurements tried (rings near A0 = 0, off-grid rings, "
            f"a reversed scan, a longer stylus) lowers what their columns share over the touches alone ({now})."
        )
    return (
        f"To tell {effect} from {other['effect']}: measure {separated['measurement']}; over the touches alone their "
        f"columns would share {100 * separated['shared']:.0f} % instead of {now}."
    )


def signature_text(entry: dict[str, Any]) -> str:
    """'b_joint_deg periodic, 22 cycles/rev, 8.4 % (0.07 %)': one entry of a signature in words."""
    setting = {
        "cycles_per_rev": "{:g} cycles/rev",
        "cycles_per_span": "{:g} cycles over its span",
        "centre_deg": "at {:g} deg",
        "centre_s": "at {:g} s",
        "centre_touch": "at touch {:g}",
        "joint": "{} joint",
    }
    where = ", ".join(text.format(entry[key]) for key, text in setting.items() if key in entry)
    return (
        f"{entry['variable']} {entry['kind']}, {where}, {100 * entry['explained_fraction']:.1f} % ({100 * entry['noise_fraction']:.2f} %)"
    )


def rounded(figures: dict[str, float]) -> dict[str, float | None]:
    """Figures for JSON: rounded, and null where a figure does not exist (one repetition has no floor)."""
    return {k: round(float(v), DIGITS) if np.isfinite(v) else None for k, v in figures.items()}
