"""The catalog of physical effects of the PH20/TP20 head-touch twin (see effects/base.py).

CATALOG maps each effect id to its class; `make_effect(spec)` builds one from a scenario's
{"id": ..., <parameters>} table; `load_user_effects(path)` adds the Effect subclasses of a
user's own Python file to the catalog.
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ph_explorer.effects.axes import AAxisCyclic, BAxisCyclic, Direction
from ph_explorer.effects.base import Effect, Parameter
from ph_explorer.effects.environment import Drift, RingForm
from ph_explorer.effects.probe import Gravity, Lobing, Noise
from ph_explorer.errors import InputError

BUILTIN: dict[str, type[Effect]] = {
    cls.id: cls for cls in (Noise, Lobing, Gravity, AAxisCyclic, BAxisCyclic, Direction, Drift, RingForm)
}
CATALOG: dict[str, type[Effect]] = dict(BUILTIN)

__all__ = ["BUILTIN", "CATALOG", "Effect", "Parameter", "load_user_effects", "make_effect"]


def make_effect(spec: Mapping[str, Any], source: str | None = None) -> Effect:
    """An effect from {"id": ID, param: value, ...}; keys "hidden" and "note" are ignored here."""
    spec = dict(spec)
    effect_id = spec.pop("id", None)
    spec.pop("hidden", None)
    spec.pop("note", None)
    if effect_id not in CATALOG:
        raise InputError(f"unknown effect {effect_id!r} (known: {', '.join(sorted(CATALOG))})", file=source, column="id")
    try:
        return CATALOG[effect_id](**spec)
    except InputError as error:
        raise InputError(error.message, file=source, column=error.column) from None


def load_user_effects(path: str | Path) -> list[type[Effect]]:
    """Import a user's Python file; every Effect subclass defined there joins CATALOG.

    Returns the classes found. A file that cannot be imported, that defines no effect, or whose
    effect lacks an id or reuses a built-in id raises InputError.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("effects file not found", file=str(path))
    module_name = f"ph_explorer_user_effects_{abs(hash(str(path.resolve())))}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise InputError("not a Python file", file=str(path))
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as error:  # noqa: BLE001 - any failure in user code is an input error
        sys.modules.pop(module_name, None)
        line = getattr(error, "lineno", None)
        raise InputError(f"cannot import: {type(error).__name__}: {error}", file=str(path), row=line) from None
    found = [
        cls
        for _, cls in inspect.getmembers(module, inspect.isclass)
        if issubclass(cls, Effect) and cls.__module__ == module_name and not cls.__name__.startswith("_")
    ]
    if not found:
        raise InputError("defines no subclass of ph_explorer.effects.base.Effect", file=str(path))
    for cls in found:
        if not isinstance(cls.id, str) or not cls.id:
            raise InputError(f"effect class {cls.__name__} has no id", file=str(path))
        if cls.id in BUILTIN:
            raise InputError(f"effect id {cls.id!r} is already a built-in effect", file=str(path))
        if not any(m in vars(c) for c in cls.__mro__ if c is not Effect for m in ("basis", "forward")):
            raise InputError(f"effect {cls.id!r} defines neither basis() nor forward()", file=str(path))
        try:
            cls()
        except InputError as error:
            raise InputError(f"effect {cls.id!r}: {error.message}", file=str(path)) from None
        CATALOG[cls.id] = cls
    return found
