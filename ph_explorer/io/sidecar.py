"""The sidecar TOML beside a campaign CSV: its path, reading (validated) and writing.

NAME.toml beside NAME.csv is optional. [geometry] sets pivot_to_ball_mm, ball_diameter_mm and
bore_diameter_mm (points_per_circle, when given, must agree with the CSV); [scenario], written by
simulate, records name, description, seed, check_orientations, hidden and effects, and merge adds
`merges` (io.merge). Options given on the command line win over [geometry].
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry

GEOMETRY_KEYS = ("pivot_to_ball_mm", "ball_diameter_mm", "bore_diameter_mm")
TABLES = ("geometry", "scenario")


def sidecar_path(csv_path: str | os.PathLike[str]) -> Path:
    """The sidecar TOML beside a campaign CSV: NAME.csv -> NAME.toml."""
    return Path(csv_path).with_suffix(".toml")


# -- reading ----------------------------------------------------------------------------------------
def read_sidecar(path: Path) -> dict[str, Any]:
    """The parsed sidecar ({} when there is none); InputError naming the TOML file when it is bad."""
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
    unknown = sorted(set(data) - set(TABLES))
    if unknown:
        raise InputError(f"unknown table [{unknown[0]}] (known: [geometry], [scenario])", file=name, column=unknown[0])
    for table in TABLES:
        if table in data and not isinstance(data[table], dict):
            raise InputError(f"{table} must be a table [{table}]", file=name, column=table)
    _check_geometry_table(data.get("geometry", {}), name)
    _check_orientation_pairs(data.get("scenario", {}).get("check_orientations"), name)
    return data


def _check_geometry_table(geometry: dict[str, Any], name: str) -> None:
    for key, value in geometry.items():
        if key not in GEOMETRY_KEYS + ("points_per_circle",):
            raise InputError(f"unknown geometry key {key!r} (known: {', '.join(GEOMETRY_KEYS)})", file=name, column=key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"geometry {key} must be a finite number, got {value!r}", file=name, column=key)


def _check_orientation_pairs(checks: Any, name: str) -> None:
    if checks is None:
        return
    try:
        arr = np.asarray(checks, dtype=float)
        ok = arr.size == 0 or (arr.ndim == 2 and arr.shape[1] == 2 and np.isfinite(arr).all())
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise InputError("check_orientations must be a list of [A, B] pairs", file=name, column="check_orientations")


def sidecar_geometry(sidecar: dict[str, Any], overrides: dict[str, Any] | None, n_points: int, toml_name: str) -> Geometry:
    """The campaign's geometry: the defaults, then the sidecar's [geometry], then the overrides (options)."""
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
            raise InputError(f"unknown geometry option {key!r}", option=key)
        if value is not None:
            values[key] = float(value)
    try:
        return replace(DEFAULT_GEOMETRY, points_per_circle=n_points, **values)
    except ValueError as error:
        source = toml_name if given and not overrides else None
        stated = ", ".join(f"{k} = {v:g}" for k, v in values.items())
        raise InputError(f"impossible geometry ({stated}): {error}", file=source) from None


def sidecar_scenario(sidecar: dict[str, Any]) -> tuple[dict[str, Any], np.ndarray | None]:
    """The sidecar's [scenario] without its check orientations, and those as an (m, 2) array (or None)."""
    scenario = dict(sidecar.get("scenario", {}))
    checks = scenario.pop("check_orientations", None)
    return scenario, (np.asarray(checks, dtype=float).reshape(-1, 2) if checks is not None else None)


# -- writing ----------------------------------------------------------------------------------------
def plain_values(value: Any) -> Any:
    """TOML/JSON-writable Python values: numpy scalars and arrays become numbers and lists; None is dropped."""
    if isinstance(value, dict):
        return {str(k): plain_values(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [plain_values(v) for v in value if v is not None]
    if isinstance(value, np.ndarray):
        return plain_values(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    return value


def sidecar_text(campaign: Campaign) -> str:
    """The sidecar TOML of a campaign: its geometry, and its scenario record and check orientations if any."""
    g = campaign.geometry
    doc: dict[str, Any] = {"geometry": {k: float(getattr(g, k)) for k in GEOMETRY_KEYS}}
    scenario = plain_values(dict(campaign.scenario or {}))
    if campaign.check_orientations is not None:
        scenario["check_orientations"] = [[float(a), float(b)] for a, b in np.asarray(campaign.check_orientations)]
    if scenario:
        doc["scenario"] = scenario
    return tomli_w.dumps(doc)
