"""The digital twin: scenarios (TOML) and the simulation of whole campaigns from the effect catalog.

A scenario names the orientations (a grid plus off-grid rings), the repetitions, the seed, the scan
(order, direction, cadence), the check orientations held out of training, and the physical effects
with their parameters; an effect marked `hidden = true` is in the data but not in the model a user
starts with. `simulate` computes every touch's kinematics in scan order, adds the effects' forward
models and applies each repetition's least-squares circle fit, all vectorised over the touches.

Method, and the scenario TOML: docs/methods/digital_twin.md.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign, orientation_match
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect, EffectSum
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import touch_kinematics
from ph_explorer.paths import scenarios_dir

SCAN_ORDERS = ("orientation", "repetition")
SCAN_DIRECTIONS = ("forward", "alternating")
TOP_KEYS = {"name", "purpose", "description", "seed", "repetitions", "check_orientations", "geometry", "orientations", "scan", "effects"}


@dataclass
class Scenario:
    """A simulated campaign's recipe (the TOML: docs/methods/digital_twin.md)."""

    name: str
    description: str
    orientations: NDArray[np.float64]  # (n_o, 2) grid then off-grid, in scan order
    effects: list[Effect]
    hidden: list[bool]  # per effect: in the data, not in the starting model
    check_orientations: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    seed: int = 0
    repetitions: int = 10
    geometry: Geometry = DEFAULT_GEOMETRY
    scan_order: str = "orientation"
    scan_direction: str = "forward"
    touch_s: float = 2.0
    move_s: float = 8.0
    source: str | None = None
    start_s: float = 0.0  # the first touch's time: later than 0 for rings measured after the campaign (at_rings)
    purpose: str = ""  # what it is for, in a few words that give nothing hidden away (the explorer's list)

    @property
    def hidden_ids(self) -> list[str]:
        return list(dict.fromkeys(e.id for e, h in zip(self.effects, self.hidden) if h))

    @property
    def starting_effects(self) -> list[Effect]:
        """The effects a user's model starts with (every effect not hidden)."""
        return [e for e, h in zip(self.effects, self.hidden) if not h]

    def times_s(self) -> NDArray[np.float64]:
        """Touch times (n_o, n_rep, n_pt) in s from the scan order, direction and cadence."""
        n_o, n_rep, n_pt = len(self.orientations), self.repetitions, self.geometry.points_per_circle
        o, r, k = np.indices((n_o, n_rep, n_pt))
        circle = o * n_rep + r if self.scan_order == "orientation" else r * n_o + o
        reverse = (r % 2 == 1) if self.scan_direction == "alternating" else np.zeros_like(r, dtype=bool)
        position = np.where(reverse, n_pt - 1 - k, k)
        return self.start_s + circle * (n_pt * self.touch_s + self.move_s) + position * self.touch_s

    def at_rings(self, rings: NDArray[np.float64]) -> Scenario:
        """The same head measured again at other rings after its campaign (the rings that would
        decide, design --decide): every one a check ring, its touches after the campaign's last,
        its seed drawn from the campaign's and the rings (another draw of the touch noise)."""
        rings = np.asarray(rings, dtype=float).reshape(-1, 2)
        after = self.start_s + float(self.times_s().max()) + self.touch_s + self.move_s
        millidegrees = np.round(rings * 1000).astype(np.int64).ravel() % 2**32
        seed = int(np.random.SeedSequence([self.seed, *millidegrees]).generate_state(1)[0] % 2**31)
        return replace(self, orientations=rings, check_orientations=rings.copy(), start_s=after, seed=seed)

    def record(self, seed: int) -> dict[str, Any]:
        """What a campaign's sidecar records about the scenario."""
        return {
            "name": self.name,
            "description": self.description,
            "seed": int(seed),
            "repetitions": self.repetitions,
            "scan_order": self.scan_order,
            "scan_direction": self.scan_direction,
            "touch_s": self.touch_s,
            "move_s": self.move_s,
            "hidden": self.hidden_ids,
            **({"start_s": self.start_s} if self.start_s else {}),
            "effects": [{**e.describe(), "hidden": h} for e, h in zip(self.effects, self.hidden)],
        }


