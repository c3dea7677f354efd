"""Calibration of the diagnosis's verdicts (issue 13): false alarms, stability, coverage, power, speed.

Every figure comes from twin campaigns that differ only in the noise seed (`simulate(scenario,
seed)`), each diagnosed as a user would (`diagnose(campaign)`: trilinear baseline, the default
catalog, Monte Carlo seed 0):

1. false_alarm: the "paper" scenario (nothing hidden beyond the usual background): the share of
   seeds whose verdict is not "none" (target at most 5 %, with its 95 % Clopper-Pearson
   interval) and the share of the most common verdict (stability, target at least 95 %).
2. designs: the same on other designs of the paper campaign: 5 repetitions, no touch times,
   another geometry (pivot to ball 100 mm), a coarser lattice (B step 30 deg).
3. stability_with_effect: "head_3": how often the hidden 22/rev B error is found, and how
   often its true amplitude (and phase) lies within the fit +- its expanded uncertainty (k = 2).
4. power: the paper scenario plus a hidden B 22/rev error of growing amplitude: the share of
   seeds where it is found (verdict "missing" or "partial" with b_axis_cyclic at 22/rev among the
   effects found), and the share with any verdict other than "none".
5. seconds_per_diagnosis: the median over the paper campaigns of part 1.

The diagnoses run as tasks of ph_explorer.task_runner on the client the run gives (a LocalCluster of the
cores, or `python -m benchmarks --scheduler ADDRESS`'s cluster; one BLAS thread each), each
simulated on its worker from its scenario and seed; the results do not depend on the order they
finish in. `run(quick=True)` is the smoke mode: a few diagnoses, the same keys.
"""

from __future__ import annotations

import copy
import hashlib
import os
import subprocess
import time
import tomllib
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.stats import binomtest

import ph_explorer
from ph_explorer.diagnosis import VERDICTS, Step, diagnose
from ph_explorer.diagnosis.within_noise import FALSE_ALARM, MEAN_TOLERANCE, RING_LEVEL
from ph_explorer.paths import scenarios_dir
from ph_explorer.task_runner import run_tasks
from ph_explorer.twin import scenario_from_dict, simulate

if TYPE_CHECKING:
    from dask.distributed import Client

TARGET_FALSE_ALARM = 0.05
TARGET_STABILITY = 0.95
TARGET_SECONDS = 30.0
DIAGNOSE_SEED = 0  # the Monte Carlo seed of the diagnosis itself (what a user's run uses)

# Noise seeds, one range per part so that no two parts share a campaign.
FALSE_ALARM_SEEDS = tuple(range(1001, 1201))  # 200: 40 seeds cannot show a rate of 5 % or less
DESIGN_SEEDS = tuple(range(2001, 2021))
EFFECT_SEEDS = tuple(range(3001, 3041))
POWER_SEEDS = tuple(range(4001, 4011))
POWER_AMPLITUDES = (0.1, 0.3, 0.4, 0.5, 0.7, 0.9, 1.1, 1.3)  # arcsec
POWER_CYCLES = 22
QUICK = {
    "false_alarm": 2,
    "designs": 1,
    "effect": 1,
    "power_seeds": 1,
    "power_amplitudes": (1.1,),
}  # the smoke run: every key, few diagnoses

DESIGNS = {
    "repetitions_5": "5 repetitions instead of 10",
    "no_touch_times": "the campaign without t_s (times_s = None)",
    "pivot_100mm": "pivot to ball 100 mm instead of 80",
    "b_step_30": "B lattice step 30 deg instead of 20 (B -160..170); check rings kept where still measured",
}


# -- scenarios -------------------------------------------------------------------------------------
def scenario_data(name: str) -> dict[str, Any]:
    """A shipped scenario's TOML as a dict (edited copies make the designs)."""
    return tomllib.loads((scenarios_dir() / f"{name}.toml").read_text(encoding="utf-8"))


