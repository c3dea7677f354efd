"""The adaptive campaign against the full one, over the population's heads (issue 58).

Each head is one of the population's (benchmarks/population.py: healthy and catalog-effect heads of
their seeds; benchmarks/unknown_population.py: unknown-shape heads, the families in turn). On its
twin, ph_explorer.planning.adaptive runs plan, measure, diagnose, next until a plan stops (no
budget: it stops when it knows, or when no lattice ring is left to add). The full paper-style
campaign of the same head is what the population diagnosed. Both are judged on EVALUATION_RINGS
rings of their own: drawn from the head's seed off both campaigns' grids (A0 not a multiple of 5
deg), measured at EVALUATION_REPETITIONS repetitions after the campaign. Per kind, with 95 %
intervals:

- rings and minutes at the machine to the stop (median, 90th percentile), and the full campaign's;
- the evaluation rings' MAE against their mean at the stop (the last diagnosis's hybrid, or its
  data part when it found nothing) over the full campaign's trilinear model's: the share of heads
  at most 1.1x (the issue's target: >= 90 %), and the median ratio; each against the floor;
- the verdict at the stop against the full campaign's (the same word), the same claims, and
  claims in the head (every effect claimed is one the head holds: its background's or the hidden one;
  a sparse campaign's data part interpolates less of the background, whose effects then show);
- the same answer about what the head hides (same_answer): a hidden catalog effect held by a claim
  of both or of neither (multi_effects.holds_truth: a pair the rings did not tell apart holding it
  counts, as the diagnosis names both); on an unknown-shape head whose shape has a group, the same
  of four answers (unknown_answer: its axis and group named, `none`, a catalog effect of another
  mechanism, or left open), for its own mechanism named is an answer about it even where the
  head's background holds that effect too; on the other heads both quiet (`none`, or claims of the
  head's own background only, as the population judges a healthy head's alarm) or both not. The
  words differ where the sparse campaign's model, physical where the full one's trilinear
  interpolates, names background effects the full campaign leaves to its data part;
- the right answer (right_answer: what the twin hid, judged as same_answer compares), of each
  campaign, and the stop as right as the full campaign (as_right: the same answer, or the right one
  where the full campaign's is not): the same answer counts a stop that finds what the full
  campaign missed as a failure, as right only what the stop loses.

The same figures over the whole population ("population"), where the issue's targets are set.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from benchmarks.calibration import code_version, commit, rate
from benchmarks.multi_effects import claim_record, holds_truth
from benchmarks.population import FIRST_SEED, head_of
from benchmarks.unknown_population import FIRST_SEED as UNKNOWN_SEED, catalog_name_other_mechanism, group_right, shape_truth
from benchmarks.unknown_shapes import FAMILIES, unknown_shape_head
from ph_explorer import metrics
from ph_explorer.campaign import orientation_match
from ph_explorer.diagnosis import diagnose
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.models.hybrid import HybridModel
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.planning.closed_loop import adaptive_campaign
from ph_explorer.task_runner import run_tasks
from ph_explorer.twin import simulate
from ph_explorer.twin.random_heads import random_campaign

if TYPE_CHECKING:
    from dask.distributed import Client

COUNT, QUICK_COUNT = 100, 1  # heads of each kind
KINDS = ("healthy", "catalog_effect", "unknown_shape")
EVALUATION_RINGS, EVALUATION_REPETITIONS = 10, 10
RECORDS = Path(__file__).with_name("adaptive_records.json")
TARGETS = {"median_rings_max": 20, "mae_ratio": 1.1, "mae_within_ratio_min": 0.90, "verdict_agreement_min": 0.90}


def head(job: dict[str, Any]) -> tuple[Any, Any, dict[str, Any] | None]:
    """(the head's scenario, its full campaign as the population diagnosed it, an unknown shape's truth)."""
    if job["kind"] == "unknown_shape":
        unknown = unknown_shape_head(job["seed"], job["family"])
        return unknown.scenario, unknown.campaign, {k: v for k, v in unknown.truth.items() if isinstance(v, (int, float, str, dict))}
    scenario, truth = head_of({"group": "healthy" if job["kind"] == "healthy" else "catalog_effect", "seed": job["seed"]})
    seed = job["seed"] if truth is None else truth["head_seed"]
    return scenario, random_campaign(seed, None, scenario.effects[-1:] if truth is not None else ()), None


def evaluation_rings(seed: int, known: np.ndarray) -> np.ndarray:
    """EVALUATION_RINGS reachable orientations off every grid the campaigns use (A0 not a multiple
    of 5 deg, B0 not of 10 deg), none measured by the full campaign."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 58]))
    out: list[list[float]] = []
    while len(out) < EVALUATION_RINGS:
        a, b = float(rng.integers(3, 88)), float(rng.integers(-179, 180))
        if a % 5 == 0 or b % 10 == 0 or orientation_match(np.array([[a, b]]), known).any() or [a, b] in out:
            continue
        out.append([a, b])
    return np.array(out)


