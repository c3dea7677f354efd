"""`python -m benchmarks [--quick] [--out DIR] [--only SECTIONS] [--scheduler ADDRESS] [--stale]`: every benchmark, one JSON and PNG plots.

Writes DIR/results.json (default: this folder) and DIR/data_efficiency.png, DIR/speed.png,
DIR/calibration.png. The full run takes about 45 minutes on 2 cores (the diagnosis
calibration about 22 of them); --quick is a smoke-test mode (two subsets, a
short network, 2 browsers for 1 s, a few diagnoses) that keeps every key. --only runs some
sections and updates them in the last run's results.json, each stamped under "updated" with its
date, the code it was measured on and the machine. The many diagnoses of the calibration, the population, the
hidden effects and the coverage are tasks of ph_explorer.task_runner: on a LocalCluster of this
machine's cores (quick: one worker thread in this process), or on the cluster of --scheduler.
"""

from __future__ import annotations

import argparse
import compileall
import contextlib
import datetime
import json
import os
import platform
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import ph_explorer
from benchmarks import calibration, large_campaign
from ph_explorer.campaign import Campaign
from ph_explorer.task_runner import dask_client
from ph_explorer.twin import load_scenario, simulate

if TYPE_CHECKING:
    from ph_explorer.models.network import NetworkConfig

# Each section's module (and what it imports: torch, viser, scikit-learn) is imported when the
# section runs: a run of a few sections (--only) starts in a second instead of five.

HERE = Path(__file__).resolve().parent
SCENARIOS = ("paper", "head_3")


def log(text: str) -> None:
    print(text, flush=True)


@contextlib.contextmanager
def section(title: str, key: str, results: dict[str, Any]) -> Iterator[None]:
    """One section of the run, logged with its wall seconds (results["section_seconds"][key])."""
    log(title)
    started = time.perf_counter()
    yield
    seconds = round(time.perf_counter() - started, 1)
    results.setdefault("section_seconds", {})[key] = seconds
    log(f"  ({title}: {seconds} s)")


SECTIONS = (
    "data_efficiency",
    "speed",
    "scale",
    "diagnosis_calibration",
    "population",
    "population_unknown",
    "adaptive_campaign",
    "verdict_speed",
    "deciding",
    "hidden_effects",
    "uncertainty_coverage",
    "large_campaign",
    "fleet",
    "peers",
)


def paper_campaign() -> Campaign:
    scenario = load_scenario("paper")
    return simulate(scenario, scenario.seed)


def network_config(quick: bool) -> NetworkConfig:
    """The network's training: the paper's, or (quick) a few epochs."""
    from ph_explorer.models.network import NetworkConfig

    return NetworkConfig(max_epochs=large_campaign.QUICK_EPOCHS, early_stopping_patience=10) if quick else NetworkConfig()


def run_data_efficiency(quick: bool, results: dict[str, Any]) -> None:
    from benchmarks import data_efficiency

    columns = (18, 3) if quick else data_efficiency.B_COLUMNS
    budgets = (12,) if quick else data_efficiency.DESIGN_BUDGETS
    results["data_efficiency"], results["data_efficiency_details"] = {}, {}
    for name in SCENARIOS[:1] if quick else SCENARIOS:  # quick: the paper's, every path of the section
        run = data_efficiency.run_scenario(name, network_config(quick), columns, log=log, budgets=budgets)
        results["data_efficiency"][name] = run["curves"]
        details = run["details"]
        details["target"] = data_efficiency.target(run["curves"])
        details["design_target"] = data_efficiency.design_target(run["curves"], details["design"])
        if name == "paper":  # the 12-ring goal's scenario: its other noise draws
            seeds = data_efficiency.NOISE_SEEDS[:1] if quick else data_efficiency.NOISE_SEEDS
            details["design_target"]["over_noise_seeds"] = data_efficiency.design_target_over_noise_seeds(name, seeds, log=log)
        results["data_efficiency_details"][name] = details
    holds = {name: d["target"]["holds"] for name, d in results["data_efficiency_details"].items()}
    results["target"] = {
        "holds": all(holds.values()),
        "per_scenario": holds,
        "detail": "; ".join(
            f"{name}: hybrid at <= {d['target']['max_orientations']:.0f} orientations best "
            f"{d['target']['best_at_or_below_limit']} vs full-data trilinear {d['target']['full_data_trilinear']} "
            f"(ratio {d['target']['ratio_best_to_full_trilinear']}, match = within x{d['target']['tolerance']})"
            for name, d in results["data_efficiency_details"].items()
        ),
    }


