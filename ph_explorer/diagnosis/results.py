"""What a diagnosis finds, as data: candidates, steps of the error history, and the whole result.

`Diagnosis.as_dict()` is the `diagnose --json` object; figures are rounded to 0.01 nm and a figure
that does not exist (no noise floor with one repetition) is null, never NaN.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.models.hybrid import HybridModel

DIGITS = 5


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
    settings: dict[str, Any]  # the chosen values of the effect's scanned parameters
    teaching: str
    evidence: dict[str, Any] = field(default_factory=dict)
    note: str = ""  # why the effect could not be tested on this campaign, if it could not

    @classmethod
    def untested(cls, effect_id: str, name: str, teaching: str, note: str = "") -> "Candidate":
        """An effect that explains nothing here (or could not be tested: note says why)."""
        return cls(effect_id, name, 0.0, 0.0, 0.0, False, {}, {}, teaching, note=note)

    def as_dict(self) -> dict[str, Any]:
        out = asdict(self)
        for key in ("explained_fraction", "error_reduction", "noise_fraction"):
            out[key] = round(out[key], DIGITS)
        out["params"] = rounded(self.params)
        return out


@dataclass
class Step:
    """One step of the error history: the effects added so far and the held-out MAE with its floor."""

    added: list[str]
    mae_um: dict[str, float]
    noise_floor_um: dict[str, float]
    params: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class Diagnosis:
    noise_floor_um: dict[str, float]
    baseline_model: str
    baseline_mae_um: dict[str, float]
    candidates: list[Candidate]
    verdict: str  # "missing" or "none"
    steps: list[Step]
    orientations: NDArray[np.float64]
    out_of_sample_mae_um: dict[str, NDArray[np.float64]]  # per orientation: "mean", "single"
    out_of_sample_floor_um: dict[str, NDArray[np.float64]]
    failing: NDArray[np.bool_]  # orientations significantly worse than their floor
    held_out: NDArray[np.bool_]
    hybrid: HybridModel | None = None

    def as_dict(self) -> dict[str, Any]:
        """The diagnose --json object."""
        return {
            "noise_floor_um": rounded(self.noise_floor_um),
            "baseline": {"model": self.baseline_model, "mae_um": rounded(self.baseline_mae_um)},
            "candidates": [c.as_dict() for c in self.candidates],
            "verdict": self.verdict,
            "steps": [
                {"added": s.added, "mae_um": rounded(s.mae_um), "noise_floor_um": rounded(s.noise_floor_um), "params": s.params}
                for s in self.steps
            ],
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


def rounded(figures: dict[str, float]) -> dict[str, float | None]:
    """Figures for JSON: rounded, and null where a figure does not exist (one repetition has no floor)."""
    return {k: round(float(v), DIGITS) if np.isfinite(v) else None for k, v in figures.items()}
