"""A fleet's page (`ph-explorer diagnose --data 'heads/*.csv' --report fleet.html`): one HTML table of
the campaigns, each linking to its own report written beside the page (docs/fleet.md).

Each campaign's report is made on its worker, beside its diagnosis, as `ph-explorer report` makes
it (figures/html_report.py), and comes back as text; the page itself needs no script and fetches
nothing but the reports it links to.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Sequence
from html import escape as _e
from pathlib import Path
from typing import Any

from ph_explorer.diagnosis.campaign_file import catalog_of
from ph_explorer.diagnosis.fleet import FLEET_COLUMNS, diagnosed_file, found_text, suggested_text
from ph_explorer.diagnosis.results import VERDICTS
from ph_explorer.figures.html_report import STYLE, diagnosed_report_html


def reported_fleet_row(path: str, options: dict[str, Any], created: str = "") -> dict[str, Any]:
    """fleet_row with the campaign's own report as HTML text ("report_html"), made on the worker."""
    started = time.perf_counter()
    row, campaign, result, loaded = diagnosed_file(path, options)
    if campaign is not None and result is not None:
        name = Path(path).name
        campaign.source = name
        try:
            row["report_html"] = diagnosed_report_html(
                campaign,
                result,
                name,
                row["sha256"],
                options.get("model"),
                catalog_of(options.get("effects")),
                options.get("data_part") or "trilinear",
                created=created,
                loaded=loaded,
            )
        except Exception as error:  # noqa: BLE001 - a fleet answers for every file: the error is the file's row
            row["error"] = f"{path}: the report: {type(error).__name__}: {' '.join(str(error).split())}"
    row["seconds"] = round(time.perf_counter() - started, 2)
    return row


def report_names(paths: Sequence[Path], page: Path) -> list[str]:
    """Each campaign's report file name beside the fleet's page: its file's stem + .html; where two
    campaigns share a stem (or one is the page's own name), the stem + its place in the fleet."""
    stems = [Path(p).stem for p in paths]
    taken = {page.name}
    names = []
    for i, stem in enumerate(stems, start=1):
        name = f"{stem}.html"
        if stems.count(stem) > 1 or name in taken:
            name = f"{stem}-{i}.html"
        taken.add(name)
        names.append(name)
    return names


def fleet_page_html(rows: Sequence[dict[str, Any]], summary: str, created: str = "") -> str:
    """The fleet's table as one HTML page: how many campaigns got each verdict, then a line a campaign
    (its report linked when it has one, row["report"]): its verdict, found effects with U (k = 2) and
    shapes, suggested ones, failing rings, time."""
    counts = Counter("error" if "error" in row else row["verdict"] for row in rows)
    verdicts = ", ".join(f"{verdict} {counts[verdict]}" for verdict in [*VERDICTS, "error"] if counts[verdict])
    lines = []
    for row in rows:
        name = _e(row["campaign"])
        cell = f'<a href="{_e(row["report"])}">{name}</a>' if row.get("report") else name
        if "error" in row:
            cells = [cell, _e(row.get("sha256", "")[:12]), "error", _e(row["error"]), "", ""]
        else:
            cells = [cell, _e(row["sha256"][:12]), _e(row["verdict"]), _e(found_text(row)), _e(suggested_text(row))]
            cells.append(str(len(row["failing_rings"])))
        cells.append(f"{row['seconds']:.1f}")
        lines.append("<tr>" + "".join(f'<td class="t">{c}</td>' if i < 5 else f"<td>{c}</td>" for i, c in enumerate(cells)) + "</tr>")
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en"><head><meta charset="utf-8">',
            f"<title>Fleet: {len(rows)} campaigns</title><style>{STYLE}th.t{{text-align:left}}</style></head><body>",
            f"<h1>Fleet: {len(rows)} campaigns</h1>",
            f'<p class="note">Made by ph-explorer{", " + _e(created) if created else ""}. {_e(summary)}. '
            "Each campaign's name links to its own report, written beside this page.</p>",
            f"<p>Verdicts: {_e(verdicts)}.</p>",
            "<table><thead><tr>"
            + "".join(f'<th class="t">{_e(h)}</th>' if i < 5 else f"<th>{_e(h)}</th>" for i, h in enumerate(FLEET_COLUMNS)),
            "</tr></thead><tbody>",
            *lines,
            "</tbody></table>",
            "</body></html>",
        ]
    )
