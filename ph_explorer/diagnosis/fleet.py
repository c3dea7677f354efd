"""Many campaigns diagnosed at once on Dask's distributed scheduler (docs/fleet.md).

Each task gets a file's path and the command's options, reads the file on its worker and diagnoses
it as `ph-explorer diagnose` does (diagnosis.campaign_file); it sends back plain JSON-ready data,
never a pickled model. Without a scheduler address the fleet runs on a LocalCluster of one
single-threaded worker process per core. Dask is imported here only, so that the single-campaign
commands never load it.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ph_explorer.blas import one_blas_thread
from ph_explorer.campaign import orientation_label
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.errors import InputError
from ph_explorer.io import file_sha256, read_campaign


def summary(result: Diagnosis) -> dict[str, Any]:
    """A diagnosis in a fleet table's words: verdict, found effects with U (k = 2), suggested ones, failing rings."""
    return {
        "verdict": result.verdict,
        "found": [{"effect": c.effect, "settings": c.settings, "params": c.params, "params_u": c.params_u} for c in result.found],
        "suggested": [{"effect": c.effect, "settings": c.settings} for c in result.suggested],
        "failing_rings": [orientation_label(r.a_deg, r.b_deg) for r in result.failing_rings()],
    }


@one_blas_thread
def fleet_row(path: str, options: dict[str, Any]) -> dict[str, Any]:
    """One campaign's row, made on a worker: its summary and its whole diagnosis (as the single
    command's --json prints it), or the one line that says why it could not be read."""
    from ph_explorer.diagnosis.campaign_file import catalog_of, diagnose_campaign, parse_add

    started = time.perf_counter()
    row: dict[str, Any] = {"campaign": path}
    try:
        row["sha256"] = file_sha256(Path(path))
        catalog = catalog_of(options.get("effects"))
        ids = parse_add(options.get("add"), catalog)
        campaign = read_campaign(Path(path), options.get("geometry") or {})
        result = diagnose_campaign(campaign, catalog, ids, options.get("model"), options.get("data_part") or "trilinear")
    except (InputError, OSError) as error:
        row["error"] = error.line() if isinstance(error, InputError) else f"{path}: {' '.join(str(error).split())}"
    except Exception as error:  # noqa: BLE001 - a fleet answers for every file: the error is the file's row
        row["error"] = f"{path}: {type(error).__name__}: {' '.join(str(error).split())}"
    else:
        row.update(summary(result))
        row["diagnosis"] = result.as_dict()
    row["seconds"] = round(time.perf_counter() - started, 2)
    return row


def run_fleet(
    paths: Sequence[Path],
    options: dict[str, Any],
    scheduler: str | None = None,
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """{"campaigns": every campaign's row (fleet_row) in the order of `paths`, "workers": how many
    there were at the start, "workers_lost": how many of them were gone at the end (Dask ran what
    they held again on the others)}; on_row(row) as each campaign ends.

    scheduler: a Dask scheduler's address (tcp://HOST:PORT); None starts a LocalCluster of the
    machine's cores, one thread per worker (the diagnosis holds its BLAS to one thread)."""
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=os.cpu_count() or 1, threads_per_worker=1, processes=True, dashboard_address=None)
    try:
        with Client(cluster if cluster is not None else scheduler) as client:
            client.wait_for_workers(1)
            workers = set(client.scheduler_info()["workers"])
            futures = client.map(fleet_row, [str(p) for p in paths], options=options, pure=False)
            index = {future.key: i for i, future in enumerate(futures)}
            rows: list[dict[str, Any]] = [{} for _ in paths]
            for future in as_completed(futures):
                row = future.result()
                rows[index[future.key]] = row
                if on_row is not None:
                    on_row(row)
            lost = workers - set(client.scheduler_info()["workers"])
    finally:
        if cluster is not None:
            cluster.close()
    return {"campaigns": rows, "workers": len(workers), "workers_lost": len(lost)}
