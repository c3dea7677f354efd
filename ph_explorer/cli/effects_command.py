"""`ph-explorer effects [--data FILE.csv] [--effects FILE.py] [--json]`: every effect of the catalog,
and with a campaign, what its design lets head touches see of each (diagnosis/identifiability.py)."""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path
from typing import Any

from ph_explorer.effects import DEFAULT_CATALOG


def effects_command(
    data: Path | None = None,
    effects: Path | None = None,
    json_output: bool = False,
    geometry: dict[str, float] | None = None,
) -> int:
    """Print the catalog's effects, with the campaign's identifiability figures when --data is given."""
    from ph_explorer.diagnosis.identifiability import describe_effect, identifiability
    from ph_explorer.io import read_campaign

    catalog = DEFAULT_CATALOG.with_file(effects) if effects is not None else DEFAULT_CATALOG
    if data is None:
        report: dict[str, Any] = {"effects": [describe_effect(cls) for cls in catalog.values()], "design": None}
    else:
        campaign = read_campaign(Path(data), geometry or {})
        report = identifiability(campaign, catalog.values())
        report["design"] = {"file": Path(data).name, **report["design"]}
    if json_output:
        print(json.dumps(report, allow_nan=False))
    else:
        print(effects_text(report), end="")
    return 0


def _share(value: float | None) -> str:
    return "-" if value is None else f"{value:.2f}"


def _span(row: dict[str, Any], key: str) -> str:
    """'0.95' at the default settings, then '[0.17-0.99]' over the scan."""
    text = _share(row.get(key))
    scan = row.get("over_scan")
    if scan and scan.get(key):
        low, high = scan[key]
        text += f" [{low:.2f}-{high:.2f}]"
    return text


def _visible(row: dict[str, Any]) -> str:
    text = {True: "yes", False: "no", None: "-"}[row.get("visible")]
    scan = row.get("over_scan")
    if scan:
        text += f" ({scan['visible']}/{scan['settings']})"
    return text


def _settings(settings: dict[str, float]) -> str:
    return ", ".join(f"{k.replace('_', ' ')} {v:g}" for k, v in settings.items())


def _confounded(row: dict[str, Any]) -> str:
    """'a_axis_cyclic 1.00 (cycles per rev 1; cycles per rev 2)': each partner, what it shares, at
    this effect's settings and then the partner's (said once when they are the same)."""
    parts = []
    for other in row.get("confounded_with", []):
        own, theirs = _settings(other["settings"]), _settings(other["other_settings"])
        where = f"{own}, both" if own and own == theirs else "; ".join(s for s in (own, theirs) if s)
        parts.append(f"{other['effect']} {other['shared']:.2f}" + (f" ({where})" if where else ""))
    return ", ".join(parts)


def _parameters(row: dict[str, Any]) -> str:
    out: list[str] = []
    runs: dict[str, int] = {}  # a shape's values at its knots (ECB_000 ... ECB_179): one entry per component
    for p in row["parameters"]:
        knot = re.fullmatch(r"(.+)_(\d{3})", p["name"])
        if knot and p["plausible"] is not None:
            symbol = knot.group(1)
            if symbol in runs:
                runs[symbol] += 1
                out[-1] = f"{symbol} at {runs[symbol]} knots {p['plausible'][0]:g}-{p['plausible'][1]:g}"
                continue
            runs[symbol] = 1
        if p["name"] in row["scan"]:
            low, high, _ = row["scan"][p["name"]]
            out.append(f"{p['name']} scanned {low:g}-{high:g}")
        elif p["plausible"] is not None:
            out.append(f"{p['name']} {p['plausible'][0]:g}-{p['plausible'][1]:g}")
        else:
            out.append(p["name"])
    return ", ".join(out)


def effects_text(report: dict[str, Any]) -> str:
    """An aligned plain-text table, one effect a line (the parameters last, with their plausible ranges)."""
    design = report["design"]
    headers = ["id", "symbol", "axis", "kind"]
    if design is not None:
        headers += ["visible", "absorbed by fit", "learnable"]
    headers.append("parameters (plausible magnitude)")
    rows = []
    for row in report["effects"]:
        cells = [row["id"], row["symbol"] or "-", row["axis"] or "-", row["kind"]]
        if design is not None:
            cells += [_visible(row), _span(row, "absorbed_by_circle_fit"), _span(row, "learnable_by_data_model")]
        rows.append(cells + [_parameters(row)])
    widths = [max(len(r[i]) for r in [headers, *rows]) for i in range(len(headers) - 1)]
    lines = []
    if design is not None:
        floor = "n/a (one repetition)" if design["noise_floor_um"] is None else f"{design['noise_floor_um']:.3f} um"
        lines += [
            f"{design['file']}: {design['rings']} rings ({design['held_out_rings']} held out), {design['repetitions']} "
            f"repetitions, {design['points']} points; mean-curve noise {floor}.",
            f"Stacked bases at the default settings: {design['columns']} columns, rank {design['rank_after_fit']} after the "
            f"circle fit, {design['rank_out_of_sample']} after the data model's out-of-sample smoother.",
            *textwrap.wrap(
                "Figures at each effect's default settings, [range over its scan]; visible (settings visible / scanned); "
                "absorbed by fit: the share of its term the circle fits remove; learnable: the share of what they leave that "
                "the lattice interpolates out of sample (docs/twin.md).",
                118,
            ),
            f"Confounded: {design['confounding']}.",
            "",
        ]
    for cells in [headers, *rows]:
        lines.append("  ".join(c.ljust(w) for c, w in zip(cells, widths)) + "  " + cells[-1])
    # Below the table, not in a column: a long list would widen every row beyond a terminal.
    partners = [(row["id"], _confounded(row)) for row in report["effects"] if design is not None and row.get("confounded_with")]
    if partners:
        lines += ["", "Confounded with (the share through the smoother; at this effect's settings, then the partner's):"]
        lines += [textwrap.fill(text, 118, initial_indent=f"  {name}: ", subsequent_indent="      ") for name, text in partners]
    return "\n".join(line.rstrip() for line in lines) + "\n"
