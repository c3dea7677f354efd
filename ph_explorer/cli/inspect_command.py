"""`ph-explorer inspect FILE.csv [--json]`: what a campaign holds, as aligned text or one JSON object."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ph_explorer.geometry import A_LIMIT_DEG
from ph_explorer.io import campaign_summary, read_campaign
from ph_explorer.io.writer import angle_text


def inspect_command(file: Path, json_output: bool = False, geometry: dict[str, Any] | None = None) -> int:
    """Print what the campaign holds (campaign_summary), as text or as one JSON object."""
    summary = campaign_summary(read_campaign(file, geometry))
    if json_output:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(summary_text(summary))
    return 0


def _values(v: list[float]) -> str:
    return ", ".join(angle_text(x) for x in v) if v else "-"


def _pairs(v: list[list[float]] | None) -> str:
    if not v:
        return "none"
    return ", ".join(f"A{angle_text(a)} B{angle_text(b)}" for a, b in v)


def summary_text(s: dict[str, Any]) -> str:
    """The human-readable report of a campaign_summary: one label and one value a line, aligned."""
    g = s["geometry"]
    sigma = "n/a (one repetition)" if s["noise_sigma_um"] is None else f"{s['noise_sigma_um']:.4f} um"
    ront = s["mean_curve_ront_um"]
    sweep = s["joint_sweep_deg"]
    rows = [
        ("file", str(s["file"])),
        ("orientations", f"{s['orientations']} ({s['grid_orientations']} on the lattice, {len(s['off_grid'])} off it)"),
        ("repetitions", str(s["repetitions"])),
        ("points per circle", str(s["points"])),
        ("touches", str(s["touches"])),
        ("lattice A_deg", _values(s["grid"]["A_deg"])),
        ("lattice B_deg", _values(s["grid"]["B_deg"])),
        ("off-grid", _pairs(s["off_grid"])),
        ("check orientations", "from the off-grid rings" if s["check_orientations"] is None else _pairs(s["check_orientations"])),
        ("noise sigma", f"{sigma} per touch (pooled repetition std)"),
        ("deviations", f"{s['deviation_range_um'][0]:.3f} .. {s['deviation_range_um'][1]:.3f} um"),
        ("mean-curve RONt", f"{ront['min']:.3f} / {ront['median']:.3f} / {ront['max']:.3f} um (min / median / max)"),
        ("touch times", "yes" if s["has_times"] else "no (file order is the touch order)"),
        (
            "geometry",
            f"L = {g['pivot_to_ball_mm']:g} mm, ball {g['ball_diameter_mm']:g} mm, bore {g['bore_diameter_mm']:g} mm, "
            f"cone half-angle {s['cone_half_angle_deg']:.2f} deg",
        ),
        (
            "joint sweep per ring",
            f"A up to {sweep['A_max']:.1f} deg, B {sweep['B_min']:.1f} .. {sweep['B_max']:.1f} deg",
        ),
        (
            "rings near the pole",
            _pairs(s["near_pole"])
            + ("" if not s["near_pole"] else " (B turns over a quarter turn as A moves: interpolation between rings is poorest here)"),
        ),
        ("unreachable touches", f"{s['unreachable_touches']} (A joint beyond +-{A_LIMIT_DEG:g} deg)"),
    ]
    if s["scenario"]:
        scenario = dict(s["scenario"])
        description = scenario.pop("description", None)
        hidden = scenario.pop("hidden_effects", 0)
        rows.append(("scenario", ", ".join(f"{k} = {v}" for k, v in scenario.items())))
        if description:
            rows.append(("", str(description)))
        if hidden:  # counted, not named: a teaching exercise (the sidecar's hidden list is the answer)
            rows.append(("hidden effects", f"{hidden} (the sidecar's [scenario] hidden list names them)"))
    width = max(len(label) for label, _ in rows)
    return "\n".join(f"{label:<{width}}  {value}" for label, value in rows)