def run_speed(quick: bool, results: dict[str, Any], with_scale: bool) -> None:
    """Speed figures; the one-browser slider figure and (with_scale) N browsers share one server."""
    import torch

    from benchmarks import scale, speed
    from ph_explorer.app.server import ExplorerApp, build_server
    from ph_explorer.models.gaussian_process import GaussianProcessModel
    from ph_explorer.models.network import FourierNetwork
    from ph_explorer.models.trilinear import TrilinearModel

    campaign = paper_campaign()
    check = campaign.holdout_mask()
    s: dict[str, Any] = {"cpu_count": os.cpu_count(), "torch_threads": torch.get_num_threads()}
    s["simulate"] = speed.simulate_speed(2 if quick else 5)
    start = time.perf_counter()
    network = FourierNetwork(network_config(quick)).fit(campaign, ~check)
    s["network_training"] = {
        "seconds": round(time.perf_counter() - start, 2),
        "epochs": network.log.epochs,
        "best_epoch": network.log.best_epoch,
        "training_orientations": int((~check).sum()),
        "config": "short (quick mode)" if quick else "the paper's (early stopping, patience 200)",
    }
    trilinear = TrilinearModel().fit(campaign, ~check)
    s["physics_refit"], hybrid = speed.refit_speed(campaign)
    # Prediction and Monte Carlo of the hybrid use the refit's (lobing + b_axis_cyclic).
    models = {"network": network, "trilinear": trilinear, "hybrid": hybrid}
    s["hybrid_used_for_prediction"] = "lobing + b_axis_cyclic (2/rev), data part trilinear"
    s["diagnosis"] = speed.diagnosis_speed(1 if quick else 3)
    log(f"  diagnosis {s['diagnosis']}")
    s["predict_one_orientation_us"] = speed.prediction_speed(models, 30 if quick else 200)
    s["monte_carlo_touches_per_s"] = speed.monte_carlo_speed(models, campaign.orientations, 10, 1 if quick else 3)
    s["serve_startup"] = speed.serve_startup(1 if quick else 5)
    log(f"  serve start-up {s['serve_startup']}")

    # Server time per slider update, one browser; then 3. scale, N browsers.
    app = build_server(port=0)
    try:
        one = scale.drive(app, 1, 20.0, 1.0 if quick else 15.0)
        s["slider_update_ms"] = {
            **one["server_update_ms"],
            "target_p95_ms": 20,
            "latency_ms": one["latency_ms"],  # slider event -> end of its render (queueing included)
            "renders": one["renders"],
            "slider_updates_sent": one["slider_updates_sent"],
            "errors": one["errors"],
        }
        s["slider_update_ms"]["holds"] = one["server_update_ms"]["p95"] is not None and one["server_update_ms"]["p95"] < 20
        results["speed"] = s
        log(f"  slider update (1 browser) {s['slider_update_ms']}")
        if with_scale:
            log("scale")
            n_browsers, seconds = (2, 1.0) if quick else (30, 60.0)
            load = scale.drive(app, n_browsers, 20.0, seconds)
            load["clients"] = "websocket clients on 127.0.0.1 speaking viser's protocol, in a separate process (benchmarks/browsers.py)"
            # Issue 16: slider -> drawn p95 <= 50 ms and server time per render p95 <= 2 ms, no errors.
            load["p95_target_ms"] = LATENCY_TARGET_MS
            load["server_p95_target_ms"] = SERVER_TARGET_MS
            load["holds"] = bool(
                load["errors"] == 0
                and (load["latency_ms"]["p95"] or 1e9) <= LATENCY_TARGET_MS
                and (load["server_update_ms"]["p95"] or 1e9) <= SERVER_TARGET_MS
            )
            results["scale"] = load
            log(f"  {json.dumps(load)}")
            # The same browsers with the Gaussian process shown beside the models (issue 32), on a
            # server of its own right after the room above: its curves, too, read from a lattice.
            dataset = app.dataset
            gp = GaussianProcessModel().fit(dataset.campaign, dataset.train_mask)
            gp_app = ExplorerApp(dataset.with_model("gp", gp), port=0)
            try:
                shown = scale.drive(gp_app, n_browsers, 20.0, seconds)
            finally:
                gp_app.stop()
            load["with_gp"] = {
                "models": gp_app.dataset.model_names,
                **{k: shown[k] for k in ("lattice", "latency_ms", "server_update_ms", "renders_per_update", "errors")},
                "holds": bool(shown["errors"] == 0 and (shown["latency_ms"]["p95"] or 1e9) <= LATENCY_TARGET_MS),
            }
            log(f"  with the GP shown {json.dumps(load['with_gp'])}")
            # A bigger room at a gentler pace: 100 browsers at 5 Hz, no errors; its latency reported.
            n_room, room_seconds = (3, 1.0) if quick else (100, 30.0)
            room = scale.drive(app, n_room, 5.0, room_seconds)
            room["clients"] = load["clients"]
            results["scale_100"] = room
            log(f"  {json.dumps(room)}")
            # The previous design in the same run: the same app with its lattices dropped, so every
            # slider move predicts its models on demand (as before the lattice cache).
            app.dataset.drop_lattices()
            before = scale.drive(app, n_browsers, 20.0, seconds)
            load["previous_design"] = {
                "design": "on-demand prediction (no lattice cache), same app, same browsers and rate",
                **{k: before[k] for k in ("latency_ms", "server_update_ms", "renders_per_update", "errors", "server_cpu_ms_per_update")},
            }
            log(f"  previous design {json.dumps(load['previous_design'])}")
    finally:
        app.stop()


