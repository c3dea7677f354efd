"""Do the 95 % bands hold 95 % of held-out measurements? And the task's E_n check (issue 17).

For the shipped paper campaign (assets/data/paper.csv with the shipped assets/models/paper) and every
shipped teaching scenario (simulated with its own seed), each model trained without the check
rings: the trilinear tables, the network, and the hybrid (the scenario's known, i.e. not hidden,
effects + a trilinear data part, fitted on the training rings only). Each model's own error comes
from the cross-validation of its training rings (`models.model_error`, 5 folds, every fit
without the fold); the bands (`bands.model_bands`, adaptive Monte Carlo) are drawn at the check
orientations. Recorded per model and campaign: the fraction of held-out single touches inside
the touch band and of held-out mean-curve points inside the mean band, for the full band and for
the noise-only band of today (its repeatability component alone), and the budget averaged over
the check rings. On the paper campaign, the task of every check ring (one measurement, 64
touches): simulated RONt and harmonics 2..15 with U (k = 2) against the measured repetitions,
E_n and its count <= 1, and how many single measured RONt fall in the simulated 95 % interval.
Each campaign is a task of ph_explorer.task_runner on the client the run gives (simulated, trained and
sampled on its worker; its Monte Carlo seeded by its place in the run).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from benchmarks.large_campaign import QUICK_EPOCHS
from ph_explorer.campaign import Campaign
from ph_explorer.io import read_campaign
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.folder import load_card, load_models
from ph_explorer.models.gaussian_process import GaussianProcessModel
from ph_explorer.models.hybrid import HybridModel
from ph_explorer.models.network import FourierNetwork, NetworkConfig
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.paths import assets_dir, default_model_dir
from ph_explorer.task_runner import run_tasks
from ph_explorer.twin import Scenario, list_scenarios, load_scenario, simulate
from ph_explorer.uncertainty.bands import COMPONENTS, Sources, band_coverage, calibrate_model_error, model_bands
from ph_explorer.uncertainty.model_error import own_error
from ph_explorer.uncertainty.parameter_spread import parameter_spread
from ph_explorer.uncertainty.task import measured_task, normalised_error, task_uncertainty

if TYPE_CHECKING:
    from dask.distributed import Client

TARGET = (0.93, 0.97)
QUICK_CHECK_RINGS = 2
NDIG = 1  # numerical tolerance: one significant digit of u (JCGM 101 7.9.2); >= 2 batches of 10^4


def known_effects(scenario: Scenario) -> list:
    """The effects a user's hybrid starts with: the scenario's not hidden ones that can be fitted."""
    return [e for e in scenario.starting_effects if e.candidate]


SHIPPED = "paper (shipped data and model)"


def campaign_names(quick: bool) -> list[str]:
    """The shipped paper data first, then each scenario (head_3 alone when quick)."""
    return [SHIPPED, *(["head_3"] if quick else [s.name for s in list_scenarios() if s.name != "paper"])]


def campaign_of(name: str) -> tuple[Campaign, Scenario, dict[str, DeviationModel] | None]:
    """(campaign, scenario, shipped models or None): the shipped data and models for SHIPPED, else
    the scenario simulated with its own seed."""
    if name == SHIPPED:
        return read_campaign(assets_dir() / "data" / "paper.csv"), load_scenario("paper"), load_models(default_model_dir())
    scenario = load_scenario(name)
    return simulate(scenario, scenario.seed), scenario, None


def factories(scenario: Scenario, config: NetworkConfig) -> dict[str, Callable[[], DeviationModel]]:
    return {
        "trilinear": TrilinearModel,
        "network": partial(FourierNetwork, config),
        "hybrid": partial(HybridModel, known_effects(scenario), "trilinear"),
        "gp": GaussianProcessModel,  # its model error from its posterior, not the cross-validation
    }


def one_model(
    make: Callable[[], DeviationModel], campaign: Campaign, check: np.ndarray, shipped: DeviationModel | None, rng: np.random.Generator
) -> dict[str, Any]:
    """Train without the check rings (or take the shipped model), its error, its bands at `check` (a
    subset of the held-out rings in quick mode), their coverage beside the noise-only band's.

    The model error's size is calibrated on held-out rings (`bands.calibrate_model_error`), so a
    ring's band is calibrated on the OTHER held-out rings (leave one ring out): the coverage is
    measured on rings the calibration did not see. The band of the cross-validation alone
    (scale 1) is measured beside it."""
    train = ~campaign.holdout_mask()
    start = time.perf_counter()
    model = shipped if shipped is not None else make().fit(campaign.subset(train))
    fit_s = time.perf_counter() - start
    error = own_error(make, model, campaign, train)  # a GP's posterior, else the cross-validation's
    cv_s = time.perf_counter() - start - fit_s
    spread = parameter_spread(model, campaign.subset(train)) if isinstance(model, HybridModel) else None
    sources = Sources(model, campaign.n_repetitions, error, spread)
    held, means = campaign.holdout_mask(), campaign.mean_curves()
    calibrated: list[Sources] = []
    for ring in np.flatnonzero(check):
        others = held.copy()
        others[ring] = False
        calibrated.append(calibrate_model_error(sources, campaign.orientations[others], means[others]))
    bands = [model_bands(c, campaign.orientations[[ring]], rng=rng, ndig=NDIG)[0] for c, ring in zip(calibrated, np.flatnonzero(check))]
    uncalibrated = model_bands(sources, campaign.orientations[check], rng=rng, ndig=NDIG)
    measured = campaign.deviations[check]
    full, noise = band_coverage(bands, measured), band_coverage(bands, measured, "repeatability")
    cv_only = band_coverage(uncalibrated, measured)
    budget = {k: round(float(np.mean([b.budget_um[k] for b in bands])), 4) for k in bands[0].budget_um}
    # The scale each check ring's band used (local in A where its calibration rings chose a finite width).
    scales = [float(c.error.scale_at(campaign.orientations[[ring]])[0]) for c, ring in zip(calibrated, np.flatnonzero(check))]
    widths = [c.error.calibration_width_deg for c in calibrated]
    return {
        "full_band": {k: round(v, 4) for k, v in full.items()},
        "noise_only_band": {k: round(v, 4) for k, v in noise.items()},
        "cross_validation_only_band": {k: round(v, 4) for k, v in cv_only.items()},
        "model_error_scale": {
            "min": round(min(scales), 3),
            "median": round(float(np.median(scales)), 3),
            "max": round(max(scales), 3),
            "calibration_rings": calibrated[0].error.calibration_rings,
            "kernel_width_deg": sorted({"inf" if not np.isfinite(w) else round(w, 1) for w in widths}, key=str),
        },
        "in_target": all(TARGET[0] <= v <= TARGET[1] for v in full.values()),
        "half_width_um": {
            key: round(float(np.mean([(b.upper[band] - b.lower[band]).mean() / 2 for b in bands])), 4)
            for key, band in (("single", "touch"), ("mean", "mean"))
        },
        "budget_um_mean_over_check_rings": budget,
        "touches": int(measured.size),
        "mean_points": int(measured.shape[0] * measured.shape[2]),
        "trials_per_band": [int(min(b.trials for b in bands)), int(max(b.trials for b in bands))],
        "seconds": {
            "fit": round(fit_s, 1),
            "cross_validation": round(cv_s, 1),
            "bands": round(time.perf_counter() - start - fit_s - cv_s, 1),
        },
        "_sources": calibrated,
    }


def task_check(
    sources_by_model: dict[str, list[Sources]], campaign: Campaign, check: np.ndarray, rng: np.random.Generator
) -> dict[str, Any]:
    """E_n of RONt and harmonics 2..15 at every check ring of the paper campaign, per model (each
    ring's sources calibrated on the other held-out rings)."""
    measured = measured_task(campaign.deviations[check])
    out: dict[str, Any] = {}
    for name, per_ring in sources_by_model.items():
        tasks = [
            task_uncertainty(sources, o, campaign.n_points, rng=rng, ndig=NDIG)
            for sources, o in zip(per_ring, campaign.orientations[check])
        ]
        sim = np.array([[t["ront_um"]["value"]] + [h["value"] for h in t["harmonics_um"].values()] for t in tasks])
        u_sim = np.array([[t["ront_um"]["U"]] + [h["U"] for h in t["harmonics_um"].values()] for t in tasks])
        en = normalised_error(sim, u_sim, measured["value"], measured["U"])
        low = np.array([t["ront_um"]["lower"] for t in tasks])[:, None]
        high = np.array([t["ront_um"]["upper"] for t in tasks])[:, None]
        single = measured["single"][:, :, 0]
        out[name] = {
            "rings": [
                {
                    "A_deg": t["A_deg"],
                    "B_deg": t["B_deg"],
                    "ront_sim_um": t["ront_um"]["value"],
                    "U_sim_um": t["ront_um"]["U"],
                    "ront_measured_um": round(float(measured["value"][i, 0]), 5),
                    "U_measured_um": round(float(measured["U"][i, 0]), 5),
                    "E_n": round(float(en[i, 0]), 3),
                }
                for i, t in enumerate(tasks)
            ],
            "ront_E_n_at_most_1": int(np.sum(en[:, 0] <= 1.0)),
            "harmonics_E_n_at_most_1": int(np.sum(en[:, 1:] <= 1.0)),
            "harmonics_compared": int(en[:, 1:].size),
            "of_rings": int(check.sum()),
            "single_ront_inside_95_interval": round(float(np.mean((single >= low) & (single <= high))), 4),
        }
    return out


def coverage_of(item: tuple[int, str], quick: bool) -> dict[str, Any]:
    """A task: one campaign (item: its place in the run, which seeds its Monte Carlo, and its name),
    every model's coverage, and on the shipped campaign the task's E_n; with the lines to log."""
    index, name = item
    rng = np.random.default_rng([17, index])
    campaign, scenario, shipped = campaign_of(name)
    config = NetworkConfig(max_epochs=QUICK_EPOCHS, early_stopping_patience=10) if quick else NetworkConfig()
    if shipped is not None and not quick:
        config = NetworkConfig.from_dict(load_card(default_model_dir())["network"]["hyperparameters"])
    check = campaign.holdout_mask()
    if quick:  # a smoke test: the first two check rings
        check = check & (np.cumsum(check) <= QUICK_CHECK_RINGS)
    entry: dict[str, Any] = {}
    lines = []
    for model_name, make in factories(scenario, config).items():
        if model_name == "hybrid" and not known_effects(scenario):
            continue
        own = None if shipped is None or quick else shipped.get(model_name)
        entry[model_name] = r = one_model(make, campaign, check, own, rng)
        lines.append(
            f"  {name} {model_name}: full {r['full_band']} cross-validation only {r['cross_validation_only_band']} "
            f"noise-only {r['noise_only_band']} scale {r['model_error_scale']} ({r['seconds']})"
        )
    task: dict[str, Any] = {}
    if shipped is not None:
        task = task_check({m: e["_sources"] for m, e in entry.items()}, campaign, check, rng)
        lines += [
            f"  task {m}: E_n<=1 RONt {t['ront_E_n_at_most_1']}/{t['of_rings']}, harmonics "
            f"{t['harmonics_E_n_at_most_1']}/{t['harmonics_compared']}, single RONt in interval {t['single_ront_inside_95_interval']}"
            for m, t in task.items()
        ]
    for e in entry.values():
        e.pop("_sources")  # the models stay on the worker: the task returns figures
    return {"name": name, "models": entry, "task": task, "lines": lines}


def run(client: Client, quick: bool = False, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every campaign as a task on the client's workers; the results["uncertainty_coverage"] object."""
    started = time.perf_counter()
    items = list(enumerate(campaign_names(quick)))
    done = run_tasks(client, coverage_of, items, on_result=lambda r: [log(line) for line in r["lines"]], quick=quick).results
    results = {r["name"]: r["models"] for r in done}
    task = next(r["task"] for r in done if r["name"] == SHIPPED)
    in_target = {f"{c}/{m}": r["in_target"] for c, models in results.items() for m, r in models.items()}
    return {
        "mode": "quick" if quick else "full",
        "method": "model error from the cross-validation in 5 folds and along A per harmonic, kernel in A (one lattice step), "
        "its variance scaled (localized split-conformal: the 95 % quantile of the scales the mean-curve points of the OTHER "
        "held-out rings need, weighted in A with the width those rings choose by leaving one ring out) (leave one ring out); "
        "the Gaussian process's from its posterior variance, spread over harmonics 2..N/2 as white noise and scaled the same way; "
        "hybrid parameters by the ring jackknife; adaptive Monte Carlo JCGM 101 7.9 (ndig 1, batches of 10^4)",
        "components": list(COMPONENTS),
        "target": list(TARGET),
        "campaigns": results,
        "in_target": in_target,
        "in_target_count": sum(in_target.values()),
        "of": len(in_target),
        "task_paper_check_rings": task,
        "seconds": round(time.perf_counter() - started, 1),
    }