def model_of(result: Any, campaign: Any) -> Any:
    """A diagnosis's model: its hybrid (the effects it claimed), else its data part alone, fitted on
    the campaign as the diagnosis judged it."""
    if result.hybrid is not None:
        return result.hybrid
    judged = result.judged(campaign)
    return HybridModel([]).fit(judged, ~judged.holdout_mask())


def mae_vs_mean(model: Any, rings: np.ndarray, mean: np.ndarray) -> float:
    return float(np.mean(np.abs(model.predict(rings, mean.shape[-1]) - mean)))


def one_head(job: dict[str, Any]) -> dict[str, Any]:
    """The head's adaptive campaign and its full one, judged on the same evaluation rings."""
    scenario, full, truth = head(job)
    rings = evaluation_rings(job["seed"], full.orientations)
    after = replace(scenario.at_rings(rings), repetitions=EVALUATION_REPETITIONS)
    evaluation = simulate(after)
    mean = evaluation.deviations.mean(axis=1)
    floor = metrics.noise_floor(evaluation.noise_sigma_um(), EVALUATION_REPETITIONS)["mean"]
    started = time.perf_counter()
    full_result = diagnose(full)
    full_seconds = time.perf_counter() - started
    trilinear = TrilinearModel().fit(full, ~full.holdout_mask())
    started = time.perf_counter()
    run = adaptive_campaign(scenario)
    adaptive_seconds = time.perf_counter() - started
    last = run.results[-1]
    # Each diagnosis's model on the evaluation rings, against the rings measured: the loop's trajectory.
    trajectory = [
        [plan.measured_rings, round(plan.spent_minutes, 1), round(mae_vs_mean(model_of(result, measured), rings, mean), 5)]
        for plan, result, measured in zip(run.plans[1:], run.results, run.campaigns)
    ]
    return {
        **job,
        "full": {
            "rings": full.n_orientations,
            "minutes": round(float(np.ptp(scenario.times_s())) / 60.0, 1),  # at the head's cadence, times in its CSV or not
            "verdict": full_result.verdict,
            "found": sorted(c.effect for c in full_result.found),
            "claims": [claim_record(c) for c in full_result.found],
            "shapes": shape_records(full_result),
            "suggested": sorted(c.effect for c in full_result.suggested),
            "trilinear_mae_um": round(mae_vs_mean(trilinear, rings, mean), 5),
            "seconds": round(full_seconds, 2),
        },
        "adaptive": {
            "rings": run.campaign.n_orientations,
            "check_rings": int(run.campaign.holdout_mask().sum()),
            "plans": len(run.plans),
            "minutes": round(run.plans[-1].spent_minutes, 1),
            "stopped": run.stopped,
            "reason": run.plans[-1].reason,
            "verdict": last.verdict,
            "found": sorted(c.effect for c in last.found),
            "claims": [claim_record(c) for c in last.found],
            "shapes": shape_records(last),
            "suggested": sorted(c.effect for c in last.suggested),
            "mae_um": trajectory[-1][2],  # the model at the stop: the trajectory's last
            "rings_by_plan": [len(p.rings) for p in run.plans],
            "trajectory": trajectory,  # [rings measured, minutes, evaluation MAE um] after each diagnosis
            # What each diagnosis answered, for stop rules read off the records (a stop only truncates the run).
            "answers": [
                {
                    "verdict": result.verdict,
                    "found": sorted(c.effect for c in result.found),
                    "claims": [claim_record(c) for c in result.found],
                    "shapes": shape_records(result),
                    "suggested": sorted(c.effect for c in result.suggested),
                    "unseen_um": None if plan.unseen_um is None else list(plan.unseen_um),
                    "check_rings": int(measured.holdout_mask().sum()),
                }
                for plan, result, measured in zip(run.plans[1:], run.results, run.campaigns)
            ],
            "seconds": round(adaptive_seconds, 2),
        },
        "floor_um": round(float(floor), 5),
        "in_head": sorted({effect.id for effect in scenario.effects}),
        "hidden": scenario.hidden_ids,
        "hidden_settings": {e.id: {k: float(v) for k, v in e.settings().items()} for e in scenario.effects if e.id in scenario.hidden_ids},
        "truth": truth,  # an unknown shape's (None: a healthy or catalog-effect head)
    }


