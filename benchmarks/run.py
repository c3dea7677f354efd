"""`python -m benchmarks [--quick] [--out DIR]`: every benchmark of issues 7, 13, 14 and 17, one JSON and PNG plots.

Writes DIR/results.json (default: this folder) and DIR/data_efficiency.png, DIR/speed.png,
DIR/calibration.png. The full run takes several minutes on 2 cores (the scale test alone runs
60 s, the diagnosis calibration a few minutes); --quick is a smoke-test mode (two subsets, a
short network, 2 browsers for 2 s, a few diagnoses) that keeps every key.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import time
from pathlib import Path
from typing import Any

import torch

from benchmarks import calibration, data_efficiency, hidden_effects, plots, scale, speed, uncertainty_coverage
from ph_explorer.app.server import build_server
from ph_explorer.models.network import FourierNetwork, NetworkConfig
from ph_explorer.models.trilinear import TrilinearModel

HERE = Path(__file__).resolve().parent
SCENARIOS = ("paper", "b_axis_22")


def log(text: str) -> None:
    print(text, flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smoke-test mode: small and fast, same keys")
    parser.add_argument("--out", type=Path, default=HERE, help="folder for results.json and the PNGs")
    parser.add_argument("--replot", action="store_true", help="only redraw the PNGs from OUT/results.json")
    parser.add_argument(
        "--only-uncertainty", action="store_true", help="run only the uncertainty_coverage section and update OUT/results.json with it"
    )
    args = parser.parse_args(argv)
    if args.only_uncertainty:
        path = args.out / "results.json"
        results = json.loads(path.read_text()) if path.is_file() else {}
        log("uncertainty coverage")
        results["uncertainty_coverage"] = {"date": datetime.date.today().isoformat(), **uncertainty_coverage.run(quick=args.quick, log=log)}
        args.out.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(results, indent=2) + "\n")
        return 0
    if args.replot:
        results = json.loads((args.out / "results.json").read_text())
        plots.data_efficiency_plot(results, args.out / "data_efficiency.png")
        plots.speed_plot(results, args.out / "speed.png")
        if "diagnosis_calibration" in results:
            plots.calibration_plot(results, args.out / "calibration.png")
        return 0
    quick: bool = args.quick
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()

    network_config = NetworkConfig(max_epochs=30, early_stopping_patience=10) if quick else NetworkConfig()
    columns = (18, 3) if quick else data_efficiency.B_COLUMNS
    results: dict[str, Any] = {
        "date": datetime.date.today().isoformat(),
        "mode": "quick" if quick else "full",
        "machine": {"cpu_count": os.cpu_count(), "python": platform.python_version(), "torch_threads": 1, "platform": platform.platform()},
    }

    # 1. data efficiency
    log("data efficiency")
    results["data_efficiency"], results["data_efficiency_details"] = {}, {}
    paper_campaign = None
    for name in SCENARIOS:
        run = data_efficiency.run_scenario(name, network_config, columns, log=log)
        results["data_efficiency"][name] = run["curves"]
        details = run["details"]
        details["target"] = data_efficiency.target(run["curves"])
        results["data_efficiency_details"][name] = details
        if name == "paper":
            paper_campaign = run["campaign"]
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

    # 2. speed
    log("speed")
    assert paper_campaign is not None
    check = paper_campaign.holdout_mask()
    s: dict[str, Any] = {"cpu_count": os.cpu_count(), "torch_threads": torch.get_num_threads()}
    s["simulate"] = speed.simulate_speed(2 if quick else 5)
    start = time.perf_counter()
    network = FourierNetwork(network_config).fit(paper_campaign, ~check)
    s["network_training"] = {
        "seconds": round(time.perf_counter() - start, 2),
        "epochs": network.log.epochs,
        "best_epoch": network.log.best_epoch,
        "training_orientations": int((~check).sum()),
        "config": "short (quick mode)" if quick else "the paper's (early stopping, patience 200)",
    }
    trilinear = TrilinearModel().fit(paper_campaign, ~check)
    s["physics_refit"], hybrid = speed.refit_speed(paper_campaign)
    # Prediction and Monte Carlo of the hybrid use the refit's (lobing + b_axis_cyclic).
    models = {"network": network, "trilinear": trilinear, "hybrid": hybrid}
    s["hybrid_used_for_prediction"] = "lobing + b_axis_cyclic (2/rev), data part trilinear"
    s["diagnosis"] = speed.diagnosis_speed(paper_campaign)
    s["predict_one_orientation_us"] = speed.prediction_speed(models, 30 if quick else 200)
    s["monte_carlo_touches_per_s"] = speed.monte_carlo_speed(models, paper_campaign.orientations, 10, 1 if quick else 3)
    s["serve_startup"] = speed.serve_startup()
    log(f"  serve start-up {s['serve_startup']}")

    # Server time per slider update, one browser; then 3. scale, N browsers.
    app = build_server(port=0)
    try:
        one = scale.drive(app, 1, 20.0, 2.0 if quick else 15.0)
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
        log("scale")
        n_browsers, seconds = (2, 2.0) if quick else (30, 60.0)
        load = scale.drive(app, n_browsers, 20.0, seconds)
        load["clients"] = "websocket clients on 127.0.0.1 speaking viser's protocol, in a separate process (benchmarks/browsers.py)"
        load["p95_target_ms"] = 20
        results["scale"] = load
        log(f"  {json.dumps(load)}")
    finally:
        app.stop()

    # 4. diagnosis calibration: false alarms, stability, coverage, power (issue 13)
    log("diagnosis calibration")
    results["diagnosis_calibration"] = calibration.run(quick=quick, log=log)
    # 5. each rotary-axis error motion and the ball form hidden in the paper campaign (issue 14)
    log("hidden effects")
    results["hidden_effects"] = hidden_effects.run(quick=quick, log=log)
    # 6. the 95 % bands with every component against held-out rings, and the task's E_n (issue 17)
    log("uncertainty coverage")
    results["uncertainty_coverage"] = {"date": results["date"], **uncertainty_coverage.run(quick=quick, log=log)}

    results["total_seconds"] = round(time.perf_counter() - started, 1)
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    plots.data_efficiency_plot(results, out / "data_efficiency.png")
    plots.speed_plot(results, out / "speed.png")
    plots.calibration_plot(results, out / "calibration.png")
    log(f"wrote {out / 'results.json'} and the PNGs in {results['total_seconds']} s")
    return 0