def design_data(design: str) -> tuple[dict[str, Any], bool]:
    """The paper scenario changed by one design, and whether the campaign drops its touch times."""
    data = copy.deepcopy(scenario_data("paper"))
    data["name"] = f"paper/{design}"
    drop_times = False
    if design == "repetitions_5":
        data["repetitions"] = 5
    elif design == "no_touch_times":
        drop_times = True
    elif design == "pivot_100mm":
        data["geometry"]["pivot_to_ball_mm"] = 100.0
    elif design == "b_step_30":
        table = data["orientations"]
        start, stop, _ = table["b_deg"]
        table["b_deg"] = [start, stop, 30]
        a = np.arange(table["a_deg"][0], table["a_deg"][1] + 0.5 * table["a_deg"][2], table["a_deg"][2])
        b = np.arange(start, stop + 15, 30)
        measured = [[float(x), float(y)] for x in a for y in b] + [[float(x), float(y)] for x, y in table["off_grid"]]
        data["check_orientations"] = [c for c in data["check_orientations"] if any(np.allclose(c, m) for m in measured)]
    else:
        raise ValueError(f"unknown design {design!r}")
    return data, drop_times


def power_data(amplitude_arcsec: float) -> dict[str, Any]:
    """The paper scenario plus a hidden B-axis 22/rev error of this amplitude (phase 0)."""
    data = copy.deepcopy(scenario_data("paper"))
    data["name"] = f"paper+b_axis_{POWER_CYCLES}@{amplitude_arcsec:g}"
    data["effects"].append(
        {
            "id": "b_axis_cyclic",
            "hidden": True,
            "amplitude_arcsec": float(amplitude_arcsec),
            "cycles_per_rev": POWER_CYCLES,
            "phase_deg": 0.0,
        }
    )
    return data


def hidden_b_axis(data: dict[str, Any]) -> dict[str, float]:
    """The parameters of a scenario's hidden b_axis_cyclic effect."""
    scenario = scenario_from_dict(data)
    for effect, hidden in zip(scenario.effects, scenario.hidden):
        if hidden and effect.id == "b_axis_cyclic":
            return {k: float(v) for k, v in effect.describe().items() if k != "id"}
    raise ValueError("the scenario hides no b_axis_cyclic effect")


# -- one diagnosis (in a worker) -------------------------------------------------------------------
def _test_dict(test: Any) -> dict[str, Any] | None:
    if test is None:
        return None
    return {
        "fails": bool(test.fails),
        "failing_rings": int(test.failing_rings),
        "statistic": round(float(test.statistic), 3),
        "critical": round(float(test.critical), 3),
        "p_value": round(float(test.p_value), 4),
    }


def diagnose_one(job: dict[str, Any]) -> dict[str, Any]:
    """Simulate one campaign and diagnose it; a compact record of what the diagnosis said."""
    scenario = scenario_from_dict(job["data"], default_name=job["data"].get("name", "scenario"))
    campaign = simulate(scenario, job["seed"])
    if job.get("drop_times"):
        campaign = replace(campaign, times_s=None)
    record: dict[str, Any] = {"group": job["group"], "key": job["key"], "seed": job["seed"]}
    start = time.perf_counter()
    try:
        result = diagnose(campaign, seed=DIAGNOSE_SEED)
    except Exception as error:  # recorded, never lost: one failing design must not end the run
        record.update(verdict="error", error=f"{type(error).__name__}: {error}", seconds=round(time.perf_counter() - start, 2))
        return record
    record["seconds"] = round(time.perf_counter() - start, 2)
    record["verdict"] = result.verdict
    record["found"] = [
        {
            "effect": c.effect,
            "settings": {k: (float(v) if isinstance(v, (int, float, np.number)) else v) for k, v in c.settings.items()},
            "params": {k: round(float(v), 5) for k, v in c.params.items()},
            "params_u": {k: round(float(v), 5) for k, v in c.params_u.items()},
        }
        for c in result.found
    ]
    # The error after the effects found: on the check rings (which took part in choosing them), and
    # nested (chosen without the rings measured), each with its "before" on the same rings.
    record["check_rings_um"] = {"before": result.steps[0].mae_um, "after": result.steps[-1].mae_um}
    record["nested_after"] = None if result.nested is None else result.nested.to_json()
    record["baseline"] = _test_dict(result.within_noise.get("baseline"))
    record["after"] = _test_dict(result.within_noise.get("after"))
    if result.candidates:
        top = result.candidates[0]
        record["top"] = {
            "effect": top.effect,
            "settings": {k: (float(v) if isinstance(v, (int, float, np.number)) else v) for k, v in top.settings.items()},
            "significant": bool(top.significant),
            "explained_fraction": round(float(top.explained_fraction), 4),
            "noise_fraction": round(float(top.noise_fraction), 4),
            "error_reduction": round(float(top.error_reduction), 4),
        }
    return record


