"""Campaign files: the long-format CSV (one row per touch), its sidecar TOML, and `inspect`.

CSV columns (header on line 1, any order):
    A_deg, B_deg   nominal head orientation of the ring (deg), A in [-115, 115], B in [-180, 180]
    rep            repetition label, an integer; repetitions are ranked per orientation, so they
                   may start at 0 or 1 (or anywhere) as long as every orientation has as many
    point          point number k, an integer, 0..N-1 or 1..N (the smallest point number in the file
                   decides), theta_k = 360 k / N (0-based k)
    dev_um         deviation (um) from the LS circle of its own repetition, positive outward
    t_s            optional: time of the touch (s since the campaign start); it fixes the touch order
    x_mm, y_mm     optional: the raw point in the ring frame (mm); without dev_um the deviations
                   come from the geometric LS circle of each repetition

Sidecar NAME.toml beside NAME.csv (optional): [geometry] pivot_to_ball_mm, ball_diameter_mm,
bore_diameter_mm; [scenario] (written by simulate) name, description, seed, check_orientations,
hidden, effects.

Every problem is an InputError naming the file, the 1-based line number (the header is line 1)
and the column. Validation is vectorised over all rows.
"""

from __future__ import annotations

import csv
import io as _io
import json
import math
import os
import tempfile
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.geometry import A_LIMIT_DEG, B_LIMIT_DEG, DEFAULT_GEOMETRY, Geometry
from ph_explorer.harmonics import circle_deviations_um

REQUIRED_COLUMNS = ("A_deg", "B_deg", "rep", "point", "dev_um")
OPTIONAL_COLUMNS = ("t_s", "x_mm", "y_mm")
KNOWN_COLUMNS = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
GEOMETRY_KEYS = ("pivot_to_ball_mm", "ball_diameter_mm", "bore_diameter_mm")
SCENARIO_KEYS = ("name", "description", "seed", "check_orientations", "hidden", "effects")

# Orientations are the same when A and B agree to this many decimals (deg).
_ORIENTATION_DECIMALS = 6


def sidecar_path(csv_path: str | os.PathLike[str]) -> Path:
    """The sidecar TOML beside a campaign CSV: NAME.csv -> NAME.toml."""
    return Path(csv_path).with_suffix(".toml")


# -- reading --------------------------------------------------------------------------------


def _decode(raw: bytes, name: str) -> str:
    """The file's text, or an InputError when it is not UTF-8 CSV text."""
    if raw[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise InputError("not a UTF-8 CSV text file (UTF-16 text: save it as UTF-8 CSV)", file=name, row=1)
    if b"\x00" in raw:
        line = raw[: raw.index(b"\x00")].count(b"\n") + 1
        raise InputError("not a CSV text file (binary data: NUL byte)", file=name, row=line)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        line = raw[: error.start].count(b"\n") + 1
        raise InputError(
            f"not a UTF-8 CSV text file (undecodable byte 0x{raw[error.start]:02x})", file=name, row=line
        ) from None


def _parse_rows(text: str, name: str) -> tuple[list[str], int, list[list[str]], NDArray[np.int64]]:
    """Header, its line, the data rows and their 1-based line numbers; blank lines are skipped."""
    reader = csv.reader(_io.StringIO(text, newline=""), strict=True)
    if '"' not in text:
        # Fast path: without quotes every record is one physical line, so record i is line i + 1.
        try:
            records = list(reader)
        except csv.Error as error:
            raise InputError(f"not valid CSV text ({error})", file=name, row=reader.line_num) from None
        filled = [i for i, r in enumerate(records) if len(r) > 1 or (r and r[0].strip())]
        if not filled:
            raise InputError("empty file: no header and no rows", file=name, row=1)
        header_index = filled[0]
        return (
            [cell.strip() for cell in records[header_index]],
            header_index + 1,
            [records[i] for i in filled[1:]],
            np.asarray(filled[1:], dtype=np.int64) + 1,
        )
    header: list[str] | None = None
    header_line = 1
    rows: list[list[str]] = []
    lines: list[int] = []
    last_end = 0  # line where the previous record ended: a broken record starts on the next one
    try:
        for record in reader:
            last_end = reader.line_num
            if len(record) <= 1 and not (record and record[0].strip()):
                continue  # a blank line
            if header is None:
                header = [cell.strip() for cell in record]
                header_line = reader.line_num
                continue
            rows.append(record)
            lines.append(reader.line_num)
    except csv.Error as error:
        raise InputError(f"not valid CSV text ({error})", file=name, row=last_end + 1) from None
    if header is None:
        raise InputError("empty file: no header and no rows", file=name, row=1)
    return header, header_line, rows, np.asarray(lines, dtype=np.int64)


def _check_header(header: list[str], name: str, header_line: int = 1) -> None:
    seen: set[str] = set()
    for column in header:
        if column not in KNOWN_COLUMNS:
            hint = f"unknown column {column!r} (known: {', '.join(KNOWN_COLUMNS)})"
            if not column:
                hint = "empty column name in the header"
            elif any(sep in column for sep in ";\t|"):
                hint = f"unknown column {column!r}: columns must be separated by commas"
            if any(ord(ch) < 32 and ch not in "\t" for ch in column) or "\ufffd" in column:
                hint = "not a CSV text file (control characters in the header)"
            shown = column if column.isprintable() else repr(column)  # the error stays one line
            raise InputError(hint, file=name, row=header_line, column=shown or None)
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


def _numeric_column(cells: list[str], column: str, lines: NDArray[np.int64], name: str) -> NDArray[np.float64]:
    """The column as floats; an InputError at the first non-numeric, NaN or infinite value."""
    try:
        values = np.fromiter(map(float, cells), dtype=float, count=len(cells))
    except ValueError:
        # Only on the error path: find the offending cell.
        for cell, line in zip(cells, lines):
            try:
                float(cell)
            except ValueError:
                shown = cell if len(cell) <= 40 else cell[:37] + "..."
                raise InputError(f"not a number: {shown!r}", file=name, row=int(line), column=column) from None
        raise InputError("not a number", file=name, column=column) from None  # pragma: no cover
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"value {cells[i].strip()!r} is not finite", file=name, row=int(lines[i]), column=column)
    return values


