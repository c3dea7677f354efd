"""PNG plots of the results (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402

from ph_explorer.models.off_the_shelf import PEER_MODELS  # noqa: E402

COLORS = {"network": "tab:blue", "trilinear": "tab:orange", "hybrid": "tab:green"}


def data_efficiency_plot(results: dict[str, Any], path: Path) -> Path:
    curves, details = results["data_efficiency"], results["data_efficiency_details"]
    fig, axes = plt.subplots(1, len(curves), figsize=(6.5 * len(curves), 5.0), squeeze=False)
    for ax, (scenario, models) in zip(axes[0], curves.items()):
        designs = details[scenario].get("design")
        for name, points in models.items():
            # Lattice subsets joined by a line; designed subsets (ph_explorer.planning.ring_design) as open squares.
            kinds = designs if designs and len(designs) == len(points) else ["lattice"] * len(points)
            lattice = [p for p, d in zip(points, kinds) if d.startswith("lattice")]
            designed = [p for p, d in zip(points, kinds) if not d.startswith("lattice")]
            if lattice:
                n, mae = zip(*lattice)
                ax.plot(n, mae, "o-", color=COLORS.get(name), label=name)
            if designed:
                n, mae = zip(*sorted(designed))
                ax.plot(n, mae, "s--", mfc="none", color=COLORS.get(name), label=f"{name}, designed rings")
        floor = details[scenario]["noise_floor_um"]["mean"]
        ax.axhline(floor, color="grey", ls="--", label=f"noise floor {floor:.3f} um")
        full = max(models["trilinear"], key=lambda p: p[0])
        ax.axhline(full[1], color=COLORS["trilinear"], ls=":", lw=1, label=f"full-data trilinear {full[1]:.3f} um")
        ax.axvline(full[0] / 5, color="grey", ls=":", label="1/5 of the orientations")
        ax.axvline(12, color="tab:green", ls=":", lw=1, label="12 rings (the design goal)")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks(sorted({p[0] for p in models["trilinear"]}))
        ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%.2f"))
        ax.yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%.2f"))
        ax.set_xlabel("training orientations")
        ax.set_ylabel("check-ring MAE vs 10-repetition mean (um)")
        ax.set_title(scenario)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7, ncol=2, loc="upper right", framealpha=0.6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def speed_plot(results: dict[str, Any], path: Path) -> Path:
    speed, scale = results["speed"], results.get("scale", {})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    labels, values = [], []
    diagnosis = speed.get("diagnosis") or {}
    entries = [
        ("network training", speed.get("network_training") or {}),
        ("physics refit", speed.get("physics_refit") or {}),
        ("diagnosis, paper", {"seconds": (diagnosis.get("paper") or {}).get("seconds_median")}),
        ("diagnosis, head_3", {"seconds": (diagnosis.get("head_3") or {}).get("seconds_median")}),
        ("serve: URL answers", {"seconds": (speed.get("serve_startup") or {}).get("seconds_from_launch")}),
        ("serve: explorer ready", {"seconds": (speed.get("serve_startup") or {}).get("seconds_to_ready")}),
    ]
    for label, entry in entries:
        value = entry.get("seconds")
        if value is not None:
            labels.append(label)
            values.append(value)
    axes[0].barh(labels, values, color="tab:purple")
    axes[0].set_xlabel("seconds")
    axes[0].set_title(f"speed on {speed['cpu_count']} cores")
    one, shown = speed["slider_update_ms"], scale.get("with_gp") or {}
    room = f"{scale.get('browsers', '?')} browsers"
    # Each group: its render and latency figures, and its own targets drawn over it (kind, ms).
    groups = [
        ("1 browser", one, one.get("latency_ms", {}), [("render p95", one.get("target_p95_ms"))]),
        (
            room,
            scale.get("server_update_ms", {}),
            scale.get("latency_ms", {}),
            [("render p95", scale.get("server_p95_target_ms")), ("latency p95", scale.get("p95_target_ms"))],
        ),
    ]
    if shown:
        groups.append(
            (
                f"{room}, GP shown",
                shown.get("server_update_ms", {}),
                shown.get("latency_ms", {}),
                [("latency p95", scale.get("p95_target_ms"))],
            )
        )
    # Render time (server time of the render) and latency (slider event -> end of its render).
    bars = [("render p50", 1, "p50"), ("render p95", 1, "p95"), ("latency p50", 2, "p50"), ("latency p95", 2, "p95")]
    width = 0.2
    for k, (label, part, q) in enumerate(bars):
        axes[1].bar([i + width * k for i in range(len(groups))], [g[part].get(q) or 0 for g in groups], width=width, label=label)
    for i, (_, _, _, targets) in enumerate(groups):
        for kind, target in targets:
            if target is not None:
                k = [b[0] for b in bars].index(kind)
                x = i + width * k
                axes[1].hlines(target, x - 0.6 * width, x + 0.6 * width, color="red", lw=2)
    axes[1].plot([], [], color="red", lw=2, label="target (over its bar)")
    axes[1].set_xticks([i + 1.5 * width for i in range(len(groups))], [g[0] for g in groups])
    axes[1].set_yscale("log")
    axes[1].yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    axes[1].yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
    axes[1].yaxis.set_minor_locator(matplotlib.ticker.LogLocator(subs=(2.0, 3.0, 5.0)))
    axes[1].tick_params(axis="y", which="minor", labelsize=7)
    axes[1].set_ylabel("ms per slider update (log)")
    axes[1].legend(fontsize=8, ncol=3, loc="lower center", bbox_to_anchor=(0.5, 1.0))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def calibration_plot(results: dict[str, Any], path: Path) -> Path:
    """The diagnosis's detection power against the hidden B 22/rev amplitude, and the false-alarm rate per design."""
    calibration = results["diagnosis_calibration"]
    power = calibration["power"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2), gridspec_kw={"width_ratios": [3, 2]})
    ax = axes[0]
    curve = power["curve"]
    amplitudes = [p["amplitude_arcsec"] for p in curve]
    for key, label, color, shift in (
        ("power", "found b_axis_cyclic 22/rev (missing or partial)", "tab:green", -0.01),
        ("failure_detected", "any verdict but none", "tab:blue", 0.01),
    ):
        values = [p[key] for p in curve]
        low = [v - p[f"{key}_ci95"][0] for v, p in zip(values, curve)]
        high = [p[f"{key}_ci95"][1] - v for v, p in zip(values, curve)]
        ax.errorbar([a + shift for a in amplitudes], values, yerr=[low, high], fmt="o-", color=color, capsize=3, label=label)
        ax.plot([0.0 + shift], [power["at_zero"][key]], "s", color=color, mfc="white")
    ax.axhline(calibration["targets"]["false_alarm_rate_max"], color="red", ls="--", lw=1, label="5 % (false-alarm target)")
    ax.set_xlim(-0.05, max(amplitudes + [0.1]) + 0.1)
    ax.set_ylim(-0.03, 1.03)
    ax.set_xlabel("hidden B-axis 22/rev amplitude (arcsec); squares: the paper campaigns, nothing hidden")
    ax.set_ylabel(f"share of seeds ({len(power['seeds'])} per amplitude, 95 % CI)")
    ax.set_title("detection power")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="center right")

    ax = axes[1]
    rows = [("paper", calibration["false_alarm"])] + list(calibration["designs"].items())
    names = [name for name, _ in rows]
    rates = [r["false_alarm_rate"] for _, r in rows]
    low = [rate - r["false_alarm_ci95"][0] for rate, (_, r) in zip(rates, rows)]
    high = [r["false_alarm_ci95"][1] - rate for rate, (_, r) in zip(rates, rows)]
    ax.barh(names, rates, xerr=[low, high], color="tab:orange", capsize=3)
    for i, (_, r) in enumerate(rows):
        # Beside the interval, or inside the bar's left end when the interval reaches the right edge.
        x = r["false_alarm_ci95"][1] + 0.02 if r["false_alarm_ci95"][1] < 0.85 else 0.02
        ax.text(x, i, f"{r['n'] - r['verdicts'].get('none', 0)} of {r['n']}", va="center", ha="left", fontsize=8)
    ax.axvline(calibration["targets"]["false_alarm_rate_max"], color="red", ls="--", lw=1, label="target 5 %")
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel("false-alarm rate (verdict not none, 95 % CI)")
    ax.set_title("nothing hidden: false alarms per design")
    ax.legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def peers_plot(results: dict[str, Any], path: Path) -> Path:
    """Check-ring MAE over the noise floor (mean reference) of each model and peer, per campaign."""
    rows = results["peers"]["campaigns"]
    names = list(rows[0]["models"]) if rows else []  # the project's models, then the peers, as the run stored them
    fig, ax = plt.subplots(figsize=(13, 1.2 + 0.7 * len(rows)))
    height = 0.8 / len(names)
    for j, name in enumerate(names):
        values = [r["models"][name]["over_floor"]["mean"] for r in rows]
        positions = [i + (j - len(names) / 2 + 0.5) * height for i in range(len(rows))]
        hatch = "//" if name in PEER_MODELS else None
        ax.barh(positions, values, height=height, label=name.replace("_", " "), hatch=hatch)
    after = [r["diagnosis_after"]["over_floor"]["mean"] for r in rows]
    ax.plot(after, range(len(rows)), "D", color="black", ms=5, label="the diagnosis's after (check rings left out one at a time)")
    ax.axvline(1.0, color="black", lw=1, label="noise floor")
    ax.axvline(1.25, color="red", ls="--", lw=1, label="1.25 x floor")
    ax.set_yticks(range(len(rows)), [r["campaign"] for r in rows], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("check-ring MAE against the repetitions' mean / its noise floor")
    ax.set_title("the project's models (plain) and the peers (hatched): scipy RBF, scikit-learn GP")
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))  # beside the bars, never over them
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def adaptive_plot(records_path: Path, path: Path) -> Path | None:
    """The adaptive campaign's loop on three heads (a healthy one, one with a catalog effect, one with
    a shape no catalog holds: the first of each kind that took three plans or more): the evaluation
    rings' MAE after each diagnosis against the rings measured, beside the full campaign's trilinear
    model (dashed) and the evaluation rings' noise floor (dotted)."""
    import json

    if not records_path.exists():
        return None
    records = json.loads(records_path.read_text())["records"]
    fig, ax = plt.subplots(figsize=(8, 4.2))
    for kind, color in (("healthy", "tab:blue"), ("catalog_effect", "tab:orange"), ("unknown_shape", "tab:green")):
        heads = [r for r in records if r["kind"] == kind and "adaptive" in r]
        if not heads:
            continue
        head = next((r for r in heads if len(r["adaptive"]["trajectory"]) >= 3), heads[0])
        rings, _, mae = zip(*head["adaptive"]["trajectory"])
        name = kind.replace("_", " ") + f" (seed {head['seed']}{', ' + head['family'] if 'family' in head else ''})"
        ax.plot(rings, mae, "o-", color=color, label=f"{name}: adaptive, to its stop")
        ax.axhline(
            head["full"]["trilinear_mae_um"], color=color, ls="--", lw=1, label=f"full campaign ({head['full']['rings']} rings), trilinear"
        )
        ax.axhline(head["floor_um"], color=color, ls=":", lw=1)
    ax.set_xlabel("rings measured (fitted and check rings)")
    ax.set_ylabel("evaluation rings' MAE vs their mean, um")
    ax.set_title("measure until you know: the error at rings neither campaign measured (dotted: their floor)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
