"""The benchmarks page's `## Data efficiency` section (`data_efficiency` and `data_efficiency_details`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import Plots, folded, get, holds, image, interval, joined, num, table

DATA_EFFICIENCY_INTRO = """\
## Data efficiency

`data_efficiency`: the check-ring MAE (um) against the mean of the repetitions, over the check
rings (never trained on), versus the number of training orientations, on the paper scenario and
on the teaching scenario head_3. Two families of subsets of the training rings:

- the **lattice family**, sub-lattices of the grid that keep every A row (every row with evenly
  spread B columns; a lattice because the trilinear model only uses orientations on its lattice);
- the **designed family**, the rings `ph-explorer design --budget N` proposes among the training
  rings ([Designing a campaign](planning.md)).

The network is trained on the lattice family only. The hybrid is not handed the scenario's
effects: on each subset the diagnosis's own choice (`diagnosis.choose_effects` over the whole
catalog; a spread quarter of the subset's rings plays its check rings) proposes its found effects
and those it saw present (beyond noise, plausible, not material on its check quarter), and the
hybrid keeps those the subset identifies and its own cross-validation says the data can carry
(`carried_effects` in `benchmarks/carried.py`, experiment code that only this benchmark uses):

- **identifiable**: two catalog terms are aliases on the subset when they share more than 0.8 of
  their variance on its touches (the diagnosis's confounding threshold, through the data part's
  smoother) but at most 0.8 over the orientations it will predict (the candidate lattice at half
  steps, within the subset's A range). A term the data part would interpolate correctly between
  the rings anyway (it reproduces more than 0.8 of it) is exempt. Otherwise a term is carried only
  together with its aliases among the candidates (one group, kept or dropped whole), and not at
  all when it has an alias outside them: fitted alone it takes up its alias's error (on a few B
  columns a cyclic B error of one order is the mirror of another; the ring's own B sweep separates
  them only when both are fitted);
- **settled**: a term's scanned setting (cycles per revolution, ...) is carried only when it is
  the data's own choice: of every setting of its effect it explains most of the subset's data
  beside the other carried terms, beside each candidate not carried (found or present, so in the
  data, but not identifiable there) and beside all of them, unless the winner predicts as it does
  between the rings. No threshold: a comparison of one effect's settings;
- **carried**: backward elimination over these groups on `crossval.cross_val_predict` (strict,
  leave-one-ring-out up to 30 rings, else 10 folds); a group stays only when it lowers the
  cross-validated error by more than one standard error of the rings' paired differences, and a
  set whose fit is implausible is never kept.

The data part is fitted on the subset's rings only, and it is not one model but two averaged
(`carried_hybrid` in `benchmarks/stacking.py`, stacked generalisation): the hybrid with the
trilinear interpolation and the hybrid with the **mean curve** of the subset's rings (the same at
every orientation), each with the terms it carries, weighted w and 1 - w, w in tenths, the one
that minimises the average's cross-validated error over the subset's rings (the out-of-sample
curves the terms were chosen with: no fit is added). The two are the ends of what a few rings can
carry. When the terms carry the orientation dependence, interpolating between a few rings only
carries those rings' noise into every prediction, and the mean curve averages it over all of
them; when an error no catalog holds varies between the rings, only the interpolation learns it;
where the rings cannot tell the two apart, neither end is chosen (`benchmarks/experiment_checks.py`).
Why a few designed rings cannot decide between the ends: the D-optimal design takes rings where
the effects show most and repeats every A row, so no ring is ever predicted across an A gap,
where the check rings lie. The trilinear model alone gains nothing from the design: the design
serves the physical terms.

