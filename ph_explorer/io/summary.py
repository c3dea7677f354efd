"""What a campaign holds, as JSON-ready values: the `inspect --json` object (cli/inspect_command.py prints it)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.io.sidecar import plain_values
from ph_explorer.kinematics import campaign_touches, joint_sweep_deg, near_pole

# The scenario fields a summary shows (the effects and their parameters are the sidecar's business;
# a teaching scenario's hidden effects are counted, never named: the sidecar's hidden list is the answer).
SCENARIO_FIELDS = ("name", "description", "seed")


def _pairs(orientations: np.ndarray) -> list[list[float]]:
    return [[float(a), float(b)] for a, b in orientations]


def campaign_summary(campaign: Campaign) -> dict[str, Any]:
    """Sizes, lattice, off-grid and check rings, noise, deviation range, geometry, joint sweeps, rings
    near the pole, reach."""
    a_grid, b_grid = campaign.grid()
    off = campaign.off_grid_mask()
    touches = campaign_touches(campaign)
    unreachable = ~np.broadcast_to(touches.reachable, campaign.deviations.shape)
    unreachable_orientations = (~touches.reachable[:, 0, :]).any(axis=1)
    sweep = joint_sweep_deg(touches)
    sigma = campaign.noise_sigma_um()
    ron = np.ptp(campaign.mean_curves(), axis=-1)
    times = campaign.times_s
    return {
        "file": campaign.source,
        "orientations": campaign.n_orientations,
        "repetitions": campaign.n_repetitions,
        "points": campaign.n_points,
        "touches": campaign.n_touches,
        "grid": {"A_deg": [float(v) for v in a_grid], "B_deg": [float(v) for v in b_grid]},
        "grid_orientations": int((~off).sum()),
        "off_grid": _pairs(campaign.orientations[off]),
        "check_orientations": None if campaign.check_orientations is None else _pairs(campaign.check_orientations),
        "noise_sigma_um": None if math.isnan(sigma) else sigma,
        "deviation_range_um": [float(campaign.deviations.min()), float(campaign.deviations.max())],
        "mean_curve_ront_um": {"min": float(ron.min()), "median": float(np.median(ron)), "max": float(ron.max())},
        "has_times": times is not None,
        "time_span_s": None if times is None else [float(times.min()), float(times.max())],
        "geometry": campaign.geometry.as_dict(),
        "cone_half_angle_deg": campaign.geometry.cone_half_angle_deg,
        "joint_sweep_deg": {
            "A_max": float(sweep[:, 0].max()),
            "B_min": float(sweep[:, 1].min()),
            "B_max": float(sweep[:, 1].max()),
        },
        "near_pole": _pairs(campaign.orientations[near_pole(touches)]),
        "unreachable_touches": int(unreachable.sum()),
        "unreachable_orientations": _pairs(campaign.orientations[unreachable_orientations]),
        "scenario": scenario_summary(campaign.scenario) if campaign.scenario else None,
    }


def scenario_summary(scenario: dict[str, Any]) -> dict[str, Any]:
    """Name, description and seed of the scenario a campaign was simulated from, and how many effects it hides."""
    out = {k: v for k, v in plain_values(scenario).items() if k in SCENARIO_FIELDS}
    out["hidden_effects"] = len(scenario.get("hidden") or [])
    return out
