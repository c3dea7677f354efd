"""An adaptive campaign's records: the machine's cadence, a ring to measure, a plan (the rings to
measure next or the reason to stop), and the answer a plan read from its diagnosis. The plans
themselves: planning.adaptive. Method: docs/planning.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.diagnosis.results import Diagnosis


@dataclass(frozen=True)
class Cadence:
    """How long the machine takes: seconds per touch and per move between circles (the twin's defaults)."""

    touch_s: float = 2.0
    move_s: float = 8.0

    def ring_minutes(self, repetitions: int, n_points: int) -> float:
        """Minutes of one ring: its repetitions of n_points touches, a move before each."""
        return repetitions * (n_points * self.touch_s + self.move_s) / 60.0


DEFAULT_CADENCE = Cadence()


@dataclass(frozen=True)
class PlannedRing:
    """A ring to measure and why; check rings are held out of every fit."""

    a_deg: float
    b_deg: float
    reason: str
    check: bool

    def to_json(self, order: int = 0) -> dict[str, Any]:
        return {"A_deg": self.a_deg, "B_deg": self.b_deg, "order": order, "reason": self.reason, "check": self.check}


@dataclass(frozen=True)
class Plan:
    """The rings to measure next (in this order), or the reason to stop, and the time they take."""

    rings: tuple[PlannedRing, ...]
    stop: bool
    reason: str
    minutes: float  # at the machine, for these rings
    repetitions: int
    measured_rings: int = 0
    spent_minutes: float = 0.0  # at the machine so far
    budget_minutes: float | None = None
    verdict: str | None = None  # the diagnosis the plan answers (None: no data yet)
    questions: tuple[str, ...] = ()  # every question asked so far (planning.deciding): the next plan asks none again
    unseen_um: tuple[float, float, float] | None = None  # missed at unseen rings: estimate, 95 % upper, tolerance
    answer: Answer | None = None  # what the diagnosis the plan read answered (None: no data yet)

    def to_json(self) -> dict[str, Any]:
        return {
            "rings": [ring.to_json(order) for order, ring in enumerate(self.rings, start=1)],
            "stop": self.stop,
            "reason": self.reason,
            "minutes": round(self.minutes, 1),
            "repetitions": self.repetitions,
            "measured_rings": self.measured_rings,
            "spent_minutes": round(self.spent_minutes, 1),
            "budget_minutes": self.budget_minutes,
            "verdict": self.verdict,
            "questions": list(self.questions),
            "unseen_error_um": None if self.unseen_um is None else dict(zip(("estimate", "upper95", "tolerance"), self.unseen_um)),
            "answer": None if self.answer is None else self.answer.to_json(),
        }

    def lines(self) -> list[str]:
        """The plan in words: the head line, one line a ring, the time."""
        so_far = f" after {self.measured_rings} rings ({self.spent_minutes:.0f} min)" if self.measured_rings else ""
        if self.stop:
            return [f"stop{so_far}: {self.reason}"]
        head = f"measure {len(self.rings)} rings{so_far}, {self.repetitions} repetitions each, in this order: {self.reason}"
        rings = [
            f"{k:>3}. {orientation_label(r.a_deg, r.b_deg):<12} {'check' if r.check else 'fit  '}  {r.reason}"
            for k, r in enumerate(self.rings, start=1)
        ]
        budget = "" if self.budget_minutes is None else f" of a budget of {self.budget_minutes:g}"
        return [head, *rings, f"about {self.minutes:.0f} minutes at the machine ({self.spent_minutes + self.minutes:.0f}{budget} in all)"]


@dataclass(frozen=True)
class Answer:
    """What a diagnosis answered, in words that compare (its verdict, its claims at their settings,
    the shapes it claimed), and the check rings it was judged on: an adaptive campaign stops once
    the same answer comes again with fresh check rings (docs/planning.md#the-stop)."""

    words: str
    check_rings: int

    @classmethod
    def of(cls, campaign: Campaign, result: Diagnosis) -> Answer:
        claims = sorted(c.effect + "".join(f" {k} {v:g}" for k, v in sorted(c.settings.items())) for c in result.found)
        named = "; ".join([*claims, *sorted(f"a shape of the {s.words}" for s in result.claimed_shapes)])
        return cls(result.verdict + (f" ({named})" if named else ""), int(campaign.holdout_mask().sum()))

    def to_json(self) -> dict[str, Any]:
        return {"words": self.words, "check_rings": self.check_rings}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Answer:
        return cls(str(data["words"]), int(data["check_rings"]))