# The quick run's few diagnoses on one worker thread in this process: worker processes' start (their
# imports) would cost more than they save, and the test suite runs the quick run beside its other
# tests on the same cores.
QUICK_WORKERS = 1
TASK_SECTIONS = (
    "diagnosis_calibration",
    "population",
    "population_unknown",
    "adaptive_campaign",
    "hidden_effects",
    "uncertainty_coverage",
    "peers",
)
LATENCY_TARGET_MS = 50.0
SERVER_TARGET_MS = 2.0


def run_task_sections(
    client: Any, sections: list[str], quick: bool, results: dict[str, Any], stamp: dict[str, str], unknown: dict[str, Any] | None = None
) -> None:
    """The sections whose diagnoses are tasks on the client's workers; unknown: the unknown-shape
    population's families and heads a family (None: its defaults)."""
    if "diagnosis_calibration" in sections:
        # false alarms, stability, coverage, power (issue 13)
        with section("diagnosis calibration", "diagnosis_calibration", results):
            results["diagnosis_calibration"] = calibration.run(client, quick=quick, log=log)
    if "population" in sections:
        # the verdicts over a population of random heads (issue 28)
        from benchmarks import population

        with section("population", "population", results):
            results["population"] = population.run(client, quick=quick, log=log)
    if "population_unknown" in sections:
        # effects no catalog holds, in families (issue 55)
        from benchmarks import unknown_population

        with section("population: effects no catalog holds", "population_unknown", results):
            results["population_unknown"] = unknown_population.run(client, quick=quick, log=log, **(unknown or {}))
    if "adaptive_campaign" in sections:
        # measure until you know: the adaptive campaign against the full one, same heads (issue 58)
        from benchmarks import adaptive_campaign

        with section("adaptive campaign", "adaptive_campaign", results):
            results["adaptive_campaign"] = adaptive_campaign.run(client, quick=quick, log=log)
    if "hidden_effects" in sections:
        # each rotary-axis error motion and the ball form hidden in the paper campaign (issue 14)
        from benchmarks import hidden_effects

        with section("hidden effects", "hidden_effects", results):
            results["hidden_effects"] = hidden_effects.run(client, quick=quick, log=log)
    if "uncertainty_coverage" in sections:
        # the 95 % bands with every component against held-out rings, and the task's E_n (issue 17)
        from benchmarks import uncertainty_coverage

        with section("uncertainty coverage", "uncertainty_coverage", results):
            results["uncertainty_coverage"] = {"date": stamp["date"], **uncertainty_coverage.run(client, quick=quick, log=log)}
    if "peers" in sections:
        # scipy's RBF and scikit-learn's GP beside the project's models, same split (issue 32)
        from benchmarks import peers

        with section("peers", "peers", results):
            results["peers"] = peers.run(client, quick=quick, log=log)


def write_plots(results: dict[str, Any], out: Path) -> None:
    from benchmarks import plots

    if "data_efficiency" in results:
        plots.data_efficiency_plot(results, out / "data_efficiency.png")
    if "speed" in results:
        plots.speed_plot(results, out / "speed.png")
    if "diagnosis_calibration" in results:
        plots.calibration_plot(results, out / "calibration.png")
    if "peers" in results:
        plots.peers_plot(results, out / "peers.png")
    if "adaptive_campaign" in results:
        plots.adaptive_plot(out / "adaptive_records.json", out / "adaptive.png")


def torch_threads() -> int:
    import torch

    return torch.get_num_threads()