def shape_records(result: Any) -> list[dict[str, Any]]:
    """The shapes a diagnosis tried, as unknown_population judges them (group_right)."""
    return [{"group": s.group, "claimed": s.claimed, "untold": list(s.untold)} for s in result.shapes]


def quiet(side: dict[str, Any], background: set[str]) -> bool:
    """No alarm about what the head hides: `none`, or `missing` or `suggested` naming only effects of
    the head's own background (as population.alarm judges a healthy head)."""
    named = set(side["found"]) | set(side.get("suggested", []))
    return side["verdict"] == "none" or (side["verdict"] in ("missing", "suggested") and bool(named) and named <= background)


def held(record: dict[str, Any], side: dict[str, Any], effect: str) -> bool:
    """A hidden catalog effect held by a claim of one campaign (multi_effects.holds_truth)."""
    return any(holds_truth(claim, effect, record["hidden_settings"][effect]) for claim in side["claims"])


def answer(record: dict[str, Any], side: dict[str, Any]) -> tuple[bool, ...] | str | bool:
    """What one campaign answers about what the head hides, in the terms the truth is judged in: each
    hidden catalog effect held by a claim or not (holds_truth); an unknown shape's answer
    (unknown_answer); else whether it is quiet (a healthy head, a ring measured badly, touch outliers)."""
    hidden = record.get("hidden", [])
    catalog = [effect for effect in hidden if effect in DEFAULT_CATALOG]
    if record["kind"] == "catalog_effect" and catalog:
        return tuple(held(record, side, effect) for effect in catalog)
    if record["kind"] == "unknown_shape" and shape_truth(record) is not None:
        return unknown_answer(record, side)
    return quiet(side, set(record["in_head"]) - set(hidden))


def same_answer(record: dict[str, Any]) -> bool:
    """The stop and the full campaign answer alike about what the head hides (answer)."""
    return answer(record, record["full"]) == answer(record, record["adaptive"])


def right_answer(record: dict[str, Any], side: dict[str, Any]) -> bool:
    """One campaign's answer is what the twin hid (answer): every hidden catalog effect held by a
    claim; an unknown shape's axis and group named; else quiet."""
    said = answer(record, side)
    return said == "named" if isinstance(said, str) else all(said) if isinstance(said, tuple) else said


def as_right(record: dict[str, Any]) -> bool:
    """The stop loses nothing the full campaign knew: the same answer, or the right one where the full
    campaign's is not (right_answer). Agreement alone counts an adaptive campaign that finds what the
    full one missed as a failure (docs/planning.md#what-it-buys)."""
    return same_answer(record) or right_answer(record, record["adaptive"])


def unknown_answer(record: dict[str, Any], side: dict[str, Any]) -> str:
    """What one campaign said of a head's unknown shape, as the unknown-shape population judges it:
    its axis and group named (group_right: a shape on its group, or a claim of its own mechanism),
    `none`, a catalog claim of another mechanism (catalog_name_other_mechanism), or left open
    (unexplained, partial, suggested, a shape of another group)."""
    judged = {"family": record["family"], "truth": record["truth"], **{k: side[k] for k in ("verdict", "claims", "shapes")}}
    if group_right(judged):
        return "named"
    if side["verdict"] == "none":
        return "none"
    return "another mechanism" if catalog_name_other_mechanism(judged) else "open"


def jobs(count: int) -> list[dict[str, Any]]:
    families = list(FAMILIES)
    out = [{"kind": "healthy", "seed": FIRST_SEED["healthy"] + i} for i in range(count)]
    out += [{"kind": "catalog_effect", "seed": FIRST_SEED["catalog_effect"] + i} for i in range(count)]
    out += [{"kind": "unknown_shape", "seed": UNKNOWN_SEED + i, "family": families[i % len(families)]} for i in range(count)]
    return out


