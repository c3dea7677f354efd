"""The benchmarks page's `## Scale` section (`scale`, `scale_100`): many browsers on one `serve`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import get, holds, joined, num, table

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
