"""The benchmarks page's `## Diagnosis calibration` section (`diagnosis_calibration`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import Plots, folded, get, holds, image, num, pct, pct_interval, table

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