# -- reading scenarios -----------------------------------------------------------------------------
def _axis(values: Any, key: str, source: str) -> NDArray[np.float64]:
    """[start, stop, step] (stop inclusive) or an explicit list of more than three values."""
    if not isinstance(values, list) or not values or not all(isinstance(v, (int, float)) for v in values):
        raise InputError(f"orientations.{key} must be [start, stop, step] or a list of angles", file=source, column=key)
    if len(values) == 3 and values[2] > 0 and values[1] >= values[0]:
        start, stop, step = (float(v) for v in values)
        return np.arange(start, stop + 0.5 * step, step)
    return np.asarray(values, dtype=float)


def _pairs(values: Any, key: str, source: str) -> NDArray[np.float64]:
    if values is None:
        return np.zeros((0, 2))
    try:
        arr = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        arr = np.zeros((1, 3))
    if arr.size == 0:
        return np.zeros((0, 2))
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InputError(f"{key} must be a list of [A, B] pairs in degrees", file=source, column=key)
    return arr


def scenario_from_dict(
    data: dict[str, Any],
    source: str | None = None,
    default_name: str = "scenario",
    catalog: Catalog = DEFAULT_CATALOG,
) -> Scenario:
    """A Scenario from the parsed TOML (docs/methods/digital_twin.md); its effects come from catalog."""
    unknown = sorted(set(data) - TOP_KEYS)
    if unknown:
        raise InputError(f"unknown key {unknown[0]!r} in the scenario", file=source, column=unknown[0])
    try:
        geometry = Geometry(**data.get("geometry", {}))
    except (TypeError, ValueError) as error:
        raise InputError(f"[geometry]: {error}", file=source, column="geometry") from None

    table = data.get("orientations", {})
    grid = np.zeros((0, 2))
    if "a_deg" in table or "b_deg" in table:
        a = _axis(table.get("a_deg"), "a_deg", source)
        b = _axis(table.get("b_deg"), "b_deg", source)
        grid = np.stack(np.meshgrid(a, b, indexing="ij"), axis=-1).reshape(-1, 2)
    off_grid = _pairs(table.get("off_grid"), "orientations.off_grid", source)
    orientations = np.concatenate([grid, off_grid])
    if len(orientations) == 0:
        raise InputError("the scenario has no orientations", file=source, column="orientations")
    if orientation_match(orientations, orientations).sum() != len(orientations):
        raise InputError("an orientation is listed twice", file=source, column="orientations")

    checks = _pairs(data.get("check_orientations"), "check_orientations", source)
    missing = ~orientation_match(checks, orientations).any(axis=1)
    if missing.any():
        a, b = checks[missing][0]
        raise InputError(f"check orientation A{a:g} B{b:g} is not measured in the scenario", file=source, column="check_orientations")

    scan = data.get("scan", {})
    order, direction = scan.get("order", "orientation"), scan.get("direction", "forward")
    if order not in SCAN_ORDERS:
        raise InputError(f"scan.order must be one of {SCAN_ORDERS}", file=source, column="scan.order")
    if direction not in SCAN_DIRECTIONS:
        raise InputError(f"scan.direction must be one of {SCAN_DIRECTIONS}", file=source, column="scan.direction")

    specs = data.get("effects", [])
    if not isinstance(specs, list) or not all(isinstance(s, dict) for s in specs):
        raise InputError("effects must be an array of tables [[effects]]", file=source, column="effects")
    effects = [catalog.make(s, source) for s in specs]
    hidden = [bool(s.get("hidden", False)) for s in specs]

    repetitions = data.get("repetitions", 10)
    if not isinstance(repetitions, int) or repetitions < 1:
        raise InputError("repetitions must be a positive integer", file=source, column="repetitions")
    return Scenario(
        name=str(data.get("name", default_name)),
        description=" ".join(str(data.get("description", "")).split()),
        purpose=" ".join(str(data.get("purpose", "")).split()),
        orientations=orientations,
        effects=effects,
        hidden=hidden,
        check_orientations=checks,
        seed=int(data.get("seed", 0)),
        repetitions=repetitions,
        geometry=geometry,
        scan_order=order,
        scan_direction=direction,
        touch_s=float(scan.get("touch_s", 2.0)),
        move_s=float(scan.get("move_s", 8.0)),
        source=source,
    )


