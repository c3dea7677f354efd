"""`ph-explorer diagnose --data 'heads/*.csv'`: a fleet of campaigns, each diagnosed as the single
command does, gathered into one table (or one JSON object); progress on stderr. Method: docs/fleet.md."""

from __future__ import annotations

import datetime
import json
import time
from functools import partial
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from ph_explorer.io import campaign_files, checked_output_file
from ph_explorer.io.writer import atomic_write


def fleet_command(
    specs: list[Path], scheduler: str | None = None, json_output: bool = False, report: Path | None = None, **options: Any
) -> int:
    """Diagnose every campaign the specs name on Dask (diagnosis.fleet), each with the single
    command's `options` (model, add, effects, geometry, data_part); with `report`, the fleet's page
    and each campaign's report beside it. Exit 2 when any failed, after all."""
    from ph_explorer.diagnosis.campaign_file import catalog_of, check_data_part, parse_add
    from ph_explorer.diagnosis.fleet import fleet_row, run_fleet
    from ph_explorer.figures.fleet_page import fleet_page_html, report_names, reported_fleet_row
    from ph_explorer.models.folder import check_model_folder

    paths = campaign_files(specs)
    page = checked_output_file(report, "--report", "the fleet's page", "fleet.html") if report is not None else None
    # The options are checked here once, so that a bad one is one line before any worker starts.
    parse_add(options.get("add"), catalog_of(options.get("effects")))
    options["data_part"] = check_data_part(options.get("data_part") or "trilinear")
    if options.get("model") is not None:
        check_model_folder(options["model"])
    errors = Console(stderr=True)
    started, done, slowest = time.perf_counter(), 0, ("", 0.0)
    created = datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%d %H:%M UTC")
    names = dict(zip(map(str, paths), report_names(paths, page))) if page is not None else {}
    task = partial(reported_fleet_row, created=created) if page is not None else fleet_row

    def progress(row: dict[str, Any]) -> None:
        nonlocal done, slowest
        text = row.pop("report_html", None)
        if page is not None and text is not None:
            # Written as it arrives, each atomically: the reports never wait in memory for the fleet.
            atomic_write([(page.parent / names[row["campaign"]], text)])
            row["report"] = names[row["campaign"]]
        done += 1
        if row["seconds"] >= slowest[1]:
            slowest = (Path(row["campaign"]).name, row["seconds"])
        errors.print(
            f"{done}/{len(paths)} diagnosed, {time.perf_counter() - started:.0f} s; slowest {slowest[0]} ({slowest[1]:.1f} s)",
            highlight=False,
        )

    run = run_fleet(paths, options, scheduler, on_row=progress, row=task)
    rows = run["campaigns"]
    failed = sum("error" in row for row in rows)
    seconds = round(time.perf_counter() - started, 2)
    lost = run["workers_lost"]
    said = f"{lost} of {run['workers']} workers lost during the fleet: Dask ran what they held again on the others" if lost else ""
    if said:
        errors.print(said, highlight=False)
    last = f"{len(rows)} campaigns in {seconds:.1f} s, {failed} failed" + (f"; {said}" if said else "")
    if page is not None:
        atomic_write([(page, fleet_page_html(rows, last, created))])
        errors.print(f"Fleet page written to {page}, each campaign's report beside it.", highlight=False)
    if json_output:
        print(json.dumps({**run, "failed": failed, "seconds": seconds}))
    else:
        Console(width=200).print(fleet_table(rows), last, highlight=False)
    return 2 if failed else 0


def fleet_table(rows: list[dict[str, Any]]) -> Table:
    """One line a campaign: its verdict, found effects with U (k = 2) and shapes, suggested ones, failing rings, time."""
    from ph_explorer.diagnosis.fleet import FLEET_COLUMNS, found_text, suggested_text

    table = Table(*FLEET_COLUMNS)
    for row in rows:
        if "error" in row:
            table.add_row(row["campaign"], row.get("sha256", "")[:12], "error", row["error"], "", "", f"{row['seconds']:.1f}")
            continue
        table.add_row(
            row["campaign"],
            row["sha256"][:12],
            row["verdict"],
            found_text(row),
            suggested_text(row),
            str(len(row["failing_rings"])),
            f"{row['seconds']:.1f}",
        )
    return table
