"""Many campaigns diagnosed at once on Dask's distributed scheduler (docs/fleet.md).

Each task gets a file's path and the command's options, reads the file on its worker and diagnoses
it as `ph-explorer diagnose` does (diagnosis.campaign_file); it sends back plain JSON-ready data,
never a pickled model. Without a scheduler address the fleet runs on a LocalCluster of one
single-threaded worker process per core (ph_explorer.task_runner, the runner the benchmarks use too).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.diagnosis.campaign_file import catalog_of, diagnose_campaign, parse_add
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.errors import InputError
from ph_explorer.io import file_sha256
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.folder import load_models
from ph_explorer.models.lattice_need import read_lattice_campaign
from ph_explorer.task_runner import dask_client, run_tasks

# A fleet's table, in the command's text and on its page: one line a campaign.
FLEET_COLUMNS = ("campaign", "sha256", "verdict", "found (+- U, k = 2); shapes", "suggested", "failing rings (baseline)", "s")


def summary(result: Diagnosis) -> dict[str, Any]:
    """A diagnosis in a fleet table's words: verdict, found effects with U (k = 2), the shapes claimed
    for what no catalog holds, suggested ones, failing rings."""
    return {
        "verdict": result.verdict,
        "found": [{"effect": c.effect, "settings": c.settings, "params": c.params, "params_u": c.params_u} for c in result.found],
        "shapes": [{"id": s.id, "variable": s.variable, "period_cycles_per_rev": s.period_cycles} for s in result.claimed_shapes],
        "suggested": [{"effect": c.effect, "settings": c.settings} for c in result.suggested],
        "failing_rings": [orientation_label(r.a_deg, r.b_deg) for r in result.failing_rings()],
    }


def fleet_row(path: str, options: dict[str, Any]) -> dict[str, Any]:
    """One campaign's row, made on a worker: its summary and its whole diagnosis (as the single
    command's --json prints it), or the one line that says why it could not be read."""
    started = time.perf_counter()
    row, _, _, _ = diagnosed_file(path, options)
    row["seconds"] = round(time.perf_counter() - started, 2)
    return row


def diagnosed_file(
    path: str, options: dict[str, Any]
) -> tuple[dict[str, Any], Campaign | None, Diagnosis | None, dict[str, DeviationModel] | None]:
    """A campaign file diagnosed with the command's options: its row (fleet_row's, without the
    seconds), the campaign, the diagnosis and the --model folder's models (loaded once, None
    without one); the row says the error, and the others are None, when it failed."""
    row: dict[str, Any] = {"campaign": path}
    try:
        row["sha256"] = file_sha256(Path(path))
        catalog = catalog_of(options.get("effects"))
        ids = parse_add(options.get("add"), catalog)
        campaign = read_lattice_campaign(path, options.get("geometry"))
        loaded = load_models(Path(options["model"])) if options.get("model") else None
        result = diagnose_campaign(campaign, catalog, ids, loaded, options.get("data_part") or "trilinear")
    except (InputError, OSError) as error:
        row["error"] = error.line() if isinstance(error, InputError) else f"{path}: {' '.join(str(error).split())}"
    except Exception as error:  # noqa: BLE001 - a fleet answers for every file: the error is the file's row
        row["error"] = f"{path}: {type(error).__name__}: {' '.join(str(error).split())}"
    else:
        row.update(summary(result))
        row["diagnosis"] = result.to_json()
        return row, campaign, result, loaded
    return row, None, None, None


def run_fleet(
    paths: Sequence[Path],
    options: dict[str, Any],
    scheduler: str | None = None,
    on_row: Callable[[dict[str, Any]], None] | None = None,
    row: Callable[[str, dict[str, Any]], dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """{"campaigns": every campaign's row in the order of `paths`, "workers": how many there were
    at the start, "workers_lost": how many of them were gone at the end (Dask ran what they held
    again on the others)}; on_row(row) as each campaign ends.

    scheduler: a Dask scheduler's address (tcp://HOST:PORT); None starts a LocalCluster of the
    machine's cores (task_runner.dask_client). row: what a task makes of a file (default fleet_row)."""
    with dask_client(scheduler) as client:
        run = run_tasks(client, row or fleet_row, [str(p) for p in paths], on_result=on_row, options=options)
    return {"campaigns": run.results, "workers": run.workers, "workers_lost": run.workers_lost}


def found_text(row: dict[str, Any]) -> str:
    """A row's found effects as one text: each with its period and its parameters +- U (k = 2); then
    each shape claimed, with its variable and the period its curve holds mostly."""
    found = [
        effect_text(f)
        + ": "
        + ", ".join(f"{k} {v:.3g} +- {f['params_u'][k]:.2g}" for k, v in f["params"].items() if k not in f["settings"])
        for f in row["found"]
    ]
    shapes = [
        f"{s['id']} of {s['variable']}" + (f", mostly {s['period_cycles_per_rev']:g}/rev" if s["period_cycles_per_rev"] is not None else "")
        for s in row.get("shapes", [])  # a row written before shapes were listed has none
    ]
    return "; ".join(found + shapes)


def suggested_text(row: dict[str, Any]) -> str:
    return ", ".join(effect_text(s) for s in row["suggested"])


def effect_text(entry: dict[str, Any]) -> str:
    period = entry["settings"].get("cycles_per_rev")
    return entry["effect"] + (f" {period:g}/rev" if period is not None else "")