def shipped_scenario_paths() -> list[Path]:
    return sorted(scenarios_dir().glob("*.toml"))


def load_scenario(name_or_path: str | Path, catalog: Catalog = DEFAULT_CATALOG) -> Scenario:
    """A shipped scenario by name (e.g. "paper"), or a scenario TOML by path; its effects come from catalog."""
    text = str(name_or_path)
    path = Path(text)
    if not (path.suffix == ".toml" or path.is_file()):
        path = scenarios_dir() / f"{text}.toml"
        if not path.is_file():
            names = ", ".join(p.stem for p in shipped_scenario_paths())
            raise InputError(f"unknown scenario {text!r} (shipped: {names}; or give a .toml path)")
    if not path.is_file():
        raise InputError("scenario file not found", file=text)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
        raise InputError(f"not a valid TOML file: {error}", file=str(path)) from None
    return scenario_from_dict(data, source=str(path), default_name=path.stem, catalog=catalog)


def list_scenarios() -> list[Scenario]:
    """Every shipped scenario, by name (its purpose and description: what a list shows of it)."""
    return [load_scenario(p) for p in shipped_scenario_paths()]


def twin_scenario(campaign: Campaign, catalog: Catalog = DEFAULT_CATALOG) -> Scenario | None:
    """The head a simulated campaign came from, at its seed, so that its twin can measure more rings
    of it: the shipped scenario of that name, else the head its sidecar records (every effect with
    its parameters: a random head, a scenario of one's own). None for measured data, or an effect
    the catalog does not know."""
    record = campaign.scenario or {}
    name, specs = record.get("name"), record.get("effects")
    if "seed" not in record or not name:
        return None
    if name in {s.name for s in list_scenarios()}:
        return replace(load_scenario(name), seed=int(record["seed"]))
    if not specs or any(spec.get("id") not in catalog for spec in specs):
        return None
    try:
        effects = [catalog[spec["id"]](**{k: v for k, v in spec.items() if k not in ("id", "hidden")}) for spec in specs]
    except (TypeError, ValueError):
        return None  # a sidecar written by hand, whose parameters are not the effect's
    return Scenario(
        name=str(name),
        description=str(record.get("description", "")),
        orientations=campaign.orientations.copy(),
        effects=effects,
        hidden=[bool(spec.get("hidden", False)) for spec in specs],
        check_orientations=campaign.orientations[campaign.holdout_mask()],
        seed=int(record["seed"]),
        repetitions=campaign.n_repetitions,
        geometry=campaign.geometry,
        scan_order=str(record.get("scan_order", "orientation")),
        scan_direction=str(record.get("scan_direction", "forward")),
        touch_s=float(record.get("touch_s", 2.0)),
        move_s=float(record.get("move_s", 8.0)),
        start_s=float(record.get("start_s", 0.0)),
    )


# -- simulation ------------------------------------------------------------------------------------
def simulate(scenario: Scenario, seed: int | None = None) -> Campaign:
    """Simulate the scenario's campaign; the same scenario and seed give the same campaign."""
    seed = scenario.seed if seed is None else int(seed)
    rng = np.random.default_rng(seed)
    times = scenario.times_s()
    touches = touch_kinematics(scenario.orientations, scenario.geometry, scenario.repetitions, times)
    radial = EffectSum(scenario.effects).forward(touches, rng)  # drawn in order: one random stream
    return Campaign(
        orientations=scenario.orientations.copy(),
        deviations=remove_size_and_centre(radial),
        times_s=times,
        geometry=scenario.geometry,
        check_orientations=scenario.check_orientations.copy(),
        scenario=scenario.record(seed),
        source=scenario.source,
    )