def _integer_column(values: NDArray[np.float64], column: str, lines: NDArray[np.int64], name: str) -> NDArray[np.int64]:
    bad = (values != np.round(values)) | (np.abs(values) > 2**31)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"{column} must be an integer, got {values[i]:g}", file=name, row=int(lines[i]), column=column)
    return values.astype(np.int64)


def _first_line(mask: NDArray[np.bool_], lines: NDArray[np.int64]) -> int:
    return int(lines[int(np.argmax(mask))])


def _read_sidecar(path: Path) -> dict[str, Any]:
    if not path.is_file():
        return {}
    name = str(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError:
        raise InputError("not a UTF-8 TOML text file", file=name) from None
    except tomllib.TOMLDecodeError as error:
        lineno = getattr(error, "lineno", None)
        raise InputError(f"not valid TOML ({error})", file=name, row=lineno) from None
    unknown = sorted(set(data) - {"geometry", "scenario"})
    if unknown:
        raise InputError(f"unknown table [{unknown[0]}] (known: [geometry], [scenario])", file=name, column=unknown[0])
    for table in ("geometry", "scenario"):
        if table in data and not isinstance(data[table], dict):
            raise InputError(f"{table} must be a table [{table}]", file=name, column=table)
    geometry = data.get("geometry", {})
    for key, value in geometry.items():
        if key not in GEOMETRY_KEYS + ("points_per_circle",):
            raise InputError(f"unknown geometry key {key!r} (known: {', '.join(GEOMETRY_KEYS)})", file=name, column=key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"geometry {key} must be a finite number, got {value!r}", file=name, column=key)
    scenario = data.get("scenario", {})
    checks = scenario.get("check_orientations")
    if checks is not None:
        try:
            arr = np.asarray(checks, dtype=float)
            ok = arr.size == 0 or (arr.ndim == 2 and arr.shape[1] == 2 and np.isfinite(arr).all())
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise InputError("check_orientations must be a list of [A, B] pairs", file=name, column="check_orientations")
    return data


def _geometry(sidecar: dict[str, Any], overrides: dict[str, Any] | None, n_points: int, toml_name: str) -> Geometry:
    values: dict[str, Any] = {}
    given = dict(sidecar.get("geometry", {}))
    stated_points = given.pop("points_per_circle", None)
    if stated_points is not None and int(stated_points) != n_points:
        raise InputError(
            f"points_per_circle = {stated_points} but the CSV has {n_points} points per circle",
            file=toml_name,
            column="points_per_circle",
        )
    values.update({k: float(v) for k, v in given.items()})
    for key, value in (overrides or {}).items():
        if key not in GEOMETRY_KEYS:
            raise InputError(f"unknown geometry option {key!r}", column=key)
        if value is not None:
            values[key] = float(value)
    try:
        return replace(DEFAULT_GEOMETRY, points_per_circle=n_points, **values)
    except ValueError as error:
        source = toml_name if given and not overrides else None
        stated = ", ".join(f"{k} = {v:g}" for k, v in values.items())
        raise InputError(f"impossible geometry ({stated}): {error}", file=source) from None


def read_campaign(path: str | os.PathLike[str], geometry_overrides: dict[str, Any] | None = None) -> Campaign:
    """Load a long-format campaign CSV (and its sidecar TOML) into a Campaign; InputError on bad input.

    geometry_overrides (e.g. from CLI options) win over the sidecar's [geometry].
    """
    path = Path(path)
    name = str(path)
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError("no such file", file=name) from None
    except IsADirectoryError:
        raise InputError("is a directory, not a CSV file", file=name) from None
    except OSError as error:
        raise InputError(f"cannot read the file ({error.strerror})", file=name) from None
    if not raw.strip():
        raise InputError("empty file: no header and no rows", file=name, row=1)
    text = _decode(raw, name)
    header, header_line, rows, lines = _parse_rows(text, name)
    _check_header(header, name, header_line)
    if not rows:
        raise InputError("empty file: a header but no rows", file=name, row=header_line + 1)

    width = len(header)
    lengths = np.fromiter((len(r) for r in rows), dtype=np.int64, count=len(rows))
    ragged = lengths != width
    if ragged.any():
        i = int(np.argmax(ragged))
        column = header[lengths[i]] if lengths[i] < width else None
        raise InputError(
            f"{lengths[i]} fields where the header has {width}", file=name, row=int(lines[i]), column=column
        )
    columns = {col: [r[j] for r in rows] for j, col in enumerate(header)}
    values = {col: _numeric_column(columns[col], col, lines, name) for col in header}

    a, b = values["A_deg"], values["B_deg"]
    for col, arr, limit in (("A_deg", a, A_LIMIT_DEG), ("B_deg", b, B_LIMIT_DEG)):
        out = np.abs(arr) > limit
        if out.any():
            i = int(np.argmax(out))
            raise InputError(
                f"{col} = {arr[i]:g} is outside [-{limit:g}, {limit:g}]", file=name, row=int(lines[i]), column=col
            )
    rep = _integer_column(values["rep"], "rep", lines, name)
    point = _integer_column(values["point"], "point", lines, name)

    # Point numbers: 0..N-1 or 1..N, decided by the smallest one in the file.
    base = int(point.min())
    if base not in (0, 1):
        i = int(np.argmin(point))
        raise InputError(
            f"point numbers must start at 0 or 1, the smallest is {base}", file=name, row=int(lines[i]), column="point"
        )
    k = point - base

    # Orientations in the order they were measured: by their first touch time when the file has
    # t_s, else by their first appearance in the file.
    keys = np.round(np.stack([a, b], axis=1), _ORIENTATION_DECIMALS)
    _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
    inverse = inverse.ravel()
    if "t_s" in values:
        first_time = np.full(len(first), np.inf)
        np.minimum.at(first_time, inverse, values["t_s"])
        by_appearance = np.lexsort((first, first_time))
    else:
        by_appearance = np.argsort(first, kind="stable")
    rank = np.empty_like(by_appearance)
    rank[by_appearance] = np.arange(len(by_appearance))
    orient = rank[inverse]
    orientations = np.stack([a[first[by_appearance]], b[first[by_appearance]]], axis=1)
    n_o = len(orientations)

    # Repetitions ranked per orientation (labels may start at 0, 1 or anywhere).
    pairs, pair_first, pair_inv = np.unique(
        np.stack([orient, rep], axis=1), axis=0, return_index=True, return_inverse=True
    )
    pair_inv = pair_inv.ravel()
    reps_per_orient = np.bincount(pairs[:, 0], minlength=n_o)
    start = np.concatenate([[0], np.cumsum(reps_per_orient)[:-1]])
    rep_rank = (np.arange(len(pairs)) - start[pairs[:, 0]])[pair_inv]
    n_rep = int(reps_per_orient.max())
    if (reps_per_orient != n_rep).any():
        o = int(np.argmax(reps_per_orient != n_rep))
        row = _first_line(orient == o, lines)
        raise InputError(
            f"orientation A={orientations[o, 0]:g} B={orientations[o, 1]:g} has {reps_per_orient[o]} repetitions, "
            f"others have {n_rep}",
            file=name,
            row=row,
            column="rep",
        )

    # Duplicate touches: the same (A, B, rep, point) twice.
    touch_key = (pair_inv.astype(np.int64) * (int(k.max()) + 1)) + k
    order = np.argsort(touch_key, kind="stable")
    dup = np.flatnonzero(touch_key[order][1:] == touch_key[order][:-1])
    if dup.size:
        i = int(order[dup[0] + 1])
        raise InputError(
            f"duplicate touch A={a[i]:g} B={b[i]:g} rep={rep[i]} point={point[i]}",
            file=name,
            row=int(lines[i]),
            column="point",
        )

    # Points: every repetition holds points 0..N-1 with the same N.
    counts = np.bincount(pair_inv, minlength=len(pairs))
    highest = np.full(len(pairs), -1, dtype=np.int64)
    np.maximum.at(highest, pair_inv, k)
    complete = highest + 1 == counts  # no duplicates, so count == max+1 means 0..max all there
    n_pt_each = highest + 1
    n_pt = int(np.bincount(n_pt_each[complete]).argmax()) if complete.any() else int(highest.max() + 1)
    gap = ~complete
    if gap.any():
        g = int(np.argmax(gap))
        held = np.sort(k[pair_inv == g])
        missing = int(np.argmax(held != np.arange(held.size))) + base  # the first number not held
        o, r = pairs[g]
        raise InputError(
            f"repetition rep={r} at A={orientations[o, 0]:g} B={orientations[o, 1]:g} is missing point {missing}",
            file=name,
            row=int(lines[pair_first[g]]),
            column="point",
        )
    unequal = n_pt_each != n_pt
    if unequal.any():
        g = int(np.argmax(unequal))
        o, r = pairs[g]
        raise InputError(
            f"unequal point counts: repetition rep={r} at A={orientations[o, 0]:g} B={orientations[o, 1]:g} "
            f"has {n_pt_each[g]} points, the others {n_pt}",
            file=name,
            row=int(lines[pair_first[g]]),
            column="point",
        )
    if n_pt < 3:
        raise InputError(f"a circle needs at least 3 points, the file has {n_pt}", file=name, row=2, column="point")

    def to_cube(v: NDArray[np.float64]) -> NDArray[np.float64]:
        cube = np.empty((n_o, n_rep, n_pt))
        cube[orient, rep_rank, k] = v
        return cube

    if "dev_um" in values:
        deviations = to_cube(values["dev_um"])
    else:
        with np.errstate(all="ignore"):
            deviations = circle_deviations_um(to_cube(values["x_mm"]), to_cube(values["y_mm"]))
        degenerate = ~np.isfinite(deviations).all(axis=-1)  # (n_o, n_rep)
        if degenerate.any():
            o, r = np.argwhere(degenerate)[0]
            raise InputError(
                f"the points of repetition {r + 1} at A={orientations[o, 0]:g} B={orientations[o, 1]:g} "
                "do not define a circle",
                file=name,
                row=int(lines[pair_first[start[o] + r]]),
                column="x_mm",
            )
    times = to_cube(values["t_s"]) if "t_s" in values else None

    toml_path = sidecar_path(path)
    sidecar = _read_sidecar(toml_path)
    geometry = _geometry(sidecar, geometry_overrides, n_pt, str(toml_path))
    scenario = dict(sidecar.get("scenario", {}))
    checks = scenario.pop("check_orientations", None)
    check_orientations = np.asarray(checks, dtype=float).reshape(-1, 2) if checks is not None else None
    return Campaign(
        orientations=orientations,
        deviations=deviations,
        times_s=times,
        geometry=geometry,
        check_orientations=check_orientations,
        scenario=scenario,
        source=name,
    )


# -- writing --------------------------------------------------------------------------------


def _plain(value: Any) -> Any:
    """TOML-writable Python values: numpy scalars and arrays become numbers and lists; None is dropped."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value if v is not None]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value


def _number(x: float) -> str:
    """A short, exact-enough, deterministic text for an orientation angle."""
    text = f"{x + 0.0:.10g}"
    return "0" if text == "-0" else text


def _format_rows(campaign: Campaign) -> str:
    n_o, n_rep, n_pt = campaign.deviations.shape
    o_idx, r_idx, p_idx = np.indices((n_o, n_rep, n_pt)).reshape(3, -1)
    a_text = np.array([_number(v) for v in campaign.orientations[:, 0]], dtype=object)[o_idx]
    b_text = np.array([_number(v) for v in campaign.orientations[:, 1]], dtype=object)[o_idx]
    # +0.0 turns -0.0 into 0.0 so "-0.00000" never appears.
    dev = np.round(campaign.deviations.ravel(), 5) + 0.0
    columns = [a_text, b_text, r_idx, p_idx, [f"{v:.5f}" for v in dev.tolist()]]
    header = ["A_deg", "B_deg", "rep", "point", "dev_um"]
    if campaign.times_s is not None:
        t = np.round(campaign.times_s.ravel(), 3) + 0.0
        columns.append([f"{v:.3f}" for v in t.tolist()])
        header.append("t_s")
    body = "\n".join(",".join(map(str, row)) for row in zip(*columns))
    return ",".join(header) + "\n" + body + "\n"


def _sidecar_text(campaign: Campaign) -> str:
    import tomli_w

    g = campaign.geometry
    doc: dict[str, Any] = {"geometry": {k: float(getattr(g, k)) for k in GEOMETRY_KEYS}}
    scenario = _plain(dict(campaign.scenario or {}))
    if campaign.check_orientations is not None:
        scenario["check_orientations"] = [[float(a), float(b)] for a, b in np.asarray(campaign.check_orientations)]
    if scenario:
        doc["scenario"] = scenario
    return tomli_w.dumps(doc)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _atomic_write(targets: list[tuple[Path, str]]) -> None:
    """Write every text to a temp file beside its target, then move them all into place."""
    temps: list[tuple[str, Path]] = []
    try:
        for target, text in targets:
            target.parent.mkdir(parents=True, exist_ok=True)
            fd, temp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
            temps.append((temp, target))
            os.chmod(temp, 0o666 & ~_umask())  # mkstemp makes 0600; give the usual mode of a new file
            with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
                handle.write(text)
        for temp, target in temps:
            os.replace(temp, target)
    finally:
        for temp, _ in temps:
            if os.path.exists(temp):
                os.unlink(temp)


def write_campaign(campaign: Campaign, path: str | os.PathLike[str]) -> Path:
    """Write the campaign CSV (A_deg,B_deg,rep,point,dev_um[,t_s]) and its sidecar TOML, atomically.

    rep and point are written 0-based. Numbers are formatted deterministically (dev_um to 1e-5 um,
    t_s to 1e-3 s), so the same campaign always gives byte-identical files. Returns the CSV path.
    """
    path = Path(path)
    if not np.isfinite(campaign.deviations).all():
        raise InputError("the campaign holds non-finite deviations; nothing written", file=str(path))
    csv_text = _format_rows(campaign)
    toml_text = _sidecar_text(campaign)
    _atomic_write([(path, csv_text), (sidecar_path(path), toml_text)])
    return path


# -- inspect --------------------------------------------------------------------------------


def campaign_summary(campaign: Campaign) -> dict[str, Any]:
    """What a campaign holds, as JSON-ready values (the `inspect --json` object)."""
    from ph_explorer.kinematics import campaign_touches, joint_sweep_deg

    a_grid, b_grid = campaign.grid()
    off = campaign.off_grid_mask()
    touches = campaign_touches(campaign)
    unreachable = ~np.broadcast_to(touches.reachable, campaign.deviations.shape)
    unreachable_orientations = (~touches.reachable[:, 0, :]).any(axis=1)
    sweep = joint_sweep_deg(touches)
    sigma = campaign.noise_sigma_um()
    mean_curves = campaign.mean_curves()
    ron = np.ptp(mean_curves, axis=-1)
    return {
        "file": campaign.source,
        "orientations": campaign.n_orientations,
        "repetitions": campaign.n_repetitions,
        "points": campaign.n_points,
        "touches": campaign.n_touches,
        "grid": {"A_deg": [float(v) for v in a_grid], "B_deg": [float(v) for v in b_grid]},
        "grid_orientations": int((~off).sum()),
        "off_grid": [[float(a), float(b)] for a, b in campaign.orientations[off]],
        "check_orientations": None
        if campaign.check_orientations is None
        else [[float(a), float(b)] for a, b in campaign.check_orientations],
        "noise_sigma_um": None if math.isnan(sigma) else sigma,
        "deviation_range_um": [float(campaign.deviations.min()), float(campaign.deviations.max())],
        "mean_curve_ront_um": {"min": float(ron.min()), "median": float(np.median(ron)), "max": float(ron.max())},
        "has_times": campaign.times_s is not None,
        "time_span_s": None
        if campaign.times_s is None
        else [float(campaign.times_s.min()), float(campaign.times_s.max())],
        "geometry": campaign.geometry.as_dict(),
        "cone_half_angle_deg": campaign.geometry.cone_half_angle_deg,
        "joint_sweep_deg": {
            "A_max": float(sweep[:, 0].max()),
            "B_min": float(sweep[:, 1].min()),
            "B_max": float(sweep[:, 1].max()),
        },
        "unreachable_touches": int(unreachable.sum()),
        "unreachable_orientations": [[float(a), float(b)] for a, b in campaign.orientations[unreachable_orientations]],
        "scenario": {k: v for k, v in _plain(campaign.scenario).items() if k in ("name", "description", "seed")}
        if campaign.scenario
        else None,
    }


def _values(v: list[float]) -> str:
    return ", ".join(_number(x) for x in v) if v else "-"


def _pairs(v: list[list[float]] | None) -> str:
    if not v:
        return "none"
    return ", ".join(f"A{_number(a)} B{_number(b)}" for a, b in v)


def summary_text(s: dict[str, Any]) -> str:
    """The human-readable `inspect` report."""
    g = s["geometry"]
    sigma = "n/a (one repetition)" if s["noise_sigma_um"] is None else f"{s['noise_sigma_um']:.4f} um"
    rows = [
        ("file", str(s["file"])),
        ("orientations", f"{s['orientations']} ({s['grid_orientations']} on the lattice, {len(s['off_grid'])} off it)"),
        ("repetitions", str(s["repetitions"])),
        ("points per circle", str(s["points"])),
        ("touches", str(s["touches"])),
        ("lattice A_deg", _values(s["grid"]["A_deg"])),
        ("lattice B_deg", _values(s["grid"]["B_deg"])),
        ("off-grid", _pairs(s["off_grid"])),
        ("check orientations", "from the off-grid rings" if s["check_orientations"] is None else _pairs(s["check_orientations"])),
        ("noise sigma", f"{sigma} per touch (pooled repetition std)"),
        ("deviations", f"{s['deviation_range_um'][0]:.3f} .. {s['deviation_range_um'][1]:.3f} um"),
        (
            "mean-curve RONt",
            f"{s['mean_curve_ront_um']['min']:.3f} / {s['mean_curve_ront_um']['median']:.3f} / "
            f"{s['mean_curve_ront_um']['max']:.3f} um (min / median / max)",
        ),
        ("touch times", "yes" if s["has_times"] else "no (file order is the touch order)"),
        (
            "geometry",
            f"L = {g['pivot_to_ball_mm']:g} mm, ball {g['ball_diameter_mm']:g} mm, bore {g['bore_diameter_mm']:g} mm, "
            f"cone half-angle {s['cone_half_angle_deg']:.2f} deg",
        ),
        (
            "joint sweep per ring",
            f"A up to {s['joint_sweep_deg']['A_max']:.1f} deg, B {s['joint_sweep_deg']['B_min']:.1f} .. "
            f"{s['joint_sweep_deg']['B_max']:.1f} deg",
        ),
        ("unreachable touches", f"{s['unreachable_touches']} (A joint beyond +-{A_LIMIT_DEG:g} deg)"),
    ]
    if s["scenario"]:
        scenario = dict(s["scenario"])
        description = scenario.pop("description", None)
        rows.append(("scenario", ", ".join(f"{k} = {v}" for k, v in scenario.items())))
        if description:
            rows.append(("", str(description)))
    width = max(len(label) for label, _ in rows)
    return "\n".join(f"{label:<{width}}  {value}" for label, value in rows)


def inspect_command(file: Path, json_output: bool = False, geometry: dict[str, Any] | None = None) -> int:
    """`ph-explorer inspect FILE.csv [--json]`: print what the campaign holds."""
    campaign = read_campaign(file, geometry)
    summary = campaign_summary(campaign)
    if json_output:
        print(json.dumps(summary, allow_nan=False))
    else:
        print(summary_text(summary))
    return 0


__all__ = [
    "read_campaign",
    "write_campaign",
    "inspect_command",
    "campaign_summary",
    "sidecar_path",
    "KNOWN_COLUMNS",
    "REQUIRED_COLUMNS",
]
