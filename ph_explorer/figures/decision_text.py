"""The rings that decide in words: the one renderer of planning.deciding's Decision that the command
line (`design --decide`), the explorer's "Rings that would decide" and the verdict's next step show.
Method: docs/methods/deciding.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ph_explorer.campaign import orientation_label
from ph_explorer.planning.deciding import BEYOND_BUDGET, DECIDING_POWER, DECIDING_RINGS, Decision

# What a ring's evidence is, said once where the rings are listed (each then reads "evidence 19").
EVIDENCE_WORDS = "a ring's evidence: the fall in squared error it is expected to show in the test over rings, in touch-noise variances"


@dataclass(frozen=True)
class DecisionWords:
    """The decision in words, by part: a head line, one line a ring in measuring order, a line per
    question no ring decides, and the CMM time (None without rings); the rings also a line per
    question, each ring with its evidence (by_question: the explorer's short list)."""

    head: str
    rings: tuple[str, ...]
    undecided: tuple[str, ...]
    time: str | None
    by_question: tuple[str, ...] = ()

    def lines(self) -> list[str]:
        """The command line's: every ring on a line of its own."""
        return [self.head, *self.rings, *self.undecided, *([self.time] if self.time is not None else [])]

    def paragraphs(self) -> list[str]:
        """The explorer's markdown: the head in bold, then a line a question ("a vs b (147 ...): 1.
        A10 B-20 (31), 2. ..."), what no ring decides and the CMM time."""
        return [f"**{self.head}**", *self.by_question, *self.undecided, *([self.time] if self.time else [])]


def undecided_sentence(label: str, question: dict[str, Any], budget: int) -> str:
    """A question no `budget` rings decide, in one sentence: the power its best rings reach, how far
    its gains scatter when more than the touch noise makes them, and how many rings or what
    measurement would decide it; else that a pair's name stays a pair, or a suggestion a suggestion."""
    scatter = question.get("scatter", 1.0)
    why = f"; what the model leaves at its check rings scatters their gains {scatter:.1f}x the touch noise's" if scatter > 1.05 else ""
    needed, separated_by = question.get("rings_needed"), question.get("separated_by")
    would = [*([f"{needed} rings would (a budget of {needed})"] if needed else []), *([f"{separated_by} would"] if separated_by else [])]
    pair = question.get("pair", True)
    beyond = BEYOND_BUDGET * max(budget, DECIDING_RINGS)
    stays = "so the name stays a pair" if pair else "so it stays a suggestion: too small here to confirm or refute"
    return (
        f"No {budget} rings of this stylus {'decide' if pair else 'confirm or refute'} {question.get('words', label.replace(' vs ', ' or '))} "
        f"(their test over rings would pass {100 * question['power']:.0f} % of the time, {100 * DECIDING_POWER:.0f} % decides{why}): "
        + (
            " and ".join(would)
            or f"not even {beyond} rings would, and no measurement tried here {'separates them' if pair else 'does'}, {stays}"
        )
        + "."
    )


def undecided_sentences(decision: Decision, budget: int) -> tuple[str, ...]:
    """A sentence per question no `budget` rings decide (undecided_sentence)."""
    return tuple(undecided_sentence(label, q, budget) for label, q in decision.expected.items() if not q["decided_by_rings"])


def undecided_text(decision: Decision) -> str:
    """What rings cannot decide, each question with what else would (or that it stays as it is)."""
    return " ".join(undecided_sentences(decision, decision.budget))


def decision_words(decision: Decision, budget: int) -> DecisionWords:
    """The decision in words (DecisionWords); the command line prints its lines, the explorer lays out its parts."""
    head = (
        f"{len(decision.rings)} rings that decide, in this order ({EVIDENCE_WORDS}):"
        if decision.rings
        else (decision.note or "no ring decides what is open")
    )
    rings = tuple(f"{r['order']:>3}. {orientation_label(r['A_deg'], r['B_deg']):<12} {r['reason']}" for r in decision.rings)
    undecided = undecided_sentences(decision, budget)
    by_question = tuple(
        f"{label} (evidence {expected['expected_gain']:.0f}): "
        + ", ".join(
            f"{r['order']}. {orientation_label(r['A_deg'], r['B_deg'])} ({r['expected_gain']:.0f})"
            for r in decision.rings
            if r["question"] == label
        )
        for label, expected in decision.expected.items()
        if expected["decided_by_rings"]
    )
    time = None
    if decision.rings:
        time = f"about {decision.minutes:.0f} minutes of CMM time" if decision.minutes is not None else decision.note
    return DecisionWords(head, rings, undecided, time, by_question)
