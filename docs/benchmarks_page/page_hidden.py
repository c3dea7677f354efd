"""The benchmarks page's `## Hidden rotary-axis effects` section (`hidden_effects`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import folded, get, joined, num, table

HIDDEN_INTRO = """\
## Hidden rotary-axis effects

`hidden_effects`: each error motion of the rotary axes and the stylus ball's form hidden in the
paper campaign, and each location error of the axes hidden in the `near_vertical` design, one
campaign each with the scenario's seed, diagnosed with the default catalog. Is the hidden effect
named first, at its true period, with every true amplitude and phase inside the fit's +- U
(k = 2), and does the check-ring error (against the mean of the repetitions) fall to the floor?
Near the vertical a tilt eps of the B axis moves the ball as an offset eps L does, so the B line's
offset and its tilt are one effect for head touches with this stylus: the diagnosis names one of
the pair and says that they are confounded. The A axis's offset and squareness are learnt by the
data model's lattice (`ph-explorer effects --data`): no ring campaign of this design tells them
from the data part. A ball form is learnt by the lattice too.
"""


def hidden_effects(results: Mapping[str, Any]) -> str:
    h = results.get("hidden_effects", {})
    rows = []
    for case, x in (h.get("cases") or {}).items():
        hidden = dict(x.get("hidden") or {})
        effect = hidden.pop("effect", case)
        found = next((f for f in x.get("found") or [] if f.get("effect") == effect), None)
        if found:
            fits = "; ".join(
                f"{k} {num(get(found, 'params', k))} +- {num(get(found, 'params_u', k))} ({num(v)})"
                for k, v in hidden.items()
                if k != "cycles_per_rev" and get(found, "params", k) is not None
            )
        else:
            fits = "not fitted (" + ", ".join(f"{k} {num(v)}" for k, v in hidden.items()) + ")"
        before_after = x.get("check_rings_mae_mean_um") or {}
        rows.append(
            [
                case,
                x.get("verdict"),
                joined(f.get("effect") for f in x.get("found") or []),
                x.get("named_first_at_its_period"),
                x.get("truth_within_u"),
                fits,
                joined((x.get("top_confounded_with") or [])[:3]),
                f"{num(before_after.get('before'))} -> {num(before_after.get('after'))}",
                x.get("after_over_floor"),
                x.get("seconds"),
            ]
        )
    body = [
        f"Campaigns: {h.get('scenario', '')}.",
        "",
        table(
            [
                "hidden",
                "verdict",
                "found",
                "named first at its period",
                "truth inside +- U",
                "fit +- U (truth)",
                "top candidate confounded with",
                "check rings MAE before -> after (um)",
                "after / floor",
                "seconds",
            ],
            rows,
        ),
        f"On the paper design: named first at its period {num(h.get('named_first'))} of {num(h.get('of'))}; "
        f"the error after within 1.3 x the floor {num(h.get('within_1_3_floor'))} of {num(h.get('of'))}.",
    ]
    return (
        HIDDEN_INTRO
        + "\n"
        + folded(
            "Hidden rotary-axis effects: the figures (they name what the teaching scenarios hide: spoilers for students)", "\n".join(body)
        )
    )
