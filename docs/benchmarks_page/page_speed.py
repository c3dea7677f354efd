"""The benchmarks page's `## Speed` section (`speed`): the steps a user waits for, one at a time."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import Plots, get, holds, image, joined, num, table

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