def quantile(values: list[float], q: float) -> float:
    return round(float(np.quantile(values, q)), 1) if values else float("nan")


def figures(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Per kind, and over the population (every head: the issue's targets are the population's)."""
    out: dict[str, Any] = {}
    for kind in (*KINDS, "population"):
        group = [r for r in records if kind in (r["kind"], "population") and "adaptive" in r]
        if not group:
            continue
        rings = [r["adaptive"]["rings"] for r in group]
        minutes = [r["adaptive"]["minutes"] for r in group]
        ratio = [r["adaptive"]["mae_um"] / r["full"]["trilinear_mae_um"] for r in group]
        out[kind] = {
            "heads": len(group),
            "rings": {"median": quantile(rings, 0.5), "p90": quantile(rings, 0.9)},
            "minutes": {"median": quantile(minutes, 0.5), "p90": quantile(minutes, 0.9)},
            "full_rings": {"median": quantile([r["full"]["rings"] for r in group], 0.5)},
            "full_minutes": {"median": quantile([r["full"]["minutes"] for r in group], 0.5)},
            "stopped": rate(sum(r["adaptive"]["stopped"] for r in group), len(group)),
            "mae_within_ratio": rate(sum(x <= TARGETS["mae_ratio"] for x in ratio), len(group)),
            "mae_ratio_median": round(float(np.median(ratio)), 3),
            "adaptive_over_floor_median": round(float(np.median([r["adaptive"]["mae_um"] / r["floor_um"] for r in group])), 3),
            "trilinear_over_floor_median": round(float(np.median([r["full"]["trilinear_mae_um"] / r["floor_um"] for r in group])), 3),
            "verdict_agreement": rate(sum(r["adaptive"]["verdict"] == r["full"]["verdict"] for r in group), len(group)),
            "claims_agreement": rate(sum(r["adaptive"]["found"] == r["full"]["found"] for r in group), len(group)),
            # the same answer about what the head hides, the words aside (same_answer)
            "same_answer": rate(sum(same_answer(r) for r in group), len(group)),
            # what the twin hid, answered rightly by the full campaign, by the stop; the stop as right as the full campaign
            "full_right": rate(sum(right_answer(r, r["full"]) for r in group), len(group)),
            "adaptive_right": rate(sum(right_answer(r, r["adaptive"]) for r in group), len(group)),
            "as_right": rate(sum(as_right(r) for r in group), len(group)),
            # a claim of an effect the head holds (its background's or the one hidden in it) is no false claim
            "claims_in_head": rate(sum(set(r["adaptive"]["found"]) <= set(r["in_head"]) for r in group), len(group)),
        }
    return out


def run(client: Client, quick: bool = False, log: Callable[[str], None] = print, count: int | None = None) -> dict[str, Any]:
    """The heads as tasks on the client's workers; the results["adaptive_campaign"] object."""
    started = time.perf_counter()
    code, checkout = code_version(), commit()
    todo = jobs(count or (QUICK_COUNT if quick else COUNT))
    log(f"  {len(todo)} heads, each measured adaptively and in full, on {len(client.scheduler_info()['workers'])} workers")
    ended = 0

    def said(_: dict[str, Any]) -> None:  # a line every ten heads: the run takes about an hour
        nonlocal ended
        ended += 1
        if ended % 10 == 0:
            log(f"  {ended} of {len(todo)} heads ended ({time.perf_counter() - started:.0f} s)")

    records = run_tasks(client, one_head, todo, on_result=said).results
    if not quick:  # each head's record beside results.json (the quick run keeps the last full run's)
        RECORDS.write_text(json.dumps({"code_sha256": code, "records": records}, separators=(",", ":")) + "\n")
    return {
        "mode": "quick" if quick else "full",
        "code_sha256": code,
        "commit": checkout,
        "targets": TARGETS,
        "evaluation": {"rings": EVALUATION_RINGS, "repetitions": EVALUATION_REPETITIONS},
        **figures(records),
        "records": RECORDS.name,
        "run_seconds": round(time.perf_counter() - started, 1),
    }
