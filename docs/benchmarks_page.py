"""The benchmarks page, written from benchmarks/results.json: `python docs/benchmarks_page.py`.

Every figure on the page is read from the results file when the site is built; the prose says what
each section measures and why, and holds no measured number. docs/hooks.py puts the page into the
site as benchmarks.md, with the plots `python -m benchmarks` draws beside the results.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
RESULTS = ROOT / "benchmarks" / "results.json"
PLOTS = ("data_efficiency.png", "speed.png", "calibration.png", "peers.png")
METADATA = (
    "date",
    "mode",
    "commit",
    "machine",
    "total_seconds",
    "section_seconds",
    "updated",
    "data_efficiency_details",
    "target",
    "scale_100",
)

Plots = Mapping[str, str]  # file name -> its path in the site, relative to benchmarks.md


# --- formatting -----------------------------------------------------------------------------------


def num(value: Any, unit: str = "") -> str:
    """A figure as the results file holds it: integers grouped by thousands, floats to 6 digits."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        text = f"{value:,}".replace(",", " ")
    elif isinstance(value, float):
        if math.isinf(value):
            text = "inf"
        elif abs(value) >= 1e5:
            text = f"{round(value):,}".replace(",", " ")
        else:
            text = f"{value:.6g}"
    else:
        text = str(value)
    return f"{text} {unit}".rstrip() if unit else text


def pct(value: Any) -> str:
    return "-" if value is None else f"{100 * value:.1f} %"


def interval(pair: Any, unit: str = "") -> str:
    if not pair or len(pair) != 2:
        return "-"
    return f"{num(pair[0])}-{num(pair[1])}{' ' + unit if unit else ''}"


def pct_interval(pair: Any) -> str:
    if not pair or len(pair) != 2:
        return "-"
    return f"{100 * pair[0]:.1f}-{100 * pair[1]:.1f} %"


def share_of(x: Any) -> str:
    """A rate of results.json ({"count", "of", "share", "ci95"}) as 'k of n: p % (interval)'."""
    x = x or {}
    return f"{num(x.get('count'))} of {num(x.get('of'))}: {pct(x.get('share'))} ({pct_interval(x.get('ci95'))})"


def holds(value: Any) -> str:
    if value is None:
        return "-"
    return "**holds**" if value else "**does not hold**"


def get(data: Any, *keys: Any) -> Any:
    """data[k0][k1]..., or None where a key is missing."""
    for key in keys:
        if isinstance(data, Mapping) and key in data:
            data = data[key]
        elif isinstance(data, list) and isinstance(key, int) and -len(data) <= key < len(data):
            data = data[key]
        else:
            return None
    return data


def cell(value: Any) -> str:
    text = value if isinstance(value, str) else num(value)
    return " ".join(text.split()).replace("|", "\\|")


def table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def folded(title: str, body: str, kind: str = "warning") -> str:
    """A collapsed block (pymdownx.details): the answers a student should not read first."""
    indented = "\n".join(("    " + line) if line.strip() else "" for line in body.splitlines())
    return f'??? {kind} "{title}"\n\n{indented}\n'


def image(plots: Plots, name: str, alt: str) -> str:
    return f"![{alt}]({plots[name]})\n" if name in plots else ""


def joined(items: Any) -> str:
    return ", ".join(str(i) for i in items) if items else "none"


# --- sections -------------------------------------------------------------------------------------


def overview(results: Mapping[str, Any]) -> str:
    machine = results.get("machine", {})
    out = [
        "# Benchmarks",
        "",
        "This page is written from `benchmarks/results.json` each time the site is built: every figure "
        "below is read from that file, none is copied by hand. Run the benchmarks from the repository root:",
        "",
        "```bash",
        '.venv/bin/pip install ".[bench]" && .venv/bin/python -m benchmarks     # every section',
        ".venv/bin/python -m benchmarks --quick --out /tmp/bench                # smoke mode, same keys (CI)",
        ".venv/bin/python -m benchmarks --only speed,hidden_effects             # some sections, updated in results.json",
        ".venv/bin/python -m benchmarks --replot                                # redraw the PNGs from the JSON",
        ".venv/bin/python -m benchmarks --scheduler tcp://HOST:8786              # the many diagnoses on a Dask cluster",
        "```",
        "",
        "A run writes `benchmarks/results.json` and the plots `benchmarks/data_efficiency.png`, "
        "`benchmarks/speed.png`, `benchmarks/calibration.png` and `benchmarks/peers.png`. A run with `--only` keeps every other "
        "section of the last `results.json` as it was and stamps the ones it ran under `updated` (date, mode, "
        "a sha256 of the package's sources): each section below says which run it comes from. "
        "The many diagnoses of the calibration, the population, the hidden effects and the coverage are tasks "
        "of one runner ([`ph_explorer.cluster`](fleet.md#where-it-runs), the fleet's): on a LocalCluster of the "
        "machine's cores, or with `--scheduler` on a Dask cluster, each random head simulated on its worker from its seed. "
        "Robustness is in the test suite, not here: `tests/test_robustness.py` (any generated file through "
        "`ph-explorer inspect` ends in exit 0 or one line and exit 2, never a traceback; bad uploads over the "
        "websocket leave every connected browser served) and `tests/test_io_properties.py` (the reader).",
        "",
        "## The run",
        "",
        table(
            ["date", "mode", "commit", "seconds", "cores (os.cpu_count)", "torch threads", "Python", "platform"],
            [
                [
                    results.get("date"),
                    results.get("mode"),
                    results.get("commit", ""),
                    results.get("total_seconds"),
                    machine.get("cpu_count"),
                    machine.get("torch_threads"),
                    machine.get("python"),
                    machine.get("platform"),
                ]
            ],
        ),
    ]
    updated = results.get("updated") or {}
    if updated:
        out += [
            "Sections run again since (with `--only`), each measured on the code named by its sha256 (and its commit, "
            "recorded since 2026-11-27):",
            "",
            table(
                ["section", "date", "mode", "code sha256", "commit"],
                [[name, s.get("date"), s.get("mode"), s.get("code_sha256"), s.get("commit", "")] for name, s in updated.items()],
            ),
        ]
    seconds = results.get("section_seconds") or {}
    if seconds:
        out += ["", "Wall seconds of each section at its last run: " + joined([f"{k} {num(v, 's')}" for k, v in seconds.items()]) + "."]
    out += ["## Targets at a glance", "", table(["section", "target", "result"], list(target_rows(results)))]
    return "\n".join(out)


