"""A population of heads: healthy random heads drawn from documented distributions.

Every background term a working PH20/TP20 shows (lobing, gravity, ball form, ring form, low-order
cyclic errors of both axes, location errors, lost motion, drift) is drawn within its plausible
range from BACKGROUND, and the touch noise from NOISE (Gaussian or Student-t); the design (the
lattice, repetitions, geometry, touch times) from DESIGNS. The same seed gives the same head.
Method and the distributions: docs/methods/random_heads.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.effects import DEFAULT_CATALOG, Effect
from ph_explorer.errors import InputError
from ph_explorer.twin import Scenario, scenario_from_dict, simulate


def _uniform(rng: np.random.Generator, low: float, high: float) -> float:
    return float(rng.uniform(low, high))


def _signed(rng: np.random.Generator, high: float) -> float:
    return float(rng.uniform(-high, high))


def _low_order_cyclic(effect_id: str) -> Callable[[np.random.Generator], list[dict[str, Any]]]:
    """Two cyclic errors of an axis at distinct low orders k (1-4 cycles/rev), 0.2-2 arcsec divided
    by max(1, k / 2): higher harmonics of a drive or an encoder are smaller (a 4/rev one near
    1 arcsec is more than a 20 deg lattice interpolates: docs/methods/random_heads.md)."""

    def draw(rng: np.random.Generator) -> list[dict[str, Any]]:
        orders = rng.choice([1, 2, 3, 4], size=2, replace=False)
        return [
            {
                "id": effect_id,
                "amplitude_arcsec": _uniform(rng, 0.2, 2.0) / max(1.0, k / 2.0),
                "phase_deg": _uniform(rng, 0, 360),
                "cycles_per_rev": int(k),
            }
            for k in orders
        ]

    return draw


def _probe(rng: np.random.Generator) -> list[dict[str, Any]]:
    seat = _uniform(rng, 0, 120)  # lobing and gravity share the module's seats
    return [
        {"id": "lobing", "amplitude_um": _uniform(rng, 0.10, 0.40), "seat_phase_deg": seat},
        {"id": "gravity", "directional_um": _uniform(rng, 0.0, 0.20), "lobing_um": _uniform(rng, 0.0, 0.20), "seat_phase_deg": seat},
        {"id": "ball_form", "amplitude_um": _uniform(rng, 0.0, 0.10), "phase_deg": _uniform(rng, 0, 360), "lobes": int(rng.integers(2, 6))},
    ]


def _ring_and_environment(rng: np.random.Generator) -> list[dict[str, Any]]:
    return [
        {"id": "ring_form", "form_um": _uniform(rng, 0.05, 0.30), "shape_seed": int(rng.integers(1, 10_000))},
        {"id": "direction", "a_lost_motion_arcsec": _uniform(rng, 0.0, 0.3), "b_lost_motion_arcsec": _uniform(rng, 0.0, 0.3)},
        {"id": "drift", "head_rate_um_per_h": _uniform(rng, 0.0, 1.0), "stylus_rate_um_per_h": _uniform(rng, 0.0, 0.5)},
    ]


def _location(rng: np.random.Generator) -> list[dict[str, Any]]:
    """What the head's own qualification leaves of its axes' location errors."""
    return [
        {"id": "b_axis_position", "x_offset_um": _signed(rng, 0.5), "y_offset_um": _signed(rng, 0.5)},
        {"id": "b_axis_orientation", "about_x_arcsec": _signed(rng, 3.0), "about_y_arcsec": _signed(rng, 3.0)},
        {"id": "a_axis_position", "y_offset_um": _signed(rng, 0.5), "z_offset_um": _signed(rng, 0.5)},
        {"id": "a_axis_squareness", "about_y_arcsec": _signed(rng, 3.0)},
    ]


# The background of a healthy head, drawn in this order (one random stream per seed).
BACKGROUND: tuple[Callable[[np.random.Generator], list[dict[str, Any]]], ...] = (
    _probe,
    _ring_and_environment,
    _low_order_cyclic("a_axis_cyclic"),
    _low_order_cyclic("b_axis_cyclic"),
    _location,
)


def noise_spec(rng: np.random.Generator) -> dict[str, Any]:
    """Touch noise: sigma 0.1-0.3 um; Gaussian or (with probability 1/2) Student-t with 3-5 degrees of freedom."""
    sigma = _uniform(rng, 0.10, 0.30)
    dof = 0 if rng.uniform() < 0.5 else int(rng.integers(3, 6))
    return {"id": "noise", "sigma_um": sigma, "dof": dof}


OFF_GRID = [[43, 90], [22, -130], [37, 150], [52, 10], [67, -70], [83, 110], [28, 50], [58, -150], [76, -10]]

# Designs: the orientations, repetitions, geometry and scan of a campaign ("times": whether its
# CSV holds touch times).
DESIGNS: dict[str, dict[str, Any]] = {
    "paper": {
        "repetitions": 10,
        "orientations": {"a_deg": [0, 90, 15], "b_deg": [-160, 180, 20], "off_grid": OFF_GRID},
        "check_orientations": [[15, -20], [75, 40], [45, -20], *OFF_GRID],
        "times": True,
    },
    "coarse": {
        "repetitions": 5,
        "orientations": {"a_deg": [0, 90, 30], "b_deg": [-150, 180, 30], "off_grid": OFF_GRID[:6]},
        "check_orientations": OFF_GRID[:6],
        "times": True,
    },
    "no_times": {
        "repetitions": 10,
        "orientations": {"a_deg": [0, 90, 15], "b_deg": [-160, 180, 20], "off_grid": OFF_GRID},
        "check_orientations": OFF_GRID,
        "times": False,
    },
    "other_geometry": {
        "repetitions": 8,
        "geometry": {"pivot_to_ball_mm": 100.0, "ball_diameter_mm": 3.0, "bore_diameter_mm": 30.0, "points_per_circle": 48},
        "orientations": {"a_deg": [0, 90, 15], "b_deg": [-160, 180, 20], "off_grid": [[9, 45], [27, -75], [49, 105], [63, -15], [81, 165]]},
        "check_orientations": [[9, 45], [27, -75], [49, 105], [63, -15], [81, 165]],
        "scan": {"touch_s": 1.5, "move_s": 6.0},
        "times": True,
    },
}


def design_of(seed: int, design: str | None = None) -> str:
    """The design's name: the given one, checked, or one drawn from the seed."""
    if design is None:
        return str(np.random.default_rng(np.random.SeedSequence([int(seed), 2])).choice(sorted(DESIGNS)))
    if design not in DESIGNS:
        raise InputError(f"unknown design {design!r} (known: {', '.join(sorted(DESIGNS))})", option="--design")
    return design