Two rules are checked at every subset. **The goal**: with at most a given number of designed rings,
the hybrid within a tolerance of the full-data trilinear model; one campaign decides nothing, so
the goal is measured again on other noise draws of the paper scenario (the same effects, the same
designed rings), with each end of the weights beside it. **Never worse**: at every subset the
hybrid at most a tolerance above the smaller of the trilinear model and its own data part alone
(the trilinear model and the mean curve, no physical term, averaged with the hybrid's weights).
In `results.json`, `data_efficiency_details.<scenario>` also has each point's `design`,
`hybrid_effects` (what the diagnosis found and saw present, what the hybrid kept beside each data
part, the identifiability report, the cross-validated error of every set tried and at each
weight), `never_worse` and `design_target`.
"""


def data_efficiency(results: Mapping[str, Any], plots: Plots) -> str:
    curves = results.get("data_efficiency", {})
    details = results.get("data_efficiency_details", {})
    body = [image(plots, "data_efficiency.png", "data efficiency")]
    for name in curves:
        body.append(efficiency_tables(name, curves[name], details.get(name, {})))
    target = results.get("target") or {}
    if target:
        body.append(
            "**With a fifth of the orientations** (`target`: the hybrid's best on at most a fifth of the full data within "
            f"the tolerance of the full-data trilinear, either family): {holds(target.get('holds'))}. {target.get('detail', '')}.\n"
        )
    spoiler = folded("Data efficiency: the figures (they name what head_3 hides: spoilers for students)", "\n".join(body))
    return DATA_EFFICIENCY_INTRO + "\n" + spoiler


def efficiency_tables(name: str, curves: Mapping[str, Any], d: Mapping[str, Any]) -> str:
    designs: list[str] = list(d.get("design") or [])
    effects = {e.get("design"): e for e in d.get("hybrid_effects") or []}
    trilinear = curves.get("trilinear") or []
    hybrid = curves.get("hybrid") or []
    network = curves.get("network") or []
    if len(designs) != len(trilinear):
        designs = [f"subset {i + 1}" for i in range(len(trilinear))]
    out = [f"**{name}** (noise floor {num(get(d, 'noise_floor_um', 'mean'), 'um')} against the mean; {d.get('reference', '')})", ""]
    for family, prefix in (("lattice family", "lattice"), ("designed", "design")):
        index = [i for i, design in enumerate(designs) if design.startswith(prefix)]
        if not index:
            continue
        header = [f"{name}, {family}"] + [num(trilinear[i][0]) for i in index]
        rows = []
        if family == "lattice family" and len(network) == len(index):
            rows.append(["network"] + [network[k][1] for k in range(len(index))])
        rows.append(["trilinear"] + [trilinear[i][1] for i in index])
        if len(hybrid) == len(trilinear):
            rows.append(["hybrid"] + [hybrid[i][1] for i in index])
            rows.append(["hybrid / trilinear"] + [f"{hybrid[i][1] / trilinear[i][1]:.2f}" for i in index])
        picked = [effects.get(designs[i], {}) for i in index]
        if any(picked):
            rows.append(["hybrid: weight on the interpolation"] + [num(get(e, "weights", "trilinear")) for e in picked])
            rows.append(["found by the diagnosis"] + [joined(e.get("found")) for e in picked])
            rows.append(["seen present"] + [joined(e.get("present")) for e in picked])
            rows.append(["kept beside the interpolation"] + [joined(get(e, "trilinear", "kept")) for e in picked])
            rows.append(["kept beside the mean curve"] + [joined(get(e, "mean_curve", "kept")) for e in picked])
        out += [table(header, rows), f"Designs: {'; '.join(designs[i] for i in index)}.", ""]
    goal = d.get("design_target") or {}
    if goal:
        out += [
            f"**Goal** ({name}): with at most {num(goal.get('max_orientations'))} designed rings the hybrid within "
            f"{num(goal.get('tolerance'))} x the full-data trilinear {num(get(goal, 'full_data_trilinear', 1), 'um')}: "
            f"best designed {num(get(goal, 'best_designed', 1), 'um')} at {num(get(goal, 'best_designed', 0))} rings "
            f"({num(goal.get('ratio_designed'))} x), {holds(goal.get('holds'))}; the lattice family's best at that size "
            f"{num(get(goal, 'best_lattice_family', 1), 'um')} at {num(get(goal, 'best_lattice_family', 0))} rings "
            f"({num(goal.get('ratio_lattice_family'))} x).",
            "",
        ]
        seeds = goal.get("over_noise_seeds") or {}
        if seeds:
            n = len(seeds.get("seeds") or [])
            rows = [
                [
                    "the hybrid (stacked)",
                    f"{num(seeds.get('within_tolerance'))} of {n}",
                    num(seeds.get("ratio_median")),
                    interval(seeds.get("ratio_range")),
                ]
            ]
            for end, label in (
                ("trilinear", "the hybrid with the interpolation alone (weight 1)"),
                ("mean_curve", "the hybrid with the mean curve alone (weight 0)"),
            ):
                e = get(seeds, "ends", end) or {}
                if e:
                    rows.append(
                        [label, f"{num(e.get('within_tolerance'))} of {n}", num(e.get("ratio_median")), interval(e.get("ratio_range"))]
                    )
            out += [
                table(
                    [
                        f"{name}, {num(seeds.get('budget'))} designed rings, {n} other noise draws",
                        f"within {num(seeds.get('tolerance'))} x",
                        "median ratio",
                        "range",
                    ],
                    rows,
                )
            ]
            per_seed = seeds.get("per_seed") or []
            if per_seed:
                out.append(
                    table(
                        [
                            "noise seed",
                            "ratio",
                            "weight on the interpolation",
                            "mean curve's gain (standard errors)",
                            "interpolation alone",
                            "mean curve alone",
                        ],
                        [
                            [
                                s.get("seed"),
                                s.get("ratio"),
                                get(s, "weights", "trilinear"),
                                s.get("mean_curve_gain_in_standard_errors"),
                                get(s, "ends", "trilinear", "ratio"),
                                get(s, "ends", "mean_curve", "ratio"),
                            ]
                            for s in per_seed
                        ],
                    )
                )
    never = d.get("never_worse") or []
    if never:
        out += [
            f"**Never worse** ({name}): {d.get('never_worse_rule', '')}: {holds(d.get('never_worse_holds'))}.",
            "",
            table(
                ["subset", "hybrid", "trilinear", "data part alone", "weights (interpolation / mean curve)", "ratio", "holds"],
                [
                    [
                        f"{num(e.get('orientations'))}: {e.get('design', '')}",
                        e.get("hybrid"),
                        e.get("trilinear"),
                        e.get("data_part"),
                        f"{num(get(e, 'data_part_weights', 'trilinear'))} / {num(get(e, 'data_part_weights', 'mean_curve'))}",
                        e.get("ratio"),
                        e.get("holds"),
                    ]
                    for e in never
                ],
            ),
        ]
    return "\n".join(out)
