"""The catalog of effects: an object passed to whoever needs one, never a mutated global.

`DEFAULT_CATALOG` holds the built-in effects; `catalog.with_file(path)` returns a new catalog that
also holds the Effect subclasses of a user's Python file. A scenario, a hybrid model or a
diagnosis is given the catalog it may draw from, so what one call loaded never changes another.
"""

from __future__ import annotations

import importlib.util
import inspect
import sys
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any

from ph_explorer.effects.axes import AAxisCyclic, BAxisCyclic, Direction
from ph_explorer.effects.effect import Effect
from ph_explorer.effects.environment import Drift, RingForm
from ph_explorer.effects.error_functions import ErrorFunction
from ph_explorer.effects.location import AAxisPosition, AAxisSquareness, BAxisOrientation, BAxisPosition
from ph_explorer.effects.motions import (
    AAxisAxialMotion,
    AAxisRadialMotion,
    AAxisTiltMotion,
    BAxisAxialMotion,
    BAxisRadialMotion,
    BAxisTiltMotion,
)
from ph_explorer.effects.probe import Gravity, Lobing, Noise
from ph_explorer.effects.shapes_file import load_shapes
from ph_explorer.effects.stylus import BallForm, StylusBending
from ph_explorer.errors import InputError

BUILTIN_EFFECTS: tuple[type[Effect], ...] = (
    Noise,
    Lobing,
    Gravity,
    BallForm,
    StylusBending,
    AAxisCyclic,
    BAxisCyclic,
    Direction,
    Drift,
    RingForm,
    # The rotary axes in the ISO 230-1 vocabulary: location errors, then error motions.
    BAxisPosition,
    BAxisOrientation,
    AAxisPosition,
    AAxisSquareness,
    BAxisRadialMotion,
    BAxisAxialMotion,
    BAxisTiltMotion,
    AAxisRadialMotion,
    AAxisAxialMotion,
    AAxisTiltMotion,
)
# Keys of a scenario's effect table that are not parameters of the effect.
SPEC_KEYS = ("id", "hidden", "note")


class Catalog(Mapping[str, type[Effect]]):
    """Effect classes by id, in the order they were given (built-ins first)."""

    def __init__(self, classes: Iterable[type[Effect]]) -> None:
        self._classes: dict[str, type[Effect]] = {cls.id: cls for cls in classes}

    def __getitem__(self, effect_id: str) -> type[Effect]:
        return self._classes[effect_id]

    def __iter__(self) -> Iterator[str]:
        return iter(self._classes)

    def __len__(self) -> int:
        return len(self._classes)

    def candidates(self) -> dict[str, type[Effect]]:
        """The effects the diagnosis's search tries (every one but pure noise and shapes), id -> class."""
        return {effect_id: cls for effect_id, cls in self._classes.items() if cls.candidate}

    def addable(self) -> dict[str, type[Effect]]:
        """The effects a model can add: the candidates and the shapes of a shapes file, id -> class."""
        return {effect_id: cls for effect_id, cls in self._classes.items() if cls.candidate or issubclass(cls, ErrorFunction)}

    def unknown(self, effect_id: str, source: str | None = None, column: str | None = "id") -> InputError:
        """The one-line error for an id this catalog does not hold."""
        return InputError(f"unknown effect {effect_id!r} (known: {', '.join(sorted(self))})", file=source, column=column)

    def make(self, spec: Mapping[str, Any], source: str | None = None) -> Effect:
        """An effect from {"id": ID, param: value, ...}; the keys "hidden" and "note" are not parameters."""
        effect_id = spec.get("id")
        if effect_id not in self._classes:
            raise self.unknown(str(effect_id), source)
        params = {k: v for k, v in spec.items() if k not in SPEC_KEYS}
        try:
            return self._classes[effect_id](**params)
        except InputError as error:
            raise InputError(error.message, file=source, column=error.column) from None

    def with_file(self, path: str | Path) -> Catalog:
        """This catalog plus the Effect subclasses defined in a user's Python file, or the shapes of a
        shapes file (.toml, diagnose --export-shapes: data, never code)."""
        found: list[type[Effect]] = list(load_shapes(path)) if Path(path).suffix.lower() == ".toml" else load_user_effects(path)
        clash = [cls.id for cls in found if cls.id in self._classes and self._classes[cls.id] is not cls]
        if clash:
            raise InputError(f"effect id {clash[0]!r} is already in the catalog", file=str(path))
        return Catalog([*self._classes.values(), *found])


DEFAULT_CATALOG = Catalog(BUILTIN_EFFECTS)


def load_user_effects(path: str | Path) -> list[type[Effect]]:
    """Import a user's Python file and return the Effect subclasses it defines (nothing is registered).

    A file that cannot be imported, that defines no effect, or whose effect lacks an id, reuses a
    built-in id or defines neither basis() nor forward() raises InputError.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("effects file not found", file=str(path))
    module_name = f"ph_explorer_user_effects_{abs(hash(str(path.resolve())))}"
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise InputError("not a Python file", file=str(path))
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # dataclasses and pickling look their module up here
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
        raise InputError("defines no subclass of ph_explorer.effects.effect.Effect", file=str(path))
    for cls in found:
        if not isinstance(cls.id, str) or not cls.id:
            raise InputError(f"effect class {cls.__name__} has no id", file=str(path))
        if cls.id in DEFAULT_CATALOG:
            raise InputError(f"effect id {cls.id!r} is already a built-in effect", file=str(path))
        if not any(m in vars(c) for c in cls.__mro__ if c is not Effect for m in ("basis", "forward")):
            raise InputError(f"effect {cls.id!r} defines neither basis() nor forward()", file=str(path))
        unknown_scan = [name for name in cls.scan if name not in {p.name for p in cls.parameters}]
        if unknown_scan:
            raise InputError(f"effect {cls.id!r}: scanned {unknown_scan[0]!r} is not one of its parameters", file=str(path))
        try:
            cls()
        except InputError as error:
            raise InputError(f"effect {cls.id!r}: {error.message}", file=str(path)) from None
    return found