def target_rows(results: Mapping[str, Any]) -> Iterable[list[Any]]:
    details = results.get("data_efficiency_details", {})
    for name, d in details.items():
        goal = d.get("design_target") or {}
        if goal:
            yield [
                f"data efficiency, {name}",
                f"the hybrid with at most {num(goal.get('max_orientations'))} designed rings within "
                f"{num(goal.get('tolerance'))} x the full-data trilinear",
                f"{num(goal.get('ratio_designed'))} x: {holds(goal.get('holds'))}",
            ]
        if "never_worse_holds" in d:
            yield [f"data efficiency, {name}", d.get("never_worse_rule", "never worse"), holds(d.get("never_worse_holds"))]
    speed = results.get("speed", {})
    if "diagnosis" in speed:
        dg = speed["diagnosis"]
        medians = ", ".join(f"{k} {num(v.get('seconds_median'), 's')}" for k, v in dg.items() if isinstance(v, Mapping))
        yield ["speed: one diagnosis", f"under {num(dg.get('target_s'), 's')}", f"{medians}: {holds(dg.get('holds'))}"]
    if "serve_startup" in speed:
        st = speed["serve_startup"]
        yield [
            "speed: `ph-explorer serve` answers its URL",
            f"within {num(st.get('target_s'), 's')} of the launch",
            f"{num(st.get('seconds_from_launch'), 's')}: {holds(st.get('holds'))}",
        ]
    if "slider_update_ms" in speed:
        su = speed["slider_update_ms"]
        yield [
            "speed: one browser, server time per slider update",
            f"p95 under {num(su.get('target_p95_ms'), 'ms')}",
            f"{num(su.get('p95'), 'ms')}: {holds(su.get('holds'))}",
        ]
    scale = results.get("scale", {})
    if scale:
        yield [
            f"scale: {num(scale.get('browsers'))} browsers at {num(scale.get('rate_hz'))} Hz",
            f"slider event to drawn p95 at most {num(scale.get('p95_target_ms'), 'ms')}, server time per render p95 at most "
            f"{num(scale.get('server_p95_target_ms'), 'ms')}, no errors",
            f"{num(get(scale, 'latency_ms', 'p95'), 'ms')}, {num(get(scale, 'server_update_ms', 'p95'), 'ms')}, "
            f"{num(scale.get('errors'))} errors: {holds(scale.get('holds'))}",
        ]
    cal = results.get("diagnosis_calibration", {})
    if cal:
        targets = cal.get("targets", {})
        h = cal.get("holds", {})
        yield [
            "diagnosis calibration: false alarms (paper campaign)",
            f"at most {pct(targets.get('false_alarm_rate_max'))}",
            f"{pct(get(cal, 'false_alarm', 'false_alarm_rate'))}: {holds(h.get('false_alarm'))}",
        ]
        yield [
            "diagnosis calibration: stability",
            f"the same verdict on at least {pct(targets.get('stability_min'))} of the seeds",
            f"{pct(get(cal, 'false_alarm', 'stability'))} (nothing hidden), {pct(get(cal, 'stability_with_effect', 'stability'))} "
            f"(an effect hidden): {holds(h.get('stability'))}",
        ]
        yield [
            "diagnosis calibration: seconds per diagnosis",
            f"under {num(targets.get('seconds_per_diagnosis_max'), 's')}",
            f"median {num(get(cal, 'seconds_per_diagnosis', 'median'), 's')}, max {num(get(cal, 'seconds_per_diagnosis', 'max'), 's')}: "
            f"{holds(h.get('seconds_per_diagnosis'))}",
        ]
    pop = results.get("population", {})
    if pop:
        t = pop.get("targets", {})
        fa = get(pop, "healthy", "false_alarm") or {}
        yield [
            "population: false alarms (healthy random heads)",
            f"at most {pct(t.get('false_alarm_max'))}, upper 95 % bound at most {pct(t.get('false_alarm_upper_max'))}",
            f"{pct(fa.get('share'))} ({pct_interval(fa.get('ci95'))}): "
            f"{holds(fa.get('share') is not None and fa['share'] <= t.get('false_alarm_max', 0) and fa['ci95'][1] <= t.get('false_alarm_upper_max', 0))}",
        ]
        for label, key, figure, bound, above in (
            ("population: stability", "stability", None, "stability_min", True),
            ("population: one catalog effect found", "catalog_effect", "found", "found_min", True),
            ("population: truth within U (per parameter)", "catalog_effect", "truth_within_u", "covered_min", True),
            ("population: out-of-catalog effect called missing", "outside_catalog", "missing", "outside_missing_max", False),
            (
                "population: signature names the right joint first",
                "outside_catalog",
                "signature_right_first",
                "signature_right_min",
                True,
            ),
        ):
            x = (get(pop, key, figure) if figure else pop.get(key)) or {}
            target = t.get(bound)
            ok = None if x.get("share") is None or target is None else (x["share"] >= target if above else x["share"] <= target)
            yield [
                label,
                f"{'at least' if above else 'at most'} {pct(target)}",
                f"{pct(x.get('share'))} ({pct_interval(x.get('ci95'))}): {holds(ok)}",
            ]
        speed = results.get("verdict_speed") or {}
        if speed.get("command"):
            command, click, st = speed["command"], speed.get("explorer_click") or {}, speed.get("targets") or {}
            yield [
                f"verdict speed ({speed.get('campaign', '').split(':')[0]})",
                f"the command's verdict within {num(st.get('verdict_median_s'), 's')} median and {num(st.get('verdict_max_s'), 's')} max "
                f"(imports included), the nested figures within {num(st.get('nested_s'), 's')} after it, the explorer's verdict "
                f"within {num(click.get('target_s'), 's')} of the click",
                f"{num(get(command, 'verdict_s', 'median'), 's')} (max {num(get(command, 'verdict_s', 'max'), 's')}), nested "
                f"{num(get(command, 'nested_s', 'median'), 's')}, click {joined([num(x, 's') for x in click.get('seconds') or []]) or '-'}: "
                f"{holds(speed.get('holds'))}",
            ]
    hidden = results.get("hidden_effects", {})
    if hidden:
        yield [
            "hidden rotary-axis effects (paper design)",
            "each hidden effect named first at its period; the error after within 1.3 x the floor",
            f"named first {num(hidden.get('named_first'))} of {num(hidden.get('of'))}; within 1.3 x "
            f"{num(hidden.get('within_1_3_floor'))} of {num(hidden.get('of'))}",
        ]
    cov = results.get("uncertainty_coverage", {})
    if cov:
        yield [
            "uncertainty coverage",
            f"both fractions in {interval(cov.get('target'))} for every campaign and model",
            f"{num(cov.get('in_target_count'))} of {num(cov.get('of'))}",
        ]
    large = results.get("large_campaign", {})
    if large:
        t = large.get("diagnosis_target", {})
        yield [
            "bigger campaign: `diagnose` on the dense design",
            f"at most {num(t.get('seconds'), 's')} and {num(t.get('peak_mib'), 'MiB')}",
            f"{num(get(large, 'dense', 'diagnose', 'seconds'), 's')}, {num(get(large, 'dense', 'diagnose', 'peak_mib'), 'MiB')}: "
            f"{holds(large.get('diagnosis_holds'))}",
        ]


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
where the rings cannot tell the two apart, neither end is chosen (`tests/test_data_part.py`).
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


SPEED_INTRO = """\
## Speed

`speed`: how long each step a user waits for takes, on the benchmark's machine, one step at a
time in the benchmark's process: simulating the paper campaign, training the network to its early
stop, refitting a hybrid's physical terms, one diagnosis (in the same process as the network's
training, as in the explorer; with an effect found, the nested cross-validation of the choice
runs too), predicting one orientation, the Monte Carlo of each model, the start of
`ph-explorer serve` (the URL polled from the launch on, median of several launches) and one
browser moving a slider at 20 Hz.
"""


