"""Each rotary-axis error motion and the ball form hidden in the paper campaign, and each location
error in the near_vertical design: is it named? (issue 14)

For each entry of CASES the paper scenario gets one more effect, hidden, at a size a real head
can have (NEAR_VERTICAL_CASES: the near_vertical scenario, its own hidden effect replaced); the campaign (the scenario's own seed) is diagnosed as a user would (`diagnose`, the
default catalog). Recorded: the verdict, the effects found with their parameters and expanded
uncertainties, whether the hidden effect is named first at its true period with every true
amplitude and phase inside fit +- U, the candidates the top one is confounded with, the check-ring
MAE (against the mean of the repetitions) before and after with the floor, the nested "after",
and the seconds. Each case is a task of ph_explorer.task_runner on the client the run gives (simulated
and diagnosed on its worker). `run(quick=True)` runs the first case only.
"""

from __future__ import annotations

import copy
import time
import tomllib
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from benchmarks.calibration import over_floor
from benchmarks.population import error_over_u
from ph_explorer.diagnosis import diagnose
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.paths import scenarios_dir
from ph_explorer.task_runner import run_tasks
from ph_explorer.twin import scenario_from_dict, simulate

if TYPE_CHECKING:
    from dask.distributed import Client

CASES: dict[str, dict[str, float]] = {
    "b_axis_radial_motion": {"x_amplitude_um": 0.5, "x_phase_deg": 30.0, "y_amplitude_um": 0.3, "y_phase_deg": 120.0, "cycles_per_rev": 17},
    "b_axis_axial_motion": {"amplitude_um": 0.6, "phase_deg": 60.0, "cycles_per_rev": 19},
    "b_axis_tilt_motion": {
        "about_x_amplitude_arcsec": 1.0,
        "about_x_phase_deg": 10.0,
        "about_y_amplitude_arcsec": 0.5,
        "about_y_phase_deg": 200.0,
        "cycles_per_rev": 14,
    },
    "a_axis_radial_motion": {"y_amplitude_um": 0.6, "y_phase_deg": 50.0, "z_amplitude_um": 0.4, "z_phase_deg": 140.0, "cycles_per_rev": 23},
    "a_axis_axial_motion": {"amplitude_um": 0.8, "phase_deg": 20.0, "cycles_per_rev": 21},
    "a_axis_tilt_motion": {
        "about_y_amplitude_arcsec": 1.2,
        "about_y_phase_deg": 70.0,
        "about_z_amplitude_arcsec": 0.8,
        "about_z_phase_deg": 300.0,
        "cycles_per_rev": 25,
    },
    "ball_form": {"amplitude_um": 0.2, "phase_deg": 40.0, "lobes": 4.0},
}
# The rotary axes' location errors, hidden in the near_vertical design (the paper's campaign and five
# held-out rings between A0 = 0 and 15 deg, the only rings where they are not interpolated) in place of
# its own hidden effect: name -> (effect id, its parameters).
NEAR_VERTICAL_CASES: dict[str, tuple[str, dict[str, float]]] = {
    "near_vertical: b_axis_position": ("b_axis_position", {"x_offset_um": 1.5, "y_offset_um": -1.0}),
    "near_vertical: b_axis_orientation": ("b_axis_orientation", {"about_x_arcsec": 6.0, "about_y_arcsec": -4.0}),
    "near_vertical: a_axis_position": ("a_axis_position", {"y_offset_um": 1.5, "z_offset_um": -1.0}),
    "near_vertical: a_axis_squareness": ("a_axis_squareness", {"about_y_arcsec": 6.0}),
}


def covered(effect_id: str, truth: dict[str, float], found: dict[str, Any]) -> bool:
    """Every true parameter the fit reports within fit +- U (phases wrapped by their period)."""
    return all(ratio <= 1.0 for ratio in error_over_u(effect_id, truth, found))


def one(effect_id: str, truth: dict[str, float], design: str = "paper") -> dict[str, Any]:
    """The design's scenario with its own hidden effects taken out and this one hidden, diagnosed."""
    data = copy.deepcopy(tomllib.loads((scenarios_dir() / f"{design}.toml").read_text(encoding="utf-8")))
    data["name"] = f"{design}+{effect_id}"
    data["effects"] = [e for e in data["effects"] if not e.get("hidden")] + [{"id": effect_id, "hidden": True, **truth}]
    campaign = simulate(scenario_from_dict(data))
    start = time.perf_counter()
    result = diagnose(campaign)
    seconds = time.perf_counter() - start
    found = [
        {
            "effect": c.effect,
            "settings": {k: float(v) for k, v in c.settings.items()},
            "params": {k: round(float(v), 4) for k, v in c.params.items()},
            "params_u": {k: round(float(v), 4) for k, v in c.params_u.items()},
        }
        for c in result.found
    ]
    scanned = {k: float(v) for k, v in truth.items() if k in DEFAULT_CATALOG[effect_id].scan}
    first = found[0] if found else None
    named_first = bool(first and first["effect"] == effect_id and all(first["settings"].get(k) == v for k, v in scanned.items()))
    top = result.candidates[0]
    return {
        "hidden": {"effect": effect_id, **truth},
        "verdict": result.verdict,
        "found": found,
        "named_first_at_its_period": named_first,
        "named_as": first["effect"] if first else None,
        "truth_within_u": bool(named_first and covered(effect_id, truth, first)),
        "top_confounded_with": [o.effect for o in top.confounded_with],
        "check_rings_mae_mean_um": {"before": round(result.steps[0].mae_um["mean"], 4), "after": round(result.steps[-1].mae_um["mean"], 4)},
        "noise_floor_mean_um": round(result.steps[-1].noise_floor_um["mean"], 4),
        "after_over_floor": over_floor(result.steps[-1]),
        "nested_mae_mean_um": None
        if result.nested is None
        else {"before": round(result.nested.before_um["mean"], 4), "after": round(result.nested.after_um["mean"], 4)},
        "seconds": round(seconds, 1),
    }


def one_case(case: tuple[str, str, dict[str, float]]) -> dict[str, Any]:
    """one() of a (design, effect id, truth) case: a task's input is one value."""
    design, effect_id, truth = case
    return one(effect_id, truth, design)


def run(client: Client, quick: bool = False, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every case as a task on the client's workers; the results["hidden_effects"] object."""
    cases = {name: ("paper", name, truth) for name, truth in CASES.items()}
    cases |= {name: ("near_vertical", effect_id, truth) for name, (effect_id, truth) in NEAR_VERTICAL_CASES.items()}
    if quick:
        cases = dict(list(cases.items())[:1])

    def said(r: dict[str, Any]) -> None:
        log(
            f"  {r['hidden']['effect']}: {r['verdict']}, found {[f['effect'] for f in r['found']]}, named first {r['named_first_at_its_period']}, "
            f"truth within U {r['truth_within_u']}, check MAE {r['check_rings_mae_mean_um']} (floor {r['noise_floor_mean_um']}), {r['seconds']} s"
        )

    out = dict(zip(cases, run_tasks(client, one_case, list(cases.values()), on_result=said).results))
    paper = [r for name, r in out.items() if name in CASES]
    return {
        "mode": "quick" if quick else "full",
        "scenario": "paper (or near_vertical where the case says) + one hidden effect (the scenario's seed)",
        "cases": out,
        "named_first": sum(r["named_first_at_its_period"] for r in paper),
        "of": len(paper),
        "within_1_3_floor": sum(r["after_over_floor"] <= 1.3 for r in paper),
    }