def random_head(seed: int, design: str | None = None, hidden: Sequence[Effect] = ()) -> Scenario:
    """A healthy head drawn from seed on the design (None: drawn too, design_of), with the given
    effects added as hidden ones."""
    name = design_of(seed, design)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0]))
    recipe = {key: value for key, value in DESIGNS[name].items() if key != "times"}
    specs = [noise_spec(rng)] + [spec for draw in BACKGROUND for spec in draw(rng)]
    data = {
        "name": f"random_head_{seed}",
        "description": f"A random head (seed {seed}) on the {name} design: what does the diagnosis say of it?",
        "seed": int(rng.integers(0, 2**31 - 1)),
        **recipe,
        "effects": specs,
    }
    scenario = scenario_from_dict(data, default_name=data["name"], catalog=DEFAULT_CATALOG)
    scenario.effects += list(hidden)
    scenario.hidden += [True] * len(hidden)
    return scenario


def random_campaign(seed: int, design: str | None = None, hidden: Sequence[Effect] = (), noise_seed: int | None = None) -> Campaign:
    """The campaign of random_head(seed, design, hidden); without touch times when its design has
    none. noise_seed: another draw of the same head's noise (default: the head's own)."""
    campaign = simulate(random_head(seed, design, hidden), noise_seed)
    if not DESIGNS[design_of(seed, design)]["times"]:
        campaign.times_s = None
    return campaign