def speed(results: Mapping[str, Any], plots: Plots) -> str:
    s = results.get("speed", {})
    rows = []
    if "simulate" in s:
        x = s["simulate"]
        rows.append(
            [
                "simulate the paper campaign",
                f"{num(x.get('touches'))} touches in {num(x.get('seconds'), 's')}",
                f"{num(x.get('touches_per_s'))} touches/s",
            ]
        )
    if "network_training" in s:
        x = s["network_training"]
        rows.append(
            [
                "network training to early stop",
                f"{num(x.get('seconds'), 's')}",
                f"{num(x.get('epochs'))} epochs (best {num(x.get('best_epoch'))}), {num(x.get('training_orientations'))} orientations, {x.get('config', '')}",
            ]
        )
    if "physics_refit" in s:
        x = s["physics_refit"]
        rows.append(
            [
                f"physics refit ({joined(x.get('effects'))}: fit and check-ring MAE)",
                f"{num(x.get('seconds'), 's')}",
                f"check-ring MAE {num(get(x, 'check_mae_um', 'mean'), 'um')} (mean), {num(get(x, 'check_mae_um', 'single'), 'um')} (single)",
            ]
        )
    for name, x in (s.get("diagnosis") or {}).items():
        if isinstance(x, Mapping):
            runs = len(x.get("seconds") or [])
            rows.append(
                [
                    f"one diagnosis, {name} ({num(x.get('touches'))} touches{', nested cross-validation included' if x.get('nested') else ''})",
                    f"{num(x.get('seconds_median'), 's')} (median of {runs})",
                    f"verdict {x.get('verdict')}; target under {num(get(s, 'diagnosis', 'target_s'), 's')}",
                ]
            )
    if "predict_one_orientation_us" in s:
        x = s["predict_one_orientation_us"]
        rows.append(["predict one orientation", ", ".join(f"{k} {num(v, 'us')}" for k, v in x.items()), ""])
    if "monte_carlo_touches_per_s" in s:
        x = dict(s["monte_carlo_touches_per_s"])
        per_call = x.pop("touches_per_call", None)
        rows.append(
            ["Monte Carlo, simulated touches/s", ", ".join(f"{k} {num(v)}" for k, v in x.items()), f"{num(per_call)} touches per call"]
        )
    if "serve_startup" in s:
        x = s["serve_startup"]
        rows.append(
            [
                "`ph-explorer serve`: the URL answers",
                f"{num(x.get('seconds_from_launch'), 's')} after launch (median of {num(x.get('launches'))})",
                f"target {num(x.get('target_s'), 's')}: {holds(x.get('holds'))}; ready, campaign and models loaded, at {num(x.get('seconds_to_ready'), 's')}",
            ]
        )
    if "slider_update_ms" in s:
        x = s["slider_update_ms"]
        rows.append(
            [
                "one browser moving a slider at 20 Hz",
                f"server time per update p50 {num(x.get('p50'), 'ms')}, p95 {num(x.get('p95'), 'ms')}",
                f"slider event to drawn p95 {num(get(x, 'latency_ms', 'p95'), 'ms')}; {num(x.get('errors'))} errors; "
                f"target p95 {num(x.get('target_p95_ms'), 'ms')}: {holds(x.get('holds'))}",
            ]
        )
    machine = f"{num(s.get('cpu_count'))} cores, {num(s.get('torch_threads'))} torch threads"
    return "\n".join(
        [SPEED_INTRO, f"Measured on {machine}.", "", table(["what", "figure", "detail"], rows), image(plots, "speed.png", "speed")]
    )


SCALE_INTRO = """\
## Scale

`scale` and `scale_100`: simulated browsers (websocket clients on 127.0.0.1 speaking viser's
protocol, in a separate process, `benchmarks/browsers.py`) move the A/B sliders of one
`ph-explorer serve`; every session must end on its own browser's last orientation. Measured: the
server's time per render, the time from a slider event to its render done (queueing included),
the server's CPU per slider update and the resident memory of the benchmark's process. **The
previous design in the same run** (`scale.previous_design`) is the same app with its prediction
lattices dropped, so that every slider move predicts its models on demand, driven by the same
browsers at the same rate: what the lattice cache buys ([The explorer](explorer.md#many-browsers-at-once)
says how a render works). **With the Gaussian process shown** (`scale.with_gp`): the same browsers
on the same data with the GP data part fitted on the training rings and drawn beside the models,
its curves read from a lattice of its own (its own target: p95 at most the same 50 ms, no errors). These room figures vary between runs of the same serving code.
A render draws what the eye follows (the head, the ring's curves, the polar plot, the map's marker);
Tables 1-3, the charts and a following camera are drawn at most every `follow_interval_s` while a
browser's sliders move, and once more at its last orientation by a catch-up render of their own
(counted and timed apart: `following_catch_up_renders`, `following_catch_up_ms`; a catch-up turn
that finds them drawn within the interval draws nothing and is not counted).
"""


def scale(results: Mapping[str, Any]) -> str:
    rows = []
    for key, label in (
        ("scale", None),
        ("scale.with_gp", "with the Gaussian process shown"),
        ("scale.previous_design", "the previous design (no lattice cache)"),
        ("scale_100", None),
    ):
        x = get(results, *key.split("."))
        if not x:
            continue
        base = results.get("scale", {}) if key.startswith("scale.") else x
        room = f"{num(base.get('browsers'))} browsers at {num(base.get('rate_hz'))} Hz for {num(base.get('seconds'), 's')}"
        rows.append(
            [
                f"{room}{', ' + label if label else ''}",
                num(x.get("slider_updates_sent")) if "slider_updates_sent" in x else "-",
                num(x.get("errors")),
                num(x.get("renders_per_update")),
                f"{num(get(x, 'server_update_ms', 'p50'))} / {num(get(x, 'server_update_ms', 'p95'))}",
                f"{num(get(x, 'latency_ms', 'p50'))} / {num(get(x, 'latency_ms', 'p95'))}",
                num(x.get("server_cpu_ms_per_update")),
                f"{num(get(x, 'rss_mb', 'before'))} -> {num(get(x, 'rss_mb', 'after'))}" if "rss_mb" in x else "-",
                num(x.get("sessions_not_on_their_last_orientation")) if "sessions_not_on_their_last_orientation" in x else "-",
            ]
        )
    out = [
        SCALE_INTRO,
        table(
            [
                "room",
                "slider updates",
                "errors",
                "renders per update",
                "server ms per render p50 / p95",
                "slider event to drawn ms p50 / p95",
                "server CPU ms per update",
                "resident MB",
                "sessions not on their last orientation",
            ],
            rows,
        ),
    ]
    x = results.get("scale", {})
    if x:
        out.append(
            f"Targets for {num(x.get('browsers'))} browsers: slider event to drawn p95 at most {num(x.get('p95_target_ms'), 'ms')}, "
            f"server time per render p95 at most {num(x.get('server_p95_target_ms'), 'ms')}, no errors: {holds(x.get('holds'))}."
        )
        shown = x.get("with_gp") or {}
        if shown:
            out.append(
                f"With the Gaussian process shown: slider event to drawn p95 at most {num(x.get('p95_target_ms'), 'ms')}, "
                f"no errors: {holds(shown.get('holds'))}."
            )
        if "following_catch_up_renders" in x:
            out.append(
                f"What follows the sliders (tables, charts, camera), at most every {num(x.get('follow_interval_s'), 's')}: "
                f"{num(x.get('following_catch_up_renders'))} catch-up renders, ms p50 / p95 "
                f"{num(get(x, 'following_catch_up_ms', 'p50'))} / {num(get(x, 'following_catch_up_ms', 'p95'))}."
            )
        lattice = x.get("lattice") or {}
        if lattice:
            sizes = ", ".join(f"{k} {num(v, 'MiB')}" for k, v in (lattice.get("models") or {}).items())
            steps = ", ".join(f"{k} {num(v, 'deg')}" for k, v in (lattice.get("step_deg") or {}).items())
            out.append(
                f"\nThe lattices: {sizes}; steps {steps}; within {num(lattice.get('tolerance_um'), 'um')} of the model; "
                f"ready before the browsers started: {num(lattice.get('ready'))}; models predicted on demand instead: "
                f"{joined(lattice.get('on_demand'))}.\n"
            )
    return "\n".join(out)