def machine() -> dict[str, Any]:
    """The machine a run measures on: times from two runs compare only on the same one."""
    return {
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "torch_threads": torch_threads(),
        "platform": platform.platform(),
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke-test mode: small and fast, same keys")
    parser.add_argument("--out", type=Path, default=HERE, help="folder for results.json and the PNGs")
    parser.add_argument("--replot", action="store_true", help="only redraw the PNGs from OUT/results.json")
    parser.add_argument("--stale", action="store_true", help="only say which sections of OUT/results.json describe this checkout's code")
    parser.add_argument(
        "--only",
        default="",
        help=f"run only these sections (comma-separated: {', '.join(SECTIONS)}) and update them in OUT/results.json",
    )
    parser.add_argument("--scheduler", default=None, help="run the sections' many diagnoses on this Dask scheduler (tcp://HOST:PORT)")
    parser.add_argument("--unknown-families", default=None, help="population_unknown: these families only (comma-separated)")
    parser.add_argument("--unknown-count", type=int, default=None, help="population_unknown: heads a family (> 0)")
    args = parser.parse_args(argv)
    # Population options checked before anything runs or is written: one line, exit 2.
    from benchmarks.unknown_population import checked_options
    from ph_explorer.errors import InputError

    try:
        families, count = checked_options(args.unknown_families, args.unknown_count)
    except InputError as error:
        print(error.line(), file=sys.stderr)
        return 2
    unknown = {"families": families, "count": count}
    out: Path = args.out
    if args.replot:
        write_plots(json.loads((out / "results.json").read_text()), out)
        return 0
    if args.stale:
        from benchmarks import freshness

        for state in freshness.states(json.loads((out / "results.json").read_text())):
            print(state.line())
        return 0
    only = [name.strip() for name in args.only.split(",") if name.strip()]
    not_sections = [name for name in only if name not in SECTIONS]
    if not_sections:
        parser.error(f"--only: unknown section {not_sections[0]!r} (sections: {', '.join(SECTIONS)})")
    sections = only or list(SECTIONS)
    if only and not (out / "results.json").is_file():
        parser.error(f"--only: {out / 'results.json'} does not exist (--only updates the sections of a previous run there)")
    quick: bool = args.quick
    out.mkdir(parents=True, exist_ok=True)
    # The commands the sections launch (`python -m ph_explorer ...`) start as the installed package
    # does, its bytecode compiled (pip compiles it at install): a checkout run with
    # PYTHONDONTWRITEBYTECODE would compile every module again at each launch, 0.15-0.2 s of a
    # diagnosis's 3 s from launch to its verdict, measured on this machine.
    compileall.compile_dir(Path(ph_explorer.__file__).parent, quiet=1)
    started = time.perf_counter()
    stamp = {"date": datetime.date.today().isoformat(), "mode": "quick" if quick else "full"}
    if only:
        # A partial run updates its sections in the results of the last run, each stamped.
        results: dict[str, Any] = json.loads((out / "results.json").read_text())
        for name in sections:
            results.setdefault("updated", {})[name] = {
                **stamp,
                "code_sha256": calibration.code_version(),
                "commit": calibration.commit(),
                "machine": machine(),  # a partial run's machine may not be the last full run's
            }
    else:
        results = {**stamp, "commit": calibration.commit(), "machine": machine()}

    if "data_efficiency" in sections:
        with section("data efficiency", "data_efficiency", results):
            run_data_efficiency(quick, results)
    if "speed" in sections or "scale" in sections:
        with section("speed", "speed_and_scale", results):
            run_speed(quick, results, with_scale="scale" in sections)
    with contextlib.ExitStack() as stack:
        client = None
        if set(sections) & set(TASK_SECTIONS):
            in_process = quick and args.scheduler is None
            client = stack.enter_context(dask_client(args.scheduler, QUICK_WORKERS if quick else None, in_process))
        run_task_sections(client, sections, quick, results, stamp, unknown)

    if "verdict_speed" in sections:
        # one diagnosis at a time with nothing else running: the command and the explorer's click (issue 28, item 5)
        with section("verdict speed", "verdict_speed", results):
            from benchmarks import population

            results["verdict_speed"] = population.verdict_speed(1 if quick else population.SPEED_REPEATS, quick)
    if "deciding" in sections:
        # the rings that decide, measured by the twin, merged, diagnosed again (issue 29)
        with section("deciding", "deciding", results):
            from benchmarks import deciding

            results["deciding"] = deciding.run(quick=quick, log=log)
    if "large_campaign" in sections:
        # every command at the paper's size and at 16x its touches (issue 16)
        with section("large campaign", "large_campaign", results), tempfile.TemporaryDirectory() as folder:
            results["large_campaign"] = large_campaign.run(Path(folder), quick=quick, log=log)

    if "fleet" in sections:
        # many campaigns on a LocalCluster of 1 and of 2 workers, and the scaling from it (issue 33)
        from benchmarks import fleet

        with section("fleet", "fleet", results):
            results["fleet"] = fleet.run(quick=quick, log=log)

    seconds = round(time.perf_counter() - started, 1)
    if only:
        for name in sections:
            results["updated"][name]["run_seconds"] = seconds  # the whole partial run
    else:
        results["total_seconds"] = seconds
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    write_plots(results, out)
    log(f"wrote {out / 'results.json'} and the PNGs in {seconds} s")
    return 0
