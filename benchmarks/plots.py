"""PNG plots of the results (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402

COLORS = {"network": "tab:blue", "trilinear": "tab:orange", "hybrid": "tab:green"}


def data_efficiency_plot(results: dict[str, Any], path: Path) -> Path:
    curves, details = results["data_efficiency"], results["data_efficiency_details"]
    fig, axes = plt.subplots(1, len(curves), figsize=(5.5 * len(curves), 4.2), squeeze=False)
    for ax, (scenario, models) in zip(axes[0], curves.items()):
        for name, points in models.items():
            n, mae = zip(*points)
            ax.plot(n, mae, "o-", color=COLORS.get(name), label=name)
        floor = details[scenario]["noise_floor_um"]["mean"]
        ax.axhline(floor, color="grey", ls="--", label=f"noise floor {floor:.3f} um")
        full = max(models["trilinear"], key=lambda p: p[0])
        ax.axhline(full[1], color=COLORS["trilinear"], ls=":", lw=1, label=f"full-data trilinear {full[1]:.3f} um")
        ax.axvline(full[0] / 5, color="grey", ls=":", label="1/5 of the orientations")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xticks([p[0] for p in models["trilinear"]])
        ax.xaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%.2f"))
        ax.yaxis.set_minor_formatter(matplotlib.ticker.FormatStrFormatter("%.2f"))
        ax.set_xlabel("training orientations")
        ax.set_ylabel("check-ring MAE vs 10-repetition mean (um)")
        ax.set_title(scenario)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def speed_plot(results: dict[str, Any], path: Path) -> Path:
    speed, scale = results["speed"], results.get("scale", {})
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    labels, values = [], []
    for key, label in (("network_training", "network training"), ("physics_refit", "physics refit"), ("diagnosis", "diagnosis"), ("serve_startup", "serve start-up")):
        entry = speed.get(key) or {}
        value = entry.get("seconds", entry.get("seconds_from_launch"))
        if value is not None:
            labels.append(label)
            values.append(value)
    axes[0].barh(labels, values, color="tab:purple")
    axes[0].set_xlabel("seconds")
    axes[0].set_title(f"speed on {speed['cpu_count']} cores")
    one = speed["slider_update_ms"]
    ms = [("1 browser", one, one.get("latency_ms", {})), (f"{scale.get('browsers', '?')} browsers", scale.get("server_update_ms", {}), scale.get("latency_ms", {}))]
    names = [m[0] for m in ms]
    # Render time (server time of the render) and latency (slider event -> end of its render).
    bars = [("render p50", 1, "p50"), ("render p95", 1, "p95"), ("latency p50", 2, "p50"), ("latency p95", 2, "p95")]
    width = 0.2
    for k, (label, part, q) in enumerate(bars):
        axes[1].bar([i + width * k for i in range(len(ms))], [m[part].get(q) or 0 for m in ms], width=width, label=label)
    axes[1].axhline(20, color="red", ls="--", label="target render p95 20 ms")
    axes[1].set_xticks([i + 1.5 * width for i in range(len(ms))], names)
    axes[1].set_yscale("log")
    axes[1].set_ylabel("ms per slider update (log)")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