CALIBRATION_INTRO = """\
## Diagnosis calibration

`diagnosis_calibration`: does the diagnosis say what it should, and how often does it cry wolf?
Many campaigns, each simulated with its own noise seed and diagnosed with the whole catalog, as a
user would (`diagnose`): the paper campaign with nothing hidden beyond its background (every
verdict but `none` is a false alarm), the same with other designs (fewer repetitions, no touch
times, a longer stylus, a coarser B lattice), the teaching scenario head_3 (the verdict must be
`missing`, the effect named at its period), and the detection power against a cyclic B-axis error
of growing amplitude added to the paper campaign. The look-elsewhere control of the search counts
every candidate and every scanned period, so a bigger catalog need not add false alarms. A coarser
B lattice is a true detection, not a false alarm: leaving one B column out opens a gap that the
background's own cyclic B error cannot be interpolated across. The "after" error is given twice:
on the check rings, which took part in choosing the effect, and nested (chosen without the rings
measured: the honest figure). Intervals are 95 % Clopper-Pearson.
"""


def calibration(results: Mapping[str, Any], plots: Plots) -> str:
    c = results.get("diagnosis_calibration", {})
    rows = []

    def row(label: str, x: Mapping[str, Any], figure: str) -> None:
        v = x.get("verdicts") or {}
        rows.append([label, num(x.get("n")), ", ".join(f"{k} {num(n)}" for k, n in v.items() if n), figure])

    if "false_alarm" in c:
        x = c["false_alarm"]
        row(
            f"{x.get('scenario')}: {x.get('design')}",
            x,
            f"false alarms {pct(x.get('false_alarm_rate'))} ({pct_interval(x.get('false_alarm_ci95'))}), stability {pct(x.get('stability'))}",
        )
    for key, x in (c.get("designs") or {}).items():
        held = get(c, "holds", "designs_false_alarm", key)
        figure = f"false alarms {pct(x.get('false_alarm_rate'))} ({pct_interval(x.get('false_alarm_ci95'))})"
        if held is False:
            figure += ": every alarm a true detection, see above"
        row(f"{x.get('scenario')}: {x.get('design')}", x, figure)
    w = c.get("stability_with_effect") or {}
    if w:
        row(
            f"{w.get('scenario')} ({w.get('true_effect', {}).get('id')} {num(get(w, 'true_effect', 'cycles_per_rev'))}/rev hidden)",
            w,
            f"found at its period on {pct(w.get('share_found_head_3'))} of the seeds; stability {pct(w.get('stability'))}",
        )
    body = [image(plots, "calibration.png", "calibration"), table(["campaign", "seeds", "verdicts", "figure (95 % interval)"], rows)]
    fa = c.get("false_alarm") or {}
    if fa.get("per_verdict"):
        per = ", ".join(f"`{k}` {pct(v.get('rate'))} ({pct_interval(v.get('ci95'))})" for k, v in fa["per_verdict"].items() if k != "none")
        body.append(
            f"False alarms per verdict on the {fa.get('scenario')} campaign: {per}. Rings exceeding their noise under the "
            f"baseline: median {num(get(fa, 'baseline_failing_rings', 'median'))}, max {num(get(fa, 'baseline_failing_rings', 'max'))}.\n"
        )
    test = c.get("within_noise_test") or {}
    if test:
        body.append(
            f"The within-noise test as run: ring level {num(test.get('ring_level'))}, campaign false-alarm rate "
            f"{num(test.get('campaign_false_alarm'))}, mean tolerance {num(test.get('mean_tolerance'))}; statistic: {test.get('statistic')}.\n"
        )
    power = get(c, "power", "curve") or []
    if power:
        body += [
            f"**Detection power**: {get(c, 'power', 'scenario')}; detected = {get(c, 'power', 'detected')}.",
            "",
            table(
                ["amplitude (arcsec)", "seeds", "verdicts", "power (95 % interval)", "mean fitted amplitude (arcsec)"],
                [
                    [
                        p.get("amplitude_arcsec"),
                        p.get("n"),
                        ", ".join(f"{k} {num(n)}" for k, n in (p.get("verdicts") or {}).items() if n),
                        f"{pct(p.get('power'))} ({pct_interval(p.get('power_ci95'))})",
                        p.get("mean_fitted_amplitude_arcsec"),
                    ]
                    for p in power
                ],
            ),
        ]
    after = c.get("after_errors") or {}
    if after:
        body.append(
            table(
                [f"{after.get('scenario')}: {after.get('reference')}", "before", "after", "share removed"],
                [
                    [
                        "check rings (took part in choosing)",
                        get(after, "check_rings", "before"),
                        get(after, "check_rings", "after"),
                        pct(get(after, "check_rings", "share_removed")),
                    ],
                    [
                        f"nested ({num(get(after, 'nested', 'folds'))} folds, chosen without the rings measured)",
                        get(after, "nested", "before"),
                        get(after, "nested", "after"),
                        pct(get(after, "nested", "share_removed")),
                    ],
                    ["noise floor", after.get("noise_floor_mean"), "", ""],
                ],
            )
        )
    for key in ("amplitude_arcsec", "phase_deg"):
        x = w.get(key) or {}
        if x:
            body.append(
                f"Fitted {key} on {w.get('scenario')}: mean {num(x.get('mean_fit'))} (sd {num(x.get('sd_fit'))}) against the true "
                f"{num(x.get('true'))}; its +- U (k = 2, mean {num(x.get('mean_u_k2'))}) covers the truth on {num(x.get('covered'))} "
                f"of {num(x.get('of'))} seeds ({pct_interval(x.get('coverage_ci95'))}).\n"
            )
    if w.get("coverage_note"):
        body.append(
            f"Coverage is the {w['coverage_note']}. A fitted amplitude can be biased where the campaign's B lattice aliases the hidden "
            "period onto the order of the background's own B error, which the data model captures and which is not fitted beside it.\n"
        )
    sp = c.get("seconds_per_diagnosis") or {}
    if sp:
        h3 = sp.get("head_3") or {}
        body.append(
            f"Seconds per diagnosis in this section ({sp.get('note', '')}): {sp.get('scenario')} median {num(sp.get('median'), 's')}, "
            f"max {num(sp.get('max'), 's')}; head_3 median {num(h3.get('median'), 's')}, max {num(h3.get('max'), 's')} "
            f"({h3.get('note', '')}); target under {num(sp.get('target_s'), 's')}: {holds(sp.get('holds'))}. "
            f"The whole section: {num(c.get('diagnoses'))} diagnoses in {num(c.get('seconds'), 's')}, {num(c.get('workers'))} at a time.\n"
        )
    return (
        CALIBRATION_INTRO
        + "\n"
        + folded("Diagnosis calibration: the figures (they name what head_3 hides: spoilers for students)", "\n".join(body))
    )


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


