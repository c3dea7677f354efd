"""An adaptive campaign's records: the machine's cadence, a ring to measure, a plan (the rings to
measure next or the reason to stop), and the answer a plan read from its diagnosis. The plans
themselves: planning.adaptive. Method: docs/planning.md.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from itertools import permutations
from typing import Any

from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects.error_functions import SHAPE_GROUPS


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
    the same answer comes again with fresh check rings (docs/planning.md#the-stop). named: each claim
    and claimed shape with what these rings cannot tell it from (settings not excluded, untold
    partners and groups); the same answer is one these rings cannot tell from the last."""

    words: str
    check_rings: int
    named: tuple[tuple[str, tuple[str, ...]], ...] = ()

    @classmethod
    def of(cls, campaign: Campaign, result: Diagnosis) -> Answer:
        claims = [
            (
                _label(c.effect, c.settings),
                {_label(c.effect, s) for s in c.settings_not_excluded} | {_label(p.effect, s) for p in c.untold for s in p.settings},
            )
            for c in result.found
        ]
        shapes = [
            (f"a shape of the {s.words}", {f"a shape of the {SHAPE_GROUPS[g].words}" for g in s.untold}) for s in result.claimed_shapes
        ]
        named = [(label, tuple(sorted(untold - {label}))) for label, untold in [*sorted(claims), *sorted(shapes)]]
        words = "; ".join(label for label, _ in named)
        return cls(result.verdict + (f" ({words})" if words else ""), int(campaign.holdout_mask().sum()), tuple(named))

    def same_as(self, other: Answer) -> bool:
        """The same verdict, and its claims and shapes one to one, each the other's or one these rings
        cannot tell from it (the words alone for an answer without them: an older plan's)."""
        if not (self.named and other.named) or self.words.partition(" ")[0] != other.words.partition(" ")[0]:
            return self.words == other.words
        if len(self.named) != len(other.named):
            return False

        def alike(mine: tuple[str, tuple[str, ...]], theirs: tuple[str, tuple[str, ...]]) -> bool:
            return mine[0] == theirs[0] or mine[0] in theirs[1] or theirs[0] in mine[1]

        return any(all(map(alike, self.named, order)) for order in permutations(other.named))

    def to_json(self) -> dict[str, Any]:
        named = [{"label": label, "untold": list(untold)} for label, untold in self.named]
        return {"words": self.words, "check_rings": self.check_rings, "named": named}

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> Answer:
        named = tuple((str(n["label"]), tuple(str(u) for u in n["untold"])) for n in data.get("named", []))
        return cls(str(data["words"]), int(data["check_rings"]), named)


def _label(effect: str, settings: Mapping[str, float]) -> str:
    """A claim's name at its settings, e.g. "b_axis_cyclic cycles_per_rev 22"."""
    return effect + "".join(f" {k} {v:g}" for k, v in sorted(settings.items()))
