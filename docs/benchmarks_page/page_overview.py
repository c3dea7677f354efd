"""The benchmarks page's head: how to run the benchmarks, the run (`## The run`) and the targets at a glance."""

from __future__ import annotations

import subprocess
from collections.abc import Iterable, Mapping
from typing import Any

from benchmarks import freshness  # imported with the page (mkdocs puts the checkout on sys.path only then)

from .page_format import get, holds, interval, joined, num, pct, pct_interval, table


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
        ".venv/bin/python -m benchmarks --stale                                 # which sections describe this checkout",
        "```",
        "",
        "A run writes `benchmarks/results.json` and the plots `benchmarks/data_efficiency.png`, "
        "`benchmarks/speed.png`, `benchmarks/calibration.png` and `benchmarks/peers.png`. A run with `--only` keeps every other "
        "section of the last `results.json` as it was and stamps the ones it ran under `updated` (date, mode, "
        "a sha256 of the package's sources, the machine since 2026-12-03): each section below says which run it comes from. "
        "The many diagnoses of the calibration, the population, the hidden effects and the coverage are tasks "
        "of one runner ([`ph_explorer.task_runner`](fleet.md#where-it-runs), the fleet's): on a LocalCluster of the "
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
        current = describes_this_build(results)
        out += [
            "Sections run again since (with `--only`), each measured on the code named by its sha256 (and its commit, "
            "recorded since 2026-11-27). The last column says whether its figures describe the code this page was built "
            "from: none of the package's modules its benchmark can import changed since its commit "
            "(`python -m benchmarks --stale` names them; `benchmarks/freshness.py`).",
            "",
            table(
                ["section", "date", "mode", "code sha256", "commit", "machine", "describes this build"],
                [
                    [
                        name,
                        s.get("date"),
                        s.get("mode"),
                        s.get("code_sha256"),
                        s.get("commit", ""),
                        machine_text(s.get("machine")),
                        current.get(name, "unknown"),
                    ]
                    for name, s in updated.items()
                ],
            ),
        ]
    seconds = results.get("section_seconds") or {}
    if seconds:
        out += ["", "Wall seconds of each section at its last run: " + joined([f"{k} {num(v, 's')}" for k, v in seconds.items()]) + "."]
    out += ["## Targets at a glance", "", table(["section", "target", "result"], list(target_rows(results)))]
    return "\n".join(out)


def machine_text(machine: Mapping[str, Any] | None) -> str:
    """A section's machine in a cell: "the run's" when it has none of its own (stamped before 2026-12-03)."""
    if not machine:
        return "the run's"
    return f"{machine.get('cpu_count')} cores, {machine.get('torch_threads')} torch threads, {machine.get('platform')}"


def describes_this_build(results: Mapping[str, Any]) -> dict[str, str]:
    """Section -> "yes", "no: N modules changed" or "unknown" (benchmarks/freshness.py); {} without git."""
    try:
        states = freshness.states(dict(results))
    except (OSError, subprocess.CalledProcessError):  # a build from files that git does not hold
        return {}
    return {s.section: "unknown" if not s.known else (f"no: {len(s.changed)} modules changed" if s.changed else "yes") for s in states}


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
                f"{holds(speed.get('holds'))}"
                + (
                    f" (the machine's reference workload {num(get(speed, 'machine_reference_s', 'before'), 's')} before, "
                    f"{num(get(speed, 'machine_reference_s', 'after'), 's')} after)"
                    if speed.get("machine_reference_s")
                    else ""
                ),
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
