"""`ph-explorer diagnose --data 'heads/*.csv'`: a fleet of campaigns, each diagnosed as the single
command does, gathered into one table (or one JSON object); progress on stderr. Method: docs/fleet.md."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from ph_explorer.io import campaign_files


def fleet_command(specs: list[Path], scheduler: str | None = None, json_output: bool = False, **options: Any) -> int:
    """Diagnose every campaign the specs name on Dask (diagnosis.fleet), each with the single
    command's `options` (model, add, effects, geometry, data_part); exit 2 when any failed, after all."""
    from ph_explorer.diagnosis.campaign_file import catalog_of, check_data_part, parse_add
    from ph_explorer.diagnosis.fleet import run_fleet
    from ph_explorer.models.folder import check_model_folder

    paths = campaign_files(specs)
    # The options are checked here once, so that a bad one is one line before any worker starts.
    parse_add(options.get("add"), catalog_of(options.get("effects")))
    options["data_part"] = check_data_part(options.get("data_part") or "trilinear")
    if options.get("model") is not None:
        check_model_folder(options["model"])
    errors = Console(stderr=True)
    started, done, slowest = time.perf_counter(), 0, ("", 0.0)

    def progress(row: dict[str, Any]) -> None:
        nonlocal done, slowest
        done += 1
        if row["seconds"] >= slowest[1]:
            slowest = (Path(row["campaign"]).name, row["seconds"])
        errors.print(
            f"{done}/{len(paths)} diagnosed, {time.perf_counter() - started:.0f} s; slowest {slowest[0]} ({slowest[1]:.1f} s)",
            highlight=False,
        )

    run = run_fleet(paths, options, scheduler, on_row=progress)
    rows = run["campaigns"]
    failed = sum("error" in row for row in rows)
    seconds = round(time.perf_counter() - started, 2)
    lost = run["workers_lost"]
    said = f"{lost} of {run['workers']} workers lost during the fleet: Dask ran what they held again on the others" if lost else ""
    if said:
        errors.print(said, highlight=False)
    if json_output:
        print(json.dumps({**run, "failed": failed, "seconds": seconds}))
    else:
        last = f"{len(rows)} campaigns in {seconds:.1f} s, {failed} failed" + (f"; {said}" if said else "")
        Console(width=200).print(fleet_table(rows), last, highlight=False)
    return 2 if failed else 0


def fleet_table(rows: list[dict[str, Any]]) -> Table:
    """One line a campaign: its verdict, found effects with U (k = 2), suggested ones, failing rings, time."""
    table = Table("campaign", "sha256", "verdict", "found (+- U, k = 2)", "suggested", "failing rings (baseline)", "s")
    for row in rows:
        if "error" in row:
            table.add_row(row["campaign"], row.get("sha256", "")[:12], "error", row["error"], "", "", f"{row['seconds']:.1f}")
            continue
        found = "; ".join(
            row_effect(f)
            + ": "
            + ", ".join(f"{k} {v:.3g} +- {f['params_u'][k]:.2g}" for k, v in f["params"].items() if k not in f["settings"])
            for f in row["found"]
        )
        table.add_row(
            row["campaign"],
            row["sha256"][:12],
            row["verdict"],
            found,
            ", ".join(row_effect(s) for s in row["suggested"]),
            str(len(row["failing_rings"])),
            f"{row['seconds']:.1f}",
        )
    return table


def row_effect(entry: dict[str, Any]) -> str:
    period = entry["settings"].get("cycles_per_rev")
    return entry["effect"] + (f" {period:g}/rev" if period is not None else "")
