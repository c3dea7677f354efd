"""The shapes file: shapes no catalog holds written as tables (x, value, U per component) and read
back as effects (docs/formats.md, "The shapes file"); `diagnose --export-shapes` writes it,
`--effects FILE.toml` reads it.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import tomli_w
from numpy.typing import NDArray

from ph_explorer.effects.error_functions import SHAPE_GROUPS, ErrorFunction, error_function, value_name
from ph_explorer.errors import InputError

SHAPES_FILE_HEADER = '# Shapes no catalog holds, from ph-explorer diagnose --export-shapes (docs/formats.md, "The shapes file").\n'
SHAPE_KEYS = ("id", "group", "variable", "periodic", "x", "component")
COMPONENT_KEYS = ("symbol", "unit", "value", "U")


def shapes_file_text(shapes: Sequence[Mapping[str, Any]]) -> str:
    """The shapes file: one [[shape]] table per shape (id, group, variable, periodic, claimed, x,
    and a [[shape.component]] per component with its symbol, unit, value and U at the knots)."""
    return SHAPES_FILE_HEADER + tomli_w.dumps({"shape": [dict(shape) for shape in shapes]})


def load_shapes(path: str | Path) -> list[type[ErrorFunction]]:
    """The shapes of a shapes file as effects, each at its tabulated values (their defaults): addable
    to a model like any other (--effects FILE.toml, --add ID). A shape with a missing key, an unknown
    group or variable, knots that do not increase, or values that do not match its knots is one
    line (the file, the shape's row, what is wrong), and nothing is loaded."""
    path = Path(path)
    if not path.is_file():
        raise InputError("shapes file not found", file=str(path))
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise InputError(f"not a TOML file: {error}", file=str(path)) from None
    shapes = data.get("shape")
    if not isinstance(shapes, list) or not shapes or not all(isinstance(s, dict) for s in shapes):
        raise InputError("holds no [[shape]] table", file=str(path))
    out: list[type[ErrorFunction]] = []
    for row, shape in enumerate(shapes, start=1):

        def bad(message: str, column: str | None = None, row: int = row) -> InputError:
            return InputError(message, file=str(path), row=row, column=column)

        cls = shape_class(shape, bad)
        if any(other.id == cls.id for other in out):
            raise bad(f"id {cls.id!r} given twice", "id")
        out.append(cls)
    return out


def shape_class(shape: Mapping[str, Any], bad: Callable[..., InputError]) -> type[ErrorFunction]:
    """The effect class of one table of the shapes file (a study's chain holds the same table), at
    its tabulated values; bad(message, key) makes the error line of a table that is not one."""
    missing = [key for key in SHAPE_KEYS if key not in shape]
    if missing:
        raise bad(f"shape without {missing[0]!r}", missing[0])
    group = shape["group"]
    if group not in SHAPE_GROUPS:
        raise bad(f"unknown group {group!r} (known: {', '.join(SHAPE_GROUPS)})", "group")
    spec = SHAPE_GROUPS[group]
    variables = ("time_s", "campaign_fraction") if spec.variable == "time" else (spec.variable,)
    if shape["variable"] not in variables:
        raise bad(f"unknown variable {shape['variable']!r} for group {group} (expected {' or '.join(variables)})", "variable")
    x = _numbers(shape["x"], bad, "x")
    if x.size < 2 or np.any(np.diff(x) <= 0):
        raise bad("x must hold at least two knots, strictly increasing", "x")
    components = shape["component"]
    symbols = [s for s, _ in spec.components]
    if not isinstance(components, list) or [c.get("symbol") if isinstance(c, dict) else None for c in components] != symbols:
        raise bad(f"components must be {', '.join(symbols)}, in that order", "component")
    values: dict[str, float] = {}
    for component in components:
        lacking = [key for key in COMPONENT_KEYS if key not in component]
        if lacking:
            raise bad(f"component {component['symbol']} without {lacking[0]!r}", lacking[0])
        for key in ("value", "U"):
            numbers = _numbers(component[key], bad, key)
            if numbers.size != x.size:
                raise bad(f"component {component['symbol']}: {numbers.size} {key}s for {x.size} knots", key)
        values |= {value_name(component["symbol"], j): float(v) for j, v in enumerate(component["value"])}
    if not isinstance(shape["id"], str) or not shape["id"]:
        raise bad("id must be a name", "id")
    base = error_function(group, tuple(float(v) for v in x), bool(shape["periodic"]))
    parameters = tuple(replace(p, default=values[p.name]) for p in base.parameters)
    needs = frozenset({"touch_times"}) if shape["variable"] == "time_s" else frozenset()
    return type(
        f"Loaded_{base.__name__}", (base,), {"id": shape["id"], "parameters": parameters, "needs": needs, "variable": shape["variable"]}
    )


def _numbers(value: Any, bad: Callable[[str, str | None], InputError], key: str) -> NDArray[np.float64]:
    if not isinstance(value, list) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        raise bad(f"{key} must be a list of numbers", key)
    numbers = np.array(value, dtype=float)
    if not np.all(np.isfinite(numbers)):
        raise bad(f"{key} holds a value that is not finite", key)
    return numbers
