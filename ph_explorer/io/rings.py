"""A file of rings to measure: the orientations `design --decide --out` writes and `simulate --rings`
reads (columns A_deg, B_deg; others, e.g. order and reason, are kept for the reader of the file).
Format: docs/formats.md#rings-to-measure; method: docs/methods/deciding.md.
"""

from __future__ import annotations

import csv
import io as _io
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import orientation_label, orientation_match
from ph_explorer.errors import InputError
from ph_explorer.io.csv_text import decoded_text, numeric_column, parse_rows, read_bytes

RING_COLUMNS = ("A_deg", "B_deg")


def read_rings(path: str | os.PathLike[str]) -> NDArray[np.float64]:
    """(n, 2) orientations in the file's order; InputError naming the file, row and column."""
    return read_planned_rings(path)[0]


def read_planned_rings(path: str | os.PathLike[str]) -> tuple[NDArray[np.float64], NDArray[np.bool_] | None]:
    """(n, 2) orientations in the file's order and, when it has a `check` column (design --start and
    --next write one: true for a check ring, held out of every fit), which are check rings."""
    name = str(path)
    header, header_line, rows, lines = parse_rows(decoded_text(read_bytes(Path(path)), name), name)
    for column in RING_COLUMNS:
        if column not in header:
            raise InputError(f"no {column} column (a rings file has A_deg and B_deg)", file=name, row=header_line)
    if not rows:
        raise InputError("no rings: the header and no rows", file=name, row=header_line)
    index = [header.index(c) for c in RING_COLUMNS]
    for record, line in zip(rows, lines):
        if len(record) <= max(index):
            raise InputError(f"{len(record)} fields where the header has {len(header)}", file=name, row=int(line))
    rings = np.stack([numeric_column([r[j] for r in rows], c, lines, name) for j, c in zip(index, RING_COLUMNS)], axis=1)
    same = np.triu(orientation_match(rings, rings), k=1)
    if same.any():
        i, j = np.argwhere(same)[0]
        raise InputError(f"{orientation_label(*rings[j])} is listed twice (first on row {lines[i]})", file=name, row=int(lines[j]))
    if "check" not in header:
        return rings, None
    k = header.index("check")
    words = {"true": True, "1": True, "false": False, "0": False}
    for record, line in zip(rows, lines):
        if len(record) <= k or record[k].strip().lower() not in words:
            cell = record[k] if len(record) > k else ""
            raise InputError(f"check must be true or false, got {cell!r}", file=name, row=int(line), column="check")
    return rings, np.array([words[r[k].strip().lower()] for r in rows])


def rings_csv_text(rings: list[dict[str, Any]]) -> str:
    """The rings (each with A_deg, B_deg, order, reason, and check when they say which are check
    rings) as CSV text, for a CMM program."""
    out = _io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    roles = bool(rings) and all("check" in ring for ring in rings)
    writer.writerow([*RING_COLUMNS, "order", "reason", *(["check"] if roles else [])])
    for ring in rings:
        role = ["true" if ring["check"] else "false"] if roles else []
        writer.writerow([f"{ring['A_deg']:g}", f"{ring['B_deg']:g}", ring["order"], ring["reason"], *role])
    return out.getvalue()