# -- figures ---------------------------------------------------------------------------------------
def clopper_pearson(k: int, n: int) -> list[float]:
    """The exact 95 % interval of a binomial share k / n."""
    if n == 0:
        return [0.0, 1.0]
    ci = binomtest(k, n).proportion_ci(0.95, method="exact")
    return [round(float(ci.low), 4), round(float(ci.high), 4)]


def share(k: int, n: int) -> float:
    return round(k / n, 4) if n else None  # type: ignore[return-value]


def over_floor(step: Step) -> float:
    """A step's check-ring MAE over its noise floor, against the repetition mean, as records keep it."""
    return round(step.mae_um["mean"] / step.noise_floor_um["mean"], 3)


def rate(k: int, n: int) -> dict[str, Any]:
    """A share as results.json holds it: {"count", "of", "share", "ci95"} (Clopper-Pearson)."""
    return {"count": k, "of": n, "share": share(k, n), "ci95": clopper_pearson(k, n)}


def finds(record: dict[str, Any], effect: str = "b_axis_cyclic", cycles: float = POWER_CYCLES) -> dict[str, Any] | None:
    """The found entry of this effect at these cycles per revolution, if the diagnosis found it."""
    if record["verdict"] not in ("missing", "partial"):
        return None
    for c in record.get("found", []):
        if c["effect"] == effect and abs(float(c["settings"].get("cycles_per_rev", -1)) - cycles) < 1e-6:
            return c
    return None


