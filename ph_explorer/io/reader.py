"""Reading a campaign CSV (long format, one row per touch) into a Campaign, with one-line errors.

Columns (header on the first non-blank line, any order): A_deg, B_deg, rep, point, dev_um, and
optionally t_s (touch time) and x_mm, y_mm (raw points, when dev_um is missing). Every problem is
an InputError naming the file, the 1-based line number (the header is line 1) and the column.
The steps run one after the other, each vectorised over all rows: text -> rows -> numeric
columns -> orientation / repetition / point indices (checked) -> the cube.

Method: docs/methods/campaign_csv.md.
"""

from __future__ import annotations

import io as _io
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign, orientation_keys
from ph_explorer.errors import InputError
from ph_explorer.geometry import A_LIMIT_DEG, B_LIMIT_DEG
from ph_explorer.harmonics import circle_deviations_um
from ph_explorer.io.csv_text import decoded_text, numeric_columns, parse_rows, read_bytes
from ph_explorer.io.sidecar import read_sidecar, sidecar_geometry, sidecar_path, sidecar_scenario

REQUIRED_COLUMNS = ("A_deg", "B_deg", "rep", "point", "dev_um")
OPTIONAL_COLUMNS = ("t_s", "x_mm", "y_mm")
KNOWN_COLUMNS = REQUIRED_COLUMNS + OPTIONAL_COLUMNS


def read_campaign(path: str | os.PathLike[str], geometry_overrides: dict[str, Any] | None = None) -> Campaign:
    """Load a long-format campaign CSV (and its sidecar TOML) into a Campaign; InputError on bad input.

    geometry_overrides (e.g. from CLI options) win over the sidecar's [geometry].
    """
    path = Path(path)
    name = str(path)
    text = decoded_text(read_bytes(path), name)
    table = _plain_table(text, name)
    if table is None:  # quotes, blank lines or a cell numpy does not read: row by row, naming the first problem
        header, header_line, rows, lines = parse_rows(text, name)
        _check_header(header, name, header_line)
        if not rows:
            raise InputError("empty file: a header but no rows", file=name, row=header_line + 1)
        table = _Table(name, lines, numeric_columns(header, rows, lines, name))
    table.check_angle_ranges()
    layout = _layout(table)
    deviations = _deviations(table, layout)
    times = layout.cube(table.values["t_s"]) if "t_s" in table.values else None

    toml_path = sidecar_path(path)
    sidecar = read_sidecar(toml_path)
    geometry = sidecar_geometry(sidecar, geometry_overrides, layout.n_points, str(toml_path))
    scenario, check_orientations = sidecar_scenario(sidecar)
    return Campaign(
        orientations=layout.orientations,
        deviations=deviations,
        times_s=times,
        geometry=geometry,
        check_orientations=check_orientations,
        scenario=scenario,
        source=name,
    )


# -- bytes -> text -> rows --------------------------------------------------------------------------
_LONE_CR = re.compile("\r(?!\n)")
# numpy's reader skips characters float() refuses (e.g. the separator \x1c after a number): a file with
# anything beyond printable ASCII, tab and line ends is not plain (bytes.translate: 20 ms for 29 MB).
_PLAIN_BYTES = bytes(range(32, 127)) + b"\t\n\r"


def _only_plain_characters(text: str) -> bool:
    return text.isascii() and not text.encode("ascii").translate(None, _PLAIN_BYTES)


def _plain_table(text: str, name: str) -> _Table | None:
    """The numeric columns of a plain file (a header on line 1, then one row of numbers per line,
    no quotes, no blank line) through numpy's C reader, several times faster than row by row on a
    million touches; None for any other file, which the row-by-row path reads or names the problem of."""
    first_end = text.find("\n")
    # A lone carriage return ends a line for the row-by-row reader, not for this one: not plain.
    if '"' in text or first_end <= 0 or _LONE_CR.search(text) or not _only_plain_characters(text):
        return None
    header = [cell.strip() for cell in text[:first_end].split(",")]
    body = text[first_end + 1 :]
    n_rows = body.count("\n") + (0 if body.endswith("\n") else 1)
    if not body.strip() or any(not cell for cell in header):
        return None
    _check_header(header, name)
    try:  # numpy reads only what float() reads too; what it refuses goes the row-by-row way
        values = np.loadtxt(_io.StringIO(body), delimiter=",", comments=None, dtype=float, ndmin=2)
    except ValueError:
        return None
    if values.shape != (n_rows, len(header)):  # a blank line numpy skipped: line numbers would shift
        return None
    lines = np.arange(2, n_rows + 2, dtype=np.int64)
    table = _Table(name, lines, {column: np.ascontiguousarray(values[:, j]) for j, column in enumerate(header)})
    bad = ~np.isfinite(values)
    if bad.any():  # the first column's first, as the row-by-row path names it
        j = int(np.argmax(bad.any(axis=0)))
        i = int(np.argmax(bad[:, j]))
        cell = body.split("\n")[i].split(",")[j].strip()
        raise table.error(f"value {cell!r} is not finite", i, header[j])
    return table