COVERAGE_INTRO = """\
## Uncertainty coverage

`uncertainty_coverage`: do the Monte Carlo bands hold what they say ([Uncertainty](uncertainty.md))?
Every model is trained without the check rings (the paper: the shipped `assets/models/paper/` on
`assets/data/paper.csv`, its network's cross-validation retrained with the card's settings; the
teaching scenarios: simulated with their own seed, both models trained as `train` does; the
hybrid: the scenario's known, not hidden, effects and a trilinear data part, fitted on the
training rings only). **Each check ring's band is calibrated on the other held-out rings** (leave
one ring out), so no ring is covered by a band calibrated on itself. The fractions are of the
held-out single touches inside the touch band and of the held-out mean-curve points inside the
mean band; beside them, the same run's band of the cross-validation alone (scale 1) and the
noise-only band (the repeatability component alone). The model variance scale is the one each
check ring's band used (local in A): median (min-max) over the check rings.
"""


def within(u: Mapping[str, Any], band: str) -> int:
    """How many (campaign, model) pairs hold both fractions of this band inside the target."""
    low, high = u.get("target") or (0.0, 1.0)
    return sum(
        all(low <= (get(x, band, k) if get(x, band, k) is not None else -1) <= high for k in ("touch", "mean"))
        for models in (u.get("campaigns") or {}).values()
        for x in models.values()
    )


def coverage(results: Mapping[str, Any]) -> str:
    u = results.get("uncertainty_coverage", {})
    rows = []
    for campaign, models in (u.get("campaigns") or {}).items():
        for model, x in models.items():
            scale_ = x.get("model_error_scale") or {}
            rows.append(
                [
                    campaign,
                    model,
                    get(x, "full_band", "touch"),
                    get(x, "full_band", "mean"),
                    f"{num(get(x, 'cross_validation_only_band', 'touch'))} / {num(get(x, 'cross_validation_only_band', 'mean'))}",
                    f"{num(get(x, 'noise_only_band', 'touch'))} / {num(get(x, 'noise_only_band', 'mean'))}",
                    f"{num(scale_.get('median'))} ({num(scale_.get('min'))}-{num(scale_.get('max'))})",
                    num(scale_.get("calibration_rings")),
                    x.get("in_target"),
                ]
            )
    target = interval(u.get("target"))
    out = [
        COVERAGE_INTRO,
        f"Method as run: {u.get('method', '')}.",
        "",
        table(
            [
                "campaign",
                "model",
                "touches in band",
                "mean-curve points in band",
                "cross-validation only: touches / mean",
                "noise only: touches / mean",
                "model variance scale",
                "calibration rings",
                f"in {target}",
            ],
            rows,
        ),
        f"Both fractions in {target}: {num(u.get('in_target_count'))} of {num(u.get('of'))} pairs; with the band of the "
        f"cross-validation alone {within(u, 'cross_validation_only_band')} of {len(rows)}, with the noise-only band "
        f"{within(u, 'noise_only_band')} of {len(rows)}. Section time {num(u.get('seconds'), 's')}.",
        "",
    ]
    budget_rows = [
        [
            campaign,
            model,
            *[
                get(x, "budget_um_mean_over_check_rings", k)
                for k in ("repeatability", "repeatability_mean", "model", "parameters", "combined_touch", "combined_mean")
            ],
        ]
        for campaign, models in (u.get("campaigns") or {}).items()
        for model, x in models.items()
    ]
    if budget_rows:
        out += [
            "The budget, mean over the check rings (standard uncertainties, um):",
            "",
            table(
                [
                    "campaign",
                    "model",
                    "repeatability",
                    "repeatability of the mean",
                    "model",
                    "parameters",
                    "combined, one touch",
                    "combined, the mean",
                ],
                budget_rows,
            ),
        ]
    task = u.get("task_paper_check_rings") or {}
    if task:
        rows = []
        for model, x in task.items():
            rings = x.get("rings") or []
            largest = max((r.get("E_n") or 0 for r in rings), default=None)
            u_sim = [r.get("U_sim_um") for r in rings if r.get("U_sim_um") is not None]
            rows.append(
                [
                    model,
                    f"{num(x.get('ront_E_n_at_most_1'))} of {num(x.get('of_rings'))}",
                    largest,
                    f"{num(x.get('harmonics_E_n_at_most_1'))} of {num(x.get('harmonics_compared'))}",
                    interval([min(u_sim), max(u_sim)]) if u_sim else "-",
                    x.get("single_ront_inside_95_interval"),
                ]
            )
        out += [
            "**The measurement task** on the paper campaign's check rings (one circle of head touches, one measurement; each "
            "ring's sources calibrated on the other rings): the measured value is the mean over the repetitions with "
            "U_meas = 2 s / sqrt(R), and E_n = |sim - measured| / sqrt(U_sim^2 + U_meas^2). U_sim is mostly the touch noise, "
            "so E_n <= 1 is a weak check; the stricter one is the share of the single measured RONt values inside the "
            "simulated 95 % interval.",
            "",
            table(
                [
                    "model",
                    "RONt E_n <= 1",
                    "largest RONt E_n",
                    "harmonics 2..15 E_n <= 1",
                    "U_sim of RONt, k = 2 (um)",
                    "single RONt inside the 95 % interval",
                ],
                rows,
            ),
        ]
    return "\n".join(out)


LARGE_INTRO = """\
## A bigger campaign

`large_campaign`: the paper scenario at its size and a denser design, each command run through
the command line in its own process (interpreter and imports included; `serve` until it prints its
URL), its peak resident memory read from the kernel through `benchmarks/peak.py`, a launcher that
imports nothing (a process forked from the benchmark's own would carry the benchmark's high-water
mark). The growth exponent is log(dense / paper) of the figure over log(dense / paper) of the
touches: below 1, a command grows slower than the touches.
"""