def verdict_figures(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Counts of each verdict, its share with the 95 % interval, and the stability (most common share)."""
    n = len(records)
    counts = Counter(r["verdict"] for r in records)
    names = list(VERDICTS) + sorted(set(counts) - set(VERDICTS))  # "error" if any
    most, most_count = counts.most_common(1)[0] if counts else ("", 0)
    return {
        "n": n,
        "verdicts": {v: counts.get(v, 0) for v in names},
        "per_verdict": {v: {"rate": share(counts.get(v, 0), n), "ci95": clopper_pearson(counts.get(v, 0), n)} for v in names},
        "most_common": most,
        "stability": share(most_count, n),
    }


def brief(record: dict[str, Any]) -> dict[str, Any]:
    """A record without its group: what a seed said, for the JSON's lists of exceptions."""
    return {k: v for k, v in record.items() if k not in ("group", "key")}


def ring_counts(records: list[dict[str, Any]]) -> dict[str, Any]:
    """The baseline's failing rings over the seeds, against the count at which the campaign fails."""
    tests = [r["baseline"] for r in records if r.get("baseline")]
    if not tests:
        return {"median": None, "max": None, "critical": []}
    failing = [t["failing_rings"] for t in tests]
    return {
        "median": float(np.median(failing)),
        "max": int(max(failing)),
        "critical_statistic": [round(min(t["critical"] for t in tests), 3), round(max(t["critical"] for t in tests), 3)],
    }


def null_figures(records: list[dict[str, Any]], seeds: list[int], description: str) -> dict[str, Any]:
    """False-alarm rate and stability on campaigns with nothing hidden (part 1 and 2)."""
    records = sorted(records, key=lambda r: r["seed"])
    figures = verdict_figures(records)
    alarms = [r for r in records if r["verdict"] != "none"]
    k, n = len(alarms), len(records)
    rate = share(k, n)
    return {
        "design": description,
        "seeds": seeds,
        **figures,
        "false_alarm_rate": rate,
        "false_alarm_ci95": clopper_pearson(k, n),
        "holds": {"false_alarm": bool(rate <= TARGET_FALSE_ALARM), "stability": bool(figures["stability"] >= TARGET_STABILITY)},
        "baseline_failing_rings": ring_counts(records),
        "alarms": [brief(r) for r in alarms],
        "median_seconds": round(float(np.median([r["seconds"] for r in records])), 2),
    }


def effect_figures(records: list[dict[str, Any]], seeds: list[int], truth: dict[str, float]) -> dict[str, Any]:
    """Part 3: how often head_3's hidden effect is found, and the coverage of its uncertainty."""
    records = sorted(records, key=lambda r: r["seed"])
    figures = verdict_figures(records)
    n = len(records)
    hits = [(r, c) for r in records if (c := finds(r, "b_axis_cyclic", truth["cycles_per_rev"])) is not None]

    def coverage(name: str, period: float | None = None) -> dict[str, Any]:
        fits, us, covered = [], [], 0
        for _, c in hits:
            value, u = c["params"].get(name), c["params_u"].get(name)
            if value is None or u is None:
                continue
            diff = value - truth[name]
            if period is not None:
                diff = (diff + period / 2) % period - period / 2
            fits.append(value)
            us.append(u)
            covered += abs(diff) <= u
        m = len(fits)
        return {
            "true": truth[name],
            "covered": covered,
            "of": m,
            "coverage": share(covered, m),
            "coverage_ci95": clopper_pearson(covered, m),
            "mean_fit": round(float(np.mean(fits)), 4) if fits else None,
            "sd_fit": round(float(np.std(fits, ddof=1)), 4) if m > 1 else None,
            "mean_u_k2": round(float(np.mean(us)), 4) if us else None,
        }

    return {
        "seeds": seeds,
        "true_effect": {"id": "b_axis_cyclic", **truth},
        **figures,
        "share_missing": share(figures["verdicts"].get("missing", 0), n),
        "share_found_head_3": share(len(hits), n),
        "amplitude_arcsec": coverage("amplitude_arcsec"),
        "phase_deg": coverage("phase_deg", 360.0 / truth["cycles_per_rev"]),
        "coverage_note": "share of the seeds that found b_axis_cyclic at its true cycles/rev whose true value lies within fit +- params_u (k = 2; expected ~95 %)",
        "others": [brief(r) for r in records if r["verdict"] != "missing" or finds(r, "b_axis_cyclic", truth["cycles_per_rev"]) is None],
        "after_errors": after_figures(records),
        "median_seconds": round(float(np.median([r["seconds"] for r in records])), 2),
    }


def after_figures(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Nested vs check-ring "after" errors side by side (MAE against the repetition mean, um): the
    mean over the seeds where effects were found, and the share of the error removed on each."""
    pairs = [r for r in records if r.get("nested_after")]

    def mean_of(values: list[float]) -> float | None:
        return round(float(np.mean(values)), 4) if values else None

    check_before = [r["check_rings_um"]["before"]["mean"] for r in pairs]
    check_after = [r["check_rings_um"]["after"]["mean"] for r in pairs]
    nested_before = [r["nested_after"]["before_um"]["mean"] for r in pairs]
    nested_after = [r["nested_after"]["after_um"]["mean"] for r in pairs]
    return {
        "reference": "MAE against the mean of the repetitions (um), mean over the seeds",
        "seeds_with_effects_found": len(pairs),
        "check_rings": {
            "before": mean_of(check_before),
            "after": mean_of(check_after),
            "share_removed": mean_of([1 - a / b for a, b in zip(check_after, check_before)]),
        },
        "nested": {
            "before": mean_of(nested_before),
            "after": mean_of(nested_after),
            "share_removed": mean_of([1 - a / b for a, b in zip(nested_after, nested_before)]),
            "folds": pairs[0]["nested_after"]["folds"] if pairs else None,
        },
        "noise_floor_mean": mean_of([r["nested_after"]["noise_floor_um"]["mean"] for r in pairs]),
    }


def label(found: dict[str, Any]) -> str:
    cycles = found["settings"].get("cycles_per_rev")
    return found["effect"] + ("" if cycles is None else f"@{cycles:g}/rev")


def power_point(amplitude: float, records: list[dict[str, Any]]) -> dict[str, Any]:
    records = sorted(records, key=lambda r: r["seed"])
    n = len(records)
    detected = [r for r in records if finds(r) is not None]
    failure = [r for r in records if r["verdict"] != "none"]
    amplitudes = [finds(r)["params"].get("amplitude_arcsec") for r in detected]
    return {
        "amplitude_arcsec": amplitude,
        "n": n,
        "verdicts": verdict_figures(records)["verdicts"],
        "power": share(len(detected), n),
        "power_ci95": clopper_pearson(len(detected), n),
        "failure_detected": share(len(failure), n),
        "failure_detected_ci95": clopper_pearson(len(failure), n),
        "mean_fitted_amplitude_arcsec": round(float(np.mean(amplitudes)), 4) if amplitudes else None,
        "after_errors": after_figures(records),
        # Effects found besides the hidden one (e.g. a wrong period), with how many seeds found each.
        "other_findings": dict(Counter(label(c) for r in records for c in r.get("found", []) if c is not finds(r))),
    }


def commit() -> str:
    """The checkout's short commit, with "+changes" when the package or the benchmarks differ from it:
    which checkout the figures were measured on."""
    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True, check=True).stdout.strip()
        changed = subprocess.run(
            ["git", "status", "--porcelain", "--", "ph_explorer", "benchmarks/*.py"], cwd=root, capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    return head + ("+changes" if changed else "")


def code_version() -> str:
    """A short sha256 of the package's Python sources: which code the figures were measured on."""
    digest = hashlib.sha256()
    root = Path(ph_explorer.__file__).resolve().parent
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()[:12]


# -- the run ---------------------------------------------------------------------------------------
def jobs(quick: bool) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """Every diagnosis to run, and the plan (seeds per part) the figures are made from."""
    fa_seeds = list(FALSE_ALARM_SEEDS[: QUICK["false_alarm"]] if quick else FALSE_ALARM_SEEDS)
    design_seeds = list(DESIGN_SEEDS[: QUICK["designs"]] if quick else DESIGN_SEEDS)
    effect_seeds = list(EFFECT_SEEDS[: QUICK["effect"]] if quick else EFFECT_SEEDS)
    power_seeds = list(POWER_SEEDS[: QUICK["power_seeds"]] if quick else POWER_SEEDS)
    amplitudes = list(QUICK["power_amplitudes"] if quick else POWER_AMPLITUDES)
    out: list[dict[str, Any]] = []
    paper = scenario_data("paper")
    out += [{"group": "false_alarm", "key": "paper", "data": paper, "seed": s} for s in fa_seeds]
    designs = {}
    for design in DESIGNS:
        data, drop = design_data(design)
        designs[design] = data
        out += [{"group": "designs", "key": design, "data": data, "drop_times": drop, "seed": s} for s in design_seeds]
    b22 = scenario_data("head_3")
    out += [{"group": "effect", "key": "head_3", "data": b22, "seed": s} for s in effect_seeds]
    for a in amplitudes:
        out += [{"group": "power", "key": a, "data": power_data(a), "seed": s} for s in power_seeds]
    plan = {
        "false_alarm": fa_seeds,
        "designs": design_seeds,
        "effect": effect_seeds,
        "power": power_seeds,
        "amplitudes": amplitudes,
        "design_data": designs,
        "b22": b22,
    }
    return out, plan


def run(client: Client, quick: bool = False, log: Callable[[str], None] = print) -> dict[str, Any]:
    """All five parts, their diagnoses as tasks on the client's workers; the results["diagnosis_calibration"] object."""
    started = time.perf_counter()
    code = code_version()
    todo, plan = jobs(quick)
    total = len(todo)
    workers = len(client.scheduler_info()["workers"])
    log(f"  {total} diagnoses on {workers} workers")
    remaining = Counter((j["group"], j["key"]) for j in todo)
    records: dict[tuple[str, Any], list[dict[str, Any]]] = {k: [] for k in remaining}
    done = 0

    def finished(group: str, key: Any) -> None:
        rs = records[(group, key)]
        counts = dict(Counter(r["verdict"] for r in rs))
        found = dict(Counter(label(c) for r in rs for c in r.get("found", [])))
        if group == "power":
            log(
                f"  power {key:g} arcsec: {len(rs)} seeds, verdicts {counts}, found b_axis 22/rev {sum(finds(r) is not None for r in rs)}/{len(rs)}"
            )
        elif group == "effect":
            log(f"  {key}: {len(rs)} seeds, verdicts {counts}, found b_axis 22/rev {sum(finds(r) is not None for r in rs)}/{len(rs)}")
        else:
            alarms = sum(r["verdict"] != "none" for r in rs)
            log(
                f"  {group} {key}: {len(rs)} seeds, verdicts {counts}, false alarms {alarms}/{len(rs)}"
                + (f", found {found}" if found else "")
            )

    def take(record: dict[str, Any]) -> None:
        nonlocal done
        key = (record["group"], record["key"])
        records[key].append(record)
        done += 1
        if "error" in record:
            log(f"  error in {key} seed {record['seed']}: {record['error']}")
        remaining[key] -= 1
        if remaining[key] == 0:
            finished(*key)
        if done % 25 == 0 and done < total:
            log(f"  {done}/{total} diagnoses ({time.perf_counter() - started:.0f} s)")

    run_tasks(client, diagnose_one, todo, on_result=take)

    null_test = {
        "ring_level": RING_LEVEL,
        "campaign_false_alarm": FALSE_ALARM,
        "mean_tolerance": MEAN_TOLERANCE,
        "statistic": "sum over the rings but the worst of log(ring_level / p), worst ring's share in its neighbours undone",
        "diagnose_seed": DIAGNOSE_SEED,
    }
    out: dict[str, Any] = {
        "mode": "quick" if quick else "full",
        "code_sha256": code,  # of ph_explorer/**/*.py when the run started
        "targets": {
            "false_alarm_rate_max": TARGET_FALSE_ALARM,
            "stability_min": TARGET_STABILITY,
            "seconds_per_diagnosis_max": TARGET_SECONDS,
        },
        "within_noise_test": null_test,
        "false_alarm": {
            "scenario": "paper",
            **null_figures(records[("false_alarm", "paper")], plan["false_alarm"], "the paper campaign as shipped"),
        },
        "designs": {
            design: {"scenario": "paper", **null_figures(records[("designs", design)], plan["designs"], text)}
            for design, text in DESIGNS.items()
        },
    }
    out["designs"]["b_step_30"]["check_orientations"] = plan["design_data"]["b_step_30"]["check_orientations"]
    out["stability_with_effect"] = {
        "scenario": "head_3",
        **effect_figures(records[("effect", "head_3")], plan["effect"], hidden_b_axis(plan["b22"])),
    }
    out["power"] = {
        "scenario": f"paper + hidden b_axis_cyclic {POWER_CYCLES}/rev, phase 0",
        "detected": f"verdict missing or partial with b_axis_cyclic at {POWER_CYCLES}/rev among the effects found",
        "seeds": plan["power"],
        "curve": [power_point(a, records[("power", a)]) for a in plan["amplitudes"]],
        # Amplitude 0 is the paper campaign of part 1.
        "at_zero": {
            "power": share(sum(finds(r) is not None for r in records[("false_alarm", "paper")]), len(plan["false_alarm"])),
            "failure_detected": out["false_alarm"]["false_alarm_rate"],
        },
    }
    seconds = [r["seconds"] for r in records[("false_alarm", "paper")]]
    out["seconds_per_diagnosis"] = {
        "scenario": "paper",
        "median": round(float(np.median(seconds)), 2),
        "min": round(float(np.min(seconds)), 2),
        "max": round(float(np.max(seconds)), 2),
        "n": len(seconds),
        "target_s": TARGET_SECONDS,
        "holds": bool(np.median(seconds) < TARGET_SECONDS),
        "note": f"diagnose(campaign) alone (simulation excluded), {workers} workers (a diagnosis at a time each, one BLAS thread), "
        f"{os.cpu_count()} cores here",
    }
    with_effect = [r["seconds"] for r in records[("effect", "head_3")]]
    out["seconds_per_diagnosis"]["head_3"] = {
        "median": round(float(np.median(with_effect)), 2),
        "max": round(float(np.max(with_effect)), 2),
        "n": len(with_effect),
        "holds": bool(np.max(with_effect) < TARGET_SECONDS),
        "note": "an effect found: the nested cross-validation of the choice runs too (five more searches)",
    }
    out["after_errors"] = {"scenario": "head_3", **out["stability_with_effect"]["after_errors"]}
    every = [r for rs in records.values() for r in rs]
    out["errors"] = [r for r in every if r["verdict"] == "error"]
    out["holds"] = {
        "false_alarm": out["false_alarm"]["holds"]["false_alarm"],
        "stability": out["false_alarm"]["holds"]["stability"],
        "designs_false_alarm": {d: f["holds"]["false_alarm"] for d, f in out["designs"].items()},
        "seconds_per_diagnosis": out["seconds_per_diagnosis"]["holds"],
    }
    out["diagnoses"] = total
    out["workers"] = workers
    out["seconds"] = round(time.perf_counter() - started, 1)
    log(
        f"  calibration: {total} diagnoses in {out['seconds']} s; false alarms {out['false_alarm']['verdicts']}, "
        f"rate {out['false_alarm']['false_alarm_rate']} {out['false_alarm']['false_alarm_ci95']}"
    )
    return out