def _check_header(header: list[str], name: str, header_line: int = 1) -> None:
    seen: set[str] = set()
    for column in header:
        if column not in KNOWN_COLUMNS:
            raise InputError(_unknown_column_hint(column), file=name, row=header_line, column=_shown(column) or None)
        if column in seen:
            raise InputError(f"column {column!r} appears twice", file=name, row=header_line, column=column)
        seen.add(column)
    has_xy = "x_mm" in seen and "y_mm" in seen
    for column in REQUIRED_COLUMNS:
        if column == "dev_um" and has_xy:
            continue
        if column not in seen:
            extra = " (or both x_mm and y_mm)" if column == "dev_um" else ""
            raise InputError(f"missing column {column!r}{extra}", file=name, row=header_line, column=column)
    for a, b in (("x_mm", "y_mm"), ("y_mm", "x_mm")):
        if a in seen and b not in seen:
            raise InputError(f"column {a!r} needs column {b!r} too", file=name, row=header_line, column=b)


def _unknown_column_hint(column: str) -> str:
    """What to tell about a header cell that is not a known column (the likely cause first)."""
    if any(ord(ch) < 32 and ch not in "\t" for ch in column) or "\ufffd" in column:
        return "not a CSV text file (control characters in the header)"
    if not column:
        return "empty column name in the header"
    if any(sep in column for sep in ";\t|"):
        return f"unknown column {column!r}: columns must be separated by commas"
    return f"unknown column {column!r} (known: {', '.join(KNOWN_COLUMNS)})"


def _shown(column: str) -> str:
    return column if column.isprintable() else repr(column)  # the error stays one line


@dataclass
class _Table:
    """The numeric columns of a file, with the line of every row for the error messages."""

    name: str
    lines: NDArray[np.int64]
    values: dict[str, NDArray[np.float64]]

    def error(self, message: str, i: int, column: str | None) -> InputError:
        """An InputError at row i (0-based data row)."""
        return InputError(message, file=self.name, row=int(self.lines[i]), column=column)

    def check_angle_ranges(self) -> None:
        for col, limit in (("A_deg", A_LIMIT_DEG), ("B_deg", B_LIMIT_DEG)):
            arr = self.values[col]
            out = np.abs(arr) > limit
            if out.any():
                i = int(np.argmax(out))
                raise self.error(f"{col} = {arr[i]:g} is outside [-{limit:g}, {limit:g}]", i, col)

    def integers(self, column: str) -> NDArray[np.int64]:
        values = self.values[column]
        bad = (values != np.round(values)) | (np.abs(values) > 2**31)
        if bad.any():
            i = int(np.argmax(bad))
            raise self.error(f"{column} must be an integer, got {values[i]:g}", i, column)
        return values.astype(np.int64)


# -- numeric columns -> (orientation, repetition, point) of every row -------------------------------
@dataclass
class _Layout:
    """Where every row goes in the (n_o, n_rep, n_pt) cube."""

    orientations: NDArray[np.float64]  # (n_o, 2) in the order they were measured
    orient: NDArray[np.int64]  # per row: orientation index
    rep_rank: NDArray[np.int64]  # per row: repetition rank within its orientation
    point: NDArray[np.int64]  # per row: 0-based point number
    n_repetitions: int
    n_points: int
    repetition_first_row: NDArray[np.int64]  # per (orientation, repetition) in cube order: its first row

    def cube(self, column: NDArray[np.float64]) -> NDArray[np.float64]:
        cube = np.empty((len(self.orientations), self.n_repetitions, self.n_points))
        cube[self.orient, self.rep_rank, self.point] = column
        return cube


def _layout(table: _Table) -> _Layout:
    """Index every row by orientation, repetition rank and point; InputError on gaps and duplicates."""
    rep = table.integers("rep")
    point, base = _zero_based_points(table)
    orient, orientations = _orientation_index(table)
    repetitions = _Repetitions(orient, rep, len(orientations))
    repetitions.check_equal_counts(table, orientations)
    _check_duplicates(table, repetitions.group, point, rep, base)
    n_points = _points_per_circle(table, repetitions, point, base, orientations)
    return _Layout(
        orientations=orientations,
        orient=orient,
        rep_rank=repetitions.rank,
        point=point,
        n_repetitions=repetitions.n_repetitions,
        n_points=n_points,
        repetition_first_row=repetitions.first_row,
    )


def _zero_based_points(table: _Table) -> tuple[NDArray[np.int64], int]:
    """Point numbers from 0, and the base (0 or 1) the file uses, decided by its smallest point number."""
    point = table.integers("point")
    base = int(point.min())
    if base not in (0, 1):
        raise table.error(f"point numbers must start at 0 or 1, the smallest is {base}", int(np.argmin(point)), "point")
    return point - base, base