def large_campaign(results: Mapping[str, Any]) -> str:
    lc = results.get("large_campaign", {})
    touches = lc.get("touches") or {}
    commands = list((lc.get("paper") or {}).keys())
    rows = []
    for c in commands:
        p, d, g = get(lc, "paper", c) or {}, get(lc, "dense", c) or {}, get(lc, "growth_exponent", c) or {}
        rows.append(
            [
                f"`{c}`",
                f"{num(p.get('seconds'))} / {num(p.get('peak_mib'))}",
                f"{num(d.get('seconds'))} / {num(d.get('peak_mib'))}",
                f"{num(g.get('seconds'))} / {num(g.get('peak_mib'))}",
                "yes" if p.get("ok", True) and d.get("ok", True) else "no",
            ]
        )
    t = lc.get("diagnosis_target") or {}
    return "\n".join(
        [
            LARGE_INTRO,
            f"Dense design: {lc.get('design', '')}. {lc.get('note', '')}.",
            "",
            table(
                [
                    "command",
                    f"paper ({num(touches.get('paper'))} touches): s / MiB",
                    f"dense ({num(touches.get('dense'))} touches): s / MiB",
                    "growth exponent (s / MiB)",
                    "ran",
                ],
                rows,
            ),
            f"`diagnose` on the dense design within {num(t.get('seconds'), 's')} and {num(t.get('peak_mib'), 'MiB')}: {holds(lc.get('diagnosis_holds'))}.",
            "",
        ]
    )


def flattened(data: Any, prefix: str = "") -> Iterable[tuple[str, Any]]:
    if isinstance(data, Mapping):
        for key, value in data.items():
            yield from flattened(value, f"{prefix}.{key}" if prefix else str(key))
    elif isinstance(data, list) and data and all(isinstance(v, (int, float, str, bool)) or v is None for v in data) and len(data) <= 12:
        yield prefix, ", ".join(num(v) for v in data)
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from flattened(value, f"{prefix}[{i}]")
    else:
        yield prefix, data


def other_section(name: str, data: Any) -> str:
    """A section this page has no layout for yet: its figures as key and value."""
    return f"## {name}\n\n" + table(["key", "value"], list(flattened(data))) + "\n"


POPULATION_INTRO = """\
## Population

`population`: the verdicts over a population of random heads (`ph-explorer simulate
--random-head`; distributions and designs in [Random heads](methods/random_heads.md)), each
diagnosed as a user would with the default catalog, without the nested cross-validation (it gives
no verdict). Healthy heads: any verdict but `none` is a false alarm, unless it names only the
head's own background terms at their true settings (a true finding of a term the lattice model
leaves, e.g. a 4/rev B-axis error a 20 deg lattice cannot follow); both shares are shown.
Stability: the same heads with another draw of their noise. One catalog effect at 1-3x its
detection limit: `missing` or `partial` with it (at its settings, or at settings the diagnosis
cannot exclude; beside it, found at its true setting, and how many others each find keeps) or
with a candidate confounded with it, and its true parameters within the fit +- U (per parameter, as k = 2 is stated; all of
an effect's parameters at once beside it). One effect of a shape no catalog holds (a local
defect of an axis, seven lobes of the probe) at 2-4x its detection limit: how often it is called
`missing` (an overclaim), and, where the diagnosis sees it, whether the signature's first
variable is of the defect's own joint (b_joint_deg or b0_deg for a B defect), the exact variable,
and a bump within two widths of the defect. Intervals are 95 % Clopper-Pearson.
"""


def not_excluded_text(spread: Mapping[str, Any] | None) -> str:
    """'other settings not excluded per find: median 0, 90th percentile 3, max 19'."""
    if not spread or spread.get("median") is None:
        return ""
    return f"other settings not excluded per find: median {spread['median']:g}, 90th percentile {spread['p90']:g}, max {spread['max']}"


def population(results: Mapping[str, Any]) -> str:
    pop = results.get("population", {})
    healthy = pop.get("healthy") or {}
    rows = [
        [
            "healthy heads: false alarms",
            share_of(healthy.get("false_alarm")),
            joined([f"{k} {v}" for k, v in (healthy.get("verdicts") or {}).items()]),
        ],
        ["healthy heads: any verdict but none", share_of(healthy.get("any_verdict_but_none")), ""],
        ["healthy heads: naming only their own background terms", share_of(healthy.get("true_background_findings")), ""],
        *[[f"healthy heads, {d} design: false alarms", share_of(x), ""] for d, x in (healthy.get("by_design") or {}).items()],
        ["healthy heads, heavy-tailed noise", share_of(healthy.get("heavy_tailed_noise")), ""],
        ["the same heads, another noise draw: same verdict", share_of(pop.get("stability")), ""],
        [
            "one catalog effect: found",
            share_of(get(pop, "catalog_effect", "found")),
            joined([f"{k} {v}" for k, v in (get(pop, "catalog_effect", "verdicts") or {}).items()]),
        ],
        [
            "one catalog effect: found at its true setting",
            share_of(get(pop, "catalog_effect", "found_at_the_true_setting")),
            not_excluded_text(get(pop, "catalog_effect", "settings_not_excluded_per_find")),
        ],
        ["one catalog effect: parameters with the truth within U", share_of(get(pop, "catalog_effect", "truth_within_u")), ""],
        [
            "one catalog effect: every parameter within U at once",
            share_of(get(pop, "catalog_effect", "truth_within_u_every_parameter")),
            "",
        ],
        [
            "outside the catalog: called missing",
            share_of(get(pop, "outside_catalog", "missing")),
            joined([f"{k} {v}" for k, v in (get(pop, "outside_catalog", "verdicts") or {}).items()]),
        ],
        [
            "outside the catalog: signature's first variable of the right joint",
            share_of(get(pop, "outside_catalog", "signature_right_first")),
            "",
        ],
        [
            "outside the catalog: signature's first variable exactly",
            share_of(get(pop, "outside_catalog", "signature_exact_variable_first")),
            "",
        ],
        [
            "outside the catalog: signature's first entry a bump at the defect",
            share_of(get(pop, "outside_catalog", "signature_located")),
            "",
        ],
    ]
    seconds = pop.get("seconds_per_diagnosis") or {}
    tail = (
        f"\nSeconds per diagnosis ({seconds.get('what', '')}): median {num(seconds.get('median'), 's')}, max "
        f"{num(seconds.get('max'), 's')}. Claims on healthy heads: {joined([f'{k} {v}' for k, v in (healthy.get('claims') or {}).items()]) or 'none'}. "
        f"Measured on code {pop.get('code_sha256')}, commit {pop.get('commit', '-')} ({pop.get('mode')} run, {num(pop.get('run_seconds'), 's')}).\n"
    )
    speed = results.get("verdict_speed") or {}
    if speed:
        command, click = speed.get("command") or {}, speed.get("explorer_click") or {}
        clicked = (
            f"The explorer (a fresh `serve` on the shipped data, chromium, the page settled first) showed the verdict "
            f"{joined([num(x, 's') for x in click.get('seconds') or []])} after the click on Diagnose (target {num(click.get('target_s'), 's')} "
            f"each). "
            if click.get("seconds")
            else f"The explorer's click: {click.get('skipped', 'not measured')}. "
        )
        tail += (
            f"\nOne diagnosis of {speed.get('campaign')}, nothing else running, {num(speed.get('repeats'))} runs: the command "
            f"`diagnose` prints its verdict {num(get(command, 'verdict_s', 'median'), 's')} after launch (median, imports included; "
            f"max {num(get(command, 'verdict_s', 'max'), 's')}) and the nested figures {num(get(command, 'nested_s', 'median'), 's')} "
            f"after it (median); in one process the verdict takes {num(get(speed, 'in_process', 'verdict_s', 'median'), 's')}, the "
            f"nested cross-validation {num(get(speed, 'in_process', 'nested_after_s'), 's')}. {clicked}Targets: verdict median "
            f"{num(get(speed, 'targets', 'verdict_median_s'), 's')} and max {num(get(speed, 'targets', 'verdict_max_s'), 's')}, "
            f"nested {num(get(speed, 'targets', 'nested_s'), 's')}: {holds(speed.get('holds'))}.\n"
        )
    tolerance = pop.get("tolerance") or {}
    if tolerance:
        tail += (
            f"\nThe within-noise test's tolerance (a ring's mean may hold this many times its noise variance of systematic "
            f"error), chosen over {num(get(tolerance, 'baseline_fails', str(tolerance.get('used')), 'of'))} other healthy heads "
            f"(seeds {joined([str(x) for x in tolerance.get('seeds') or []])}): the baseline fails on "
            + joined([f"{share_of(x)} at {k}" for k, x in (tolerance.get("baseline_fails") or {}).items()])
            + f"; used: {num(tolerance.get('used'))}.\n"
        )
    u_cal = pop.get("u_calibration") or {}
    if u_cal:
        tail += (
            f"\nThe jackknife's U over {num(get(u_cal, 'within_u', 'of'))} parameters of "
            f"{num(u_cal.get('heads_with_the_effect_found_exactly'))} calibration heads with one catalog effect found "
            f"(seeds {joined([str(x) for x in u_cal.get('seeds') or []])}, never the heads above): within U "
            f"{share_of(u_cal.get('within_u'))}; the 95th percentile of |fit - truth| / U {num(u_cal.get('q95_error_over_u'))}; "
            f"inflation used {num(u_cal.get('inflation_used'))}, measured {num(u_cal.get('inflation_measured'))}.\n"
        )
    by_effect = get(pop, "catalog_effect", "by_effect") or {}
    effects = table(["hidden catalog effect", "found"], [[k, share_of(v)] for k, v in by_effect.items()])
    return POPULATION_INTRO + "\n" + table(["heads", "figure (95 % interval)", "verdicts"], rows) + tail + "\n" + effects + "\n"


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


