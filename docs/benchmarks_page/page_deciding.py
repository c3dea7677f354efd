"""The benchmarks page's `## Rings that decide` section (`deciding`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import joined, num, share_of, table

DECIDING_INTRO = """\
## Rings that decide

`deciding`: the whole loop a metrologist runs when the diagnosis cannot tell two candidates apart or
cannot confirm one ([Rings that decide](methods/deciding.md)): diagnose, `design --decide` (at most
{budget} rings), the twin measures the rings after the campaign on another noise draw, `merge`,
diagnose again. The pair cases: the paper's campaign with one hidden effect, over noise seeds;
success is the true effect claimed at its period and told apart from every confounded partner. The
false suggestions: the population run's healthy and out-of-catalog heads whose diagnosis suggests an
effect the head does not have (a random head's background of lobing, location and low-order cyclic
errors is real); success is that suggestion not claimed after the rings.
"""


def promised(case: Mapping[str, Any]) -> str:
    """How many of the proposals decided, and the power each promised ("-" in a run before it was kept)."""
    if "proposed_decided" not in case:
        return "-"
    powers = [f"{p:.2f}" for p in case.get("promised_power") or [] if p is not None]
    x = case["proposed_decided"]
    return f"{num(x.get('count'))} of {num(x.get('of'))} ({joined(powers)})"


def deciding(results: Mapping[str, Any]) -> str:
    d = results.get("deciding", {})

    rows = []
    for name in ("a_axis_angular", "b_axis_tilt"):
        case = d.get(name) or {}
        truth = case.get("truth") or {}
        shared = [f"{v:.3f}" if v is not None else "-" for v in case.get("shared_after") or []]
        rows.append(
            [
                f"{name}: {truth.get('id')} {truth.get('cycles_per_rev')}/rev",
                share_of(case.get("named_and_told_apart_before")),
                share_of(case.get("named_and_told_apart_after")),
                joined([str(n) for n in case.get("rings_proposed") or []]),
                promised(case),
                joined(shared),
            ]
        )
    false = d.get("false_suggestions") or {}
    rows.append(
        [
            "false suggestions: not claimed after",
            f"false claims before: {share_of(false.get('false_claims_before'))}",
            f"{share_of(false.get('refuted_or_left_suggested'))} (any false claim after: {share_of(false.get('false_claims_after'))})",
            joined([str(n) for n in false.get("rings_proposed") or []]),
            "",
            "",
        ]
    )
    header = [
        "case",
        "before the rings",
        "after the rings",
        "rings proposed",
        "proposals that decided (power promised)",
        "share with the closest partner after",
    ]
    return DECIDING_INTRO.format(budget=d.get("budget")) + "\n" + table(header, rows) + "\n"