def _orientation_index(table: _Table) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Each row's orientation index, and the orientations in the order they were measured.

    Measured order: by their first touch time when the file has t_s, else by their first row.
    """
    a, b = table.values["A_deg"], table.values["B_deg"]
    keys = orientation_keys(np.stack([a, b], axis=1))
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    if "t_s" in table.values:
        first_time = np.full(len(first), np.inf)
        np.minimum.at(first_time, inverse, table.values["t_s"])
        by_appearance = np.lexsort((first, first_time))
    else:
        by_appearance = np.argsort(first, kind="stable")
    rank = np.empty_like(by_appearance)
    rank[by_appearance] = np.arange(len(by_appearance))
    first_rows = first[by_appearance]
    return rank[inverse], np.stack([a[first_rows], b[first_rows]], axis=1)


class _Repetitions:
    """The (orientation, repetition label) groups of the rows; labels ranked within each orientation."""

    def __init__(self, orient: NDArray[np.int64], rep: NDArray[np.int64], n_orientations: int) -> None:
        pairs, first, group = np.unique(np.stack([orient, rep], axis=1), axis=0, return_index=True, return_inverse=True)
        self.pairs = pairs  # (n_groups, 2): orientation index, repetition label; sorted, so in cube order
        self.first_row = first  # per group: its first row
        self.group = group.ravel()  # per row: its group
        self.per_orientation = np.bincount(pairs[:, 0], minlength=n_orientations)
        self.start = np.concatenate([[0], np.cumsum(self.per_orientation)[:-1]])
        self.rank = (np.arange(len(pairs)) - self.start[pairs[:, 0]])[self.group]
        self.n_repetitions = int(self.per_orientation.max())
        self.orient = orient

    def check_equal_counts(self, table: _Table, orientations: NDArray[np.float64]) -> None:
        unequal = self.per_orientation != self.n_repetitions
        if unequal.any():
            o = int(np.argmax(unequal))
            raise table.error(
                f"orientation A={orientations[o, 0]:g} B={orientations[o, 1]:g} has {self.per_orientation[o]} "
                f"repetitions, others have {self.n_repetitions}",
                int(np.argmax(self.orient == o)),
                "rep",
            )


def _check_duplicates(table: _Table, group: NDArray[np.int64], point: NDArray[np.int64], rep: NDArray[np.int64], base: int) -> None:
    """No touch twice: the same (A, B, rep, point) in two rows."""
    touch_key = group.astype(np.int64) * (int(point.max()) + 1) + point
    order = np.argsort(touch_key, kind="stable")
    dup = np.flatnonzero(touch_key[order][1:] == touch_key[order][:-1])
    if dup.size:
        i = int(order[dup[0] + 1])
        a, b = table.values["A_deg"][i], table.values["B_deg"][i]
        raise table.error(f"duplicate touch A={a:g} B={b:g} rep={rep[i]} point={point[i] + base}", i, "point")


def _points_per_circle(
    table: _Table, repetitions: _Repetitions, point: NDArray[np.int64], base: int, orientations: NDArray[np.float64]
) -> int:
    """N: every repetition holds points 0..N-1, with the same N everywhere."""
    n_groups = len(repetitions.pairs)
    counts = np.bincount(repetitions.group, minlength=n_groups)
    highest = np.full(n_groups, -1, dtype=np.int64)
    np.maximum.at(highest, repetitions.group, point)
    n_each = highest + 1
    complete = n_each == counts  # no duplicates, so count == max+1 means 0..max all there
    n_points = int(np.bincount(n_each[complete]).argmax()) if complete.any() else int(n_each.max())

    def where(g: int) -> str:
        o, r = repetitions.pairs[g]
        return f"rep={r} at A={orientations[o, 0]:g} B={orientations[o, 1]:g}"

    if not complete.all():
        g = int(np.argmax(~complete))
        held = np.sort(point[repetitions.group == g])
        missing = int(np.argmax(held != np.arange(held.size))) + base  # the first number not held
        raise table.error(f"repetition {where(g)} is missing point {missing}", int(repetitions.first_row[g]), "point")
    unequal = n_each != n_points
    if unequal.any():
        g = int(np.argmax(unequal))
        raise table.error(
            f"unequal point counts: repetition {where(g)} has {n_each[g]} points, the others {n_points}",
            int(repetitions.first_row[g]),
            "point",
        )
    if n_points < 3:
        raise InputError(f"a circle needs at least 3 points, the file has {n_points}", file=table.name, row=2, column="point")
    return n_points


# -- the cube ---------------------------------------------------------------------------------------
def _deviations(table: _Table, layout: _Layout) -> NDArray[np.float64]:
    """dev_um as given, or, without it, the deviations from the LS circle of each repetition's raw points."""
    if "dev_um" in table.values:
        return layout.cube(table.values["dev_um"])
    with np.errstate(all="ignore"):
        deviations = circle_deviations_um(layout.cube(table.values["x_mm"]), layout.cube(table.values["y_mm"]))
    degenerate = ~np.isfinite(deviations).all(axis=-1)  # (n_o, n_rep)
    if degenerate.any():
        o, r = np.argwhere(degenerate)[0]
        a, b = layout.orientations[o]
        raise table.error(
            f"the points of repetition {r + 1} at A={a:g} B={b:g} do not define a circle",
            int(layout.repetition_first_row[o * layout.n_repetitions + r]),
            "x_mm",
        )
    return deviations