def deciding(results: Mapping[str, Any]) -> str:
    d = results.get("deciding", {})

    def rate(x: Any) -> str:
        x = x or {}
        return f"{num(x.get('count'))} of {num(x.get('of'))}"

    rows = []
    for name in ("a_axis_angular", "b_axis_tilt"):
        case = d.get(name) or {}
        truth = case.get("truth") or {}
        shared = [f"{v:.3f}" if v is not None else "-" for v in case.get("shared_after") or []]
        rows.append(
            [
                f"{name}: {truth.get('id')} {truth.get('cycles_per_rev')}/rev",
                rate(case.get("named_and_told_apart_before")),
                rate(case.get("named_and_told_apart_after")),
                joined([str(n) for n in case.get("rings_proposed") or []]),
                joined(shared),
            ]
        )
    false = d.get("false_suggestions") or {}
    rows.append(
        [
            "false suggestions: not claimed after",
            f"false claims before: {rate(false.get('false_claims_before'))}",
            f"{rate(false.get('refuted_or_left_suggested'))} (any false claim after: {rate(false.get('false_claims_after'))})",
            joined([str(n) for n in false.get("rings_proposed") or []]),
            "",
        ]
    )
    header = ["case", "before the rings", "after the rings", "rings proposed", "share with the closest partner after"]
    return DECIDING_INTRO.format(budget=d.get("budget")) + "\n" + table(header, rows) + "\n"


FLEET_INTRO = """\
## Many heads

`fleet`: healthy random heads of the population, written as campaign files and diagnosed as
`ph-explorer diagnose --data 'heads/*.csv'` does ([Many heads](fleet.md)), on a Dask LocalCluster
of one single-threaded worker and then of two (cluster start-up included). The expected wall time
of the population calibration is its diagnoses times the mean seconds of one here, over the cores.
"""


def fleet(results: Mapping[str, Any]) -> str:
    f = results.get("fleet", {})
    seconds, each = f.get("seconds") or {}, f.get("seconds_per_diagnosis") or {}
    population = f.get("population_calibration") or {}
    rows = [
        ["campaigns", num(f.get("campaigns"))],
        ["wall, 1 worker / 2 workers", f"{num(seconds.get('one_worker'), 's')} / {num(seconds.get('two_workers'), 's')}"],
        [f"ratio (target <= {num(f.get('target_ratio'))})", f"{num(f.get('ratio'))}: {holds(f.get('holds'))}"],
        ["rows equal between the runs", holds(f.get("rows_equal"))],
        ["seconds per diagnosis: median / mean / max", f"{num(each.get('median'))} / {num(each.get('mean'))} / {num(each.get('max'))}"],
        ["a worker's peak memory", num(f.get("worker_peak_mib"), "MiB")],
        ["bytes a task sends / returns", f"{num(get(f, 'bytes_per_task', 'sent'))} / {num(get(f, 'bytes_per_task', 'returned'))}"],
    ]
    rows += [
        [f"population calibration ({num(population.get('diagnoses'))} diagnoses) on {n} cores", num(v, "s")]
        for n, v in (population.get("expected_wall_s") or {}).items()
    ]
    return FLEET_INTRO + "\n" + table(["figure", "value"], rows) + "\n"


PEERS_INTRO = """\
## Peers

`peers`: what a data scientist would try first, beside the project's models, on the same split
(every model learns from the training rings and predicts the check rings it never saw):
scipy's `RBFInterpolator` (thin-plate spline, no smoothing) and scikit-learn's
`GaussianProcessRegressor` (constant x Matern 5/2 with a length scale per feature + white noise,
hyperparameters by the log marginal likelihood), both fitted on the feature map ({feature_map}) to
{targets}. The hybrid "before" starts from the scenario's known effects (none on a random head);
"after" adds the effects the diagnosis chose, fitted on the training rings only as the peers are
(an effect that only the check rings identify, because the lattice interpolates it, then gets no
weight). Beside it, the diagnosis's own "after" (each check ring predicted with that ring left out
of the physical fit but the other check rings in: what the loop shows) and its nested
cross-validation's "after" (each fold choosing its effects without its rings). Each
figure is the check-ring MAE against the repetitions' mean over its noise floor; the ratio is the
best of the project's models over the best peer (goal: at most 1.00). The project's models include
its own GP data part ("gaussian process": the axis angles (A, cos B, sin B) as features,
every point of the curve; [its method](methods/gaussian_process.md)) and the hybrid after the
diagnosis with it ("hybrid after gp"), and the "hybrid stacked": the diagnosis's effects kept per
data part and the data part chosen among the trilinear tables, the mean curve and the GP by the
training rings' own cross-validation (the data-efficiency benchmark's rule with the GP as a third
part, its fit time including that choice; the data-efficiency benchmark's rule keeps to the
trilinear tables and the mean curve, `benchmarks/stacking.py` says why). The peer
GP's own 95 % band (coefficients' predictive
variance through the Fourier basis, plus the repetition variance for single touches) stands beside
the project's calibrated Monte Carlo bands of the trilinear model and of the GP data part (whose
model component is its posterior variance); the coverage goal is the GP data part's.
"""


