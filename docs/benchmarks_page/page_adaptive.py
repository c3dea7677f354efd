"""The benchmarks page's `## Measure until you know` section (`adaptive_campaign`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import Plots, image, num, table

ADAPTIVE_INTRO = """\
## Measure until you know

`adaptive_campaign`: each head of the population (healthy heads, heads with a catalog effect, heads
with a shape no catalog holds, the families in turn) measured twice on its twin: adaptively
([planning](planning.md#measure-until-you-know-an-adaptive-campaign): six designed rings, two at A0 = 0 and
four check rings, then each plan after a diagnosis with its [base model](planning.md#the-base-model),
to its stop, with no budget) and in full (the
population's paper-style campaign). Both are judged on {rings} evaluation rings of their own, off
both campaigns' grids, measured at {repetitions} repetitions after the campaign: the MAE of the model
at the stop (the last diagnosis's hybrid, or its data part when it claims nothing) against the full
campaign's trilinear model. The verdict is compared word for word with the full campaign's; a
claim "in the head" names an effect the head holds (its background's or the hidden one); **same
answer**: about what the head hides, the words aside: a hidden catalog effect held by a claim of
both or of neither (a claim holds it at its own setting or one it cannot exclude, or through a
partner the rings did not tell it from, which the verdict names beside it); for a shape no catalog
holds, the same of four answers (its axis and group named, by a shape or a claim of its own
mechanism; `none`; a catalog effect of another mechanism; left open), as the
[unknown-shape population](#effects-no-catalog-holds) judges them; else both quiet (`none`, or
claims of the head's own background only) or both not. A sparse
campaign's model is physical where the full one's trilinear interpolates, so it names background
effects the full campaign leaves to its data part: the words differ where the answer does not.
**Right**: the answer is what the twin hid (every hidden catalog effect held by a claim; an unknown
shape's axis and group named; else quiet), for the full campaign and at the stop; **as right**: the
same answer, or the right one where the full campaign's is not. The same answer counts a stop that
finds what the full campaign missed as a failure; as right counts only what the stop loses.
"""


def adaptive(results: Mapping[str, Any], plots: Plots) -> str:
    a = results.get("adaptive_campaign", {})
    targets = a.get("targets", {})
    evaluation = a.get("evaluation", {})

    def share(x: Any) -> str:
        x = x or {}
        low, high = (x.get("ci95") or [None, None])[:2]
        return f"{num(x.get('count'))}/{num(x.get('of'))} ({num(low)}-{num(high)})"

    rows = []
    for kind in ("healthy", "catalog_effect", "unknown_shape", "population"):
        k = a.get(kind)
        if not k:
            continue
        rows.append(
            [
                kind.replace("_", " "),
                k.get("heads"),
                f"{num(k['rings']['median'])} (90 %: {num(k['rings']['p90'])})",
                f"{num(k['full_rings']['median'])}",
                f"{num(k['minutes']['median'])} (90 %: {num(k['minutes']['p90'])})",
                f"{num(k['full_minutes']['median'])}",
                share(k.get("stopped")),
                share(k.get("mae_within_ratio")),
                num(k.get("mae_ratio_median")),
                f"{num(k.get('adaptive_over_floor_median'))} / {num(k.get('trilinear_over_floor_median'))}",
                share(k.get("verdict_agreement")),
                share(k.get("same_answer")),
                f"{num((k.get('full_right') or {}).get('count'))} / {num((k.get('adaptive_right') or {}).get('count'))}",
                share(k.get("as_right")),
                share(k.get("claims_in_head")),
            ]
        )
    header = [
        "heads",
        "n",
        "rings to the stop, median",
        "full rings",
        "minutes, median",
        "full minutes",
        "stopped within 12 plans",
        f"MAE <= {num(targets.get('mae_ratio'))}x the full trilinear",
        "MAE ratio, median",
        "over the floor: adaptive / full",
        "same verdict",
        "same answer",
        "right: full / stop",
        "as right",
        "claims in the head",
    ]
    body = ADAPTIVE_INTRO.format(rings=evaluation.get("rings"), repetitions=evaluation.get("repetitions"))
    targets_line = (
        f"Targets (issue 58): median rings <= {num(targets.get('median_rings_max'))}; MAE within "
        f"{num(targets.get('mae_ratio'))}x on >= {num(targets.get('mae_within_ratio_min'))}; the same verdict on >= "
        f"{num(targets.get('verdict_agreement_min'))} (the same answer; as right beside it). Measured at {a.get('commit')}, {num(a.get('run_seconds'))} s."
    )
    return (
        body + "\n" + table(header, rows) + "\n" + targets_line + "\n\n" + image(plots, "adaptive.png", "the adaptive loop on three heads")
    )
