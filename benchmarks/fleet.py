"""Many campaigns at once (issue 33): a fleet of random heads diagnosed on one worker, then on two,
on this machine; and from those figures, how the population calibration would scale.

CAMPAIGNS healthy random heads of the population (their designs drawn from their seeds), written
as CSV files, are diagnosed by diagnosis.fleet.run_fleet as `ph-explorer diagnose --data` does,
on a LocalCluster of 1 worker and then of 2 (each one thread; start-up included in the wall
seconds). Recorded: each run's wall seconds and their ratio (target <= 0.6), the rows equal
between the runs, each diagnosis's seconds on its worker, a worker's peak memory, the bytes a
task sends and returns, and the population calibration's expected wall time on 8, 32 and 128
cores from those figures (its diagnoses x the mean seconds of one / the cores, every core a worker).
"""

from __future__ import annotations

import json
import pickle
import statistics
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

from benchmarks.peak import resident_mib
from benchmarks.population import CALIBRATION_HEADS, COUNTS, FIRST_SEED, U_CALIBRATION_HEADS
from ph_explorer.diagnosis.fleet import fleet_row
from ph_explorer.io import write_campaign
from ph_explorer.task_runner import dask_client, one_thread_task, run_tasks
from ph_explorer.twin.random_heads import random_campaign

CAMPAIGNS, QUICK_CAMPAIGNS = 20, 2  # quick: one campaign per worker of the two-worker run
TARGET_RATIO = 0.6
CORES = (8, 32, 128)


def on_cluster(paths: list[Path], workers: int) -> tuple[float, list[dict[str, Any]], float]:
    """(wall seconds, rows, the workers' largest peak MiB) of the fleet on a LocalCluster of `workers`
    (run_fleet's tasks on run_fleet's cluster)."""
    started = time.perf_counter()
    with dask_client(workers=workers) as client:
        rows = run_tasks(client, fleet_row, [str(p) for p in paths], options={}).results
        peak = max(client.run(resident_mib, "VmHWM").values())
    return time.perf_counter() - started, rows, peak


def run(quick: bool = False, log: Callable[[str], None] = print) -> dict[str, Any]:
    count = QUICK_CAMPAIGNS if quick else CAMPAIGNS
    with tempfile.TemporaryDirectory() as folder:
        paths = []
        for i in range(count):
            path = Path(folder) / f"head_{FIRST_SEED['healthy'] + i}.csv"
            write_campaign(random_campaign(FIRST_SEED["healthy"] + i), path)
            paths.append(path)
        runs = {}
        for workers in (1, 2):
            runs[workers] = on_cluster(paths, workers)
            log(f"  {count} campaigns on {workers} worker(s): {runs[workers][0]:.1f} s")
        row = runs[1][1][0]
        sent = len(pickle.dumps((partial(one_thread_task, fleet_row, {"options": {}}), str(paths[0]))))  # run_tasks's task
    one, two = runs[1][0], runs[2][0]
    seconds = [r["seconds"] for r in runs[1][1]]
    same = [{k: v for k, v in a.items() if k != "seconds"} for a in runs[1][1]] == [
        {k: v for k, v in b.items() if k != "seconds"} for b in runs[2][1]
    ]
    population = sum(COUNTS.values()) + CALIBRATION_HEADS + U_CALIBRATION_HEADS
    mean = statistics.fmean(seconds)
    return {
        "mode": "quick" if quick else "full",
        "campaigns": count,
        "heads": f"healthy random heads {FIRST_SEED['healthy']}.. (the population's), designs drawn from their seeds",
        "seconds": {"one_worker": round(one, 2), "two_workers": round(two, 2)},
        "ratio": round(two / one, 3),
        "target_ratio": TARGET_RATIO,
        "holds": bool(two / one <= TARGET_RATIO),
        "rows_equal": same,
        "seconds_per_diagnosis": {"median": round(statistics.median(seconds), 2), "mean": round(mean, 2), "max": round(max(seconds), 2)},
        "worker_peak_mib": round(max(runs[1][2], runs[2][2]), 1),
        "bytes_per_task": {"sent": sent, "returned": len(json.dumps(row).encode())},
        "population_calibration": {
            "diagnoses": population,
            "expected_wall_s": {str(n): round(population * mean / n, 1) for n in CORES},
            "note": "its diagnoses x the mean seconds of one here / the cores (one single-threaded worker each); "
            "the population's own designs, like these heads'",
        },
    }