def peers(results: Mapping[str, Any], plots: Plots) -> str:
    p = results.get("peers", {})
    campaigns = p.get("campaigns", [])
    names = list(campaigns[0].get("models", {})) if campaigns else []  # the project's models, then the peers, as stored
    rows = []
    for r in p.get("campaigns", []):
        models = r.get("models", {})
        ratio = r.get("ratio_best_project_to_best_peer")
        rows.append(
            [r.get("campaign"), *(num(get(models, m, "over_floor", "mean")) for m in names)]
            + [
                f"{num(ratio)}: {holds(ratio is not None and ratio <= 1.0)}",
                num(get(r, "diagnosis_after", "over_floor", "mean")),
                num(get(r, "nested_after_mae_um", "mean"), "um"),
            ]
        )
    bands = [
        [
            r.get("campaign"),
            f"{pct(get(r, 'gp_band', 'coverage', 'mean'))} / {pct(get(r, 'gp_band', 'coverage', 'single'))}",
            f"{num(get(r, 'gp_band', 'mean_half_width_um', 'mean'))} / {num(get(r, 'gp_band', 'mean_half_width_um', 'single'))}",
            f"{pct(get(r, 'monte_carlo_band', 'coverage', 'mean'))} / {pct(get(r, 'monte_carlo_band', 'coverage', 'single'))}",
            f"{num(get(r, 'monte_carlo_band', 'mean_half_width_um', 'mean'))} / "
            f"{num(get(r, 'monte_carlo_band', 'mean_half_width_um', 'single'))}",
            f"{pct(get(r, 'gaussian_process_band', 'coverage', 'mean'))} / {pct(get(r, 'gaussian_process_band', 'coverage', 'single'))}",
            f"{num(get(r, 'gaussian_process_band', 'mean_half_width_um', 'mean'))} / "
            f"{num(get(r, 'gaussian_process_band', 'mean_half_width_um', 'single'))}",
        ]
        for r in p.get("campaigns", [])
    ]
    timing = [
        [
            m,
            *(
                f"{num(get(r, 'models', m, 'fit_s'), 's')} / {num(get(r, 'models', m, 'predict_s'), 's')}"
                for r in p.get("campaigns", [])[:1]
            ),
        ]
        for m in names
    ]
    goals = [
        [
            name.replace("1_25", "1.25").replace("_", " "),
            f"{g.get('holds')} of {g.get('of')}",
            joined(g["missed"]) if "missed" in g else "-",
        ]
        for name, g in (p.get("goals") or {}).items()
    ]
    return (
        PEERS_INTRO.format(feature_map=p.get("feature_map"), targets=p.get("targets_fitted"))
        + "\n"
        + image(plots, "peers.png", "check-ring MAE over the floor, each model and peer, per campaign")
        + "\n"
        + table(["goal", "holds", "missed on"], goals)
        + "\n"
        + table(
            ["campaign", *(n.replace("_", " ") for n in names), "ratio best project / best peer", "diagnosis's after", "nested after"], rows
        )
        + "\n**95 % bands on the check rings** (mean curves / single touches):\n\n"
        + table(
            [
                "campaign",
                "peer GP coverage",
                "peer GP mean half-width (um)",
                "trilinear Monte Carlo coverage",
                "its mean half-width (um)",
                "GP data part Monte Carlo coverage",
                "its mean half-width (um)",
            ],
            bands,
        )
        + "\n**Fit / predict seconds** (first campaign):\n\n"
        + table(["model", "fit / predict"], timing)
        + "\n"
    )


SECTIONS: dict[str, Callable[[Mapping[str, Any], Plots], str]] = {
    "data_efficiency": data_efficiency,
    "speed": speed,
    "scale": lambda r, p: scale(r),
    "diagnosis_calibration": calibration,
    "population": lambda r, p: population(r),
    "deciding": lambda r, p: deciding(r),
    "hidden_effects": lambda r, p: hidden_effects(r),
    "uncertainty_coverage": lambda r, p: coverage(r),
    "large_campaign": lambda r, p: large_campaign(r),
    "fleet": lambda r, p: fleet(r),
    "peers": peers,
}


def render(results: Mapping[str, Any], plots: Plots) -> str:
    """The whole page: the run, the targets, then each section of results.json."""
    parts = [overview(results)]
    for name, write in SECTIONS.items():
        if name in results:
            parts.append(write(results, plots))
    for name, data in results.items():
        if name not in SECTIONS and name not in METADATA:
            parts.append(other_section(name, data))
    return "\n\n".join(parts) + "\n"


VERDICT_RATES_MARKER = "<!-- verdict-rates -->"


def verdict_rates(results: Mapping[str, Any]) -> str:
    """The population's verdicts by kind of head, and each verdict's own figure, for the diagnosis
    page (in place of VERDICT_RATES_MARKER): the figures beside the promises, never copied by hand."""
    pop = results.get("population") or {}
    if not pop:
        return "*No population run in benchmarks/results.json yet.*\n"
    groups = {"healthy": "healthy heads", "catalog_effect": "one catalog effect hidden", "outside_catalog": "one effect in no catalog"}
    counts = {g: get(pop, g, "verdicts") or {} for g in groups}
    totals = {g: sum(counts[g].values()) for g in groups}

    def cell(group: str, verdict: str) -> str:
        k, n = counts[group].get(verdict, 0), totals[group]
        return f"{k} of {n} ({pct(k / n if n else None)})"

    own = {
        "none": f"false alarms on healthy heads {share_of(get(pop, 'healthy', 'false_alarm'))}; same verdict on another noise draw {share_of(pop.get('stability'))}",
        "missing": f"the hidden catalog effect found {share_of(get(pop, 'catalog_effect', 'found'))}; its parameters within U "
        f"{share_of(get(pop, 'catalog_effect', 'truth_within_u'))}; an effect in no catalog called missing {share_of(get(pop, 'outside_catalog', 'missing'))}",
        "suggested": "no claim; `design --decide` proposes the rings that would confirm or refute it",
        "partial": "its found effect counts as found in the row above; what is left is read in the signature",
        "unexplained": f"the signature's first variable of the right joint {share_of(get(pop, 'outside_catalog', 'signature_right_first'))}",
    }
    rows = [[f"`{v}`", *(cell(g, v) for g in groups), own[v]] for v in ("none", "missing", "suggested", "partial", "unexplained")]
    note = (
        f"\nMeasured by the benchmark [population](benchmarks.md#population) on commit {pop.get('commit') or pop.get('code_sha256')} "
        f"({pop.get('mode')} run); intervals are 95 % Clopper-Pearson.\n"
    )
    return table(["verdict", *groups.values(), "its own figure"], rows) + note


def load(path: Path = RESULTS) -> dict[str, Any]:
    return json.loads(path.read_text(encoding="utf-8"))


if __name__ == "__main__":
    print(render(load(), {name: f"img/benchmarks/{name}" for name in PLOTS if (RESULTS.parent / name).is_file()}))
