"""Error functions: an error motion, or a probe term, as a tabulated function of one variable of the
touch, for what no catalog holds (docs/methods/shapes.md).

A group is one ISO 230-7 component group of a rotary axis (angular positioning, radial, axial or
tilt motion) as a function of that axis's joint angle, or the probe's pre-travel lobes as a
function of time. Each component of the group has its own f(x), piecewise linear through values at
knots x_0 < ... < x_{K-1} (periodic over a full turn of an angle), multiplied by its lever
(effect.screw_deviation for an axis's components). The basis columns are the knots' hat functions
times the levers and the parameters are the values at the knots, so a shape exported as a table
(x, value, U) and loaded again is the same function (a catalog effect is one harmonic of one
group). Its coefficients are the values in roughness coordinates (`knots.roughness`): a ridge then
also penalises the steps between knots (a P-spline's), weighed by a found curve's own steps.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects.effect import Effect, Evidence, Parameter, full_shape, screw_deviation
from ph_explorer.effects.knots import hat_functions, hat_neighbours, roughness
from ph_explorer.effects.motions import ABOUT_X, ABOUT_Y, ABOUT_Z, X, Y, Z
from ph_explorer.effects.probe import lateral_share
from ph_explorer.errors import InputError
from ph_explorer.kinematics import Touches


@dataclass(frozen=True)
class ShapeVariable:
    """A variable a shape is a function of: its name (the JSON's and the shapes file's), label,
    unit, and its value at every touch (broadcastable to touches.shape)."""

    name: str
    label: str
    unit: str
    values: Callable[[Touches], NDArray[np.float64]]
    angle: bool = False


SHAPE_VARIABLES: dict[str, ShapeVariable] = {
    v.name: v
    for v in (
        ShapeVariable("a_joint_deg", "A joint angle (deg)", "deg", lambda t: t.a_deg, angle=True),
        ShapeVariable("b_joint_deg", "B joint angle (deg)", "deg", lambda t: t.b_deg, angle=True),
        ShapeVariable("time_s", "touch time (s)", "s", lambda t: t.times_s),
        ShapeVariable("campaign_fraction", "place in the campaign's touch order (0 to 1)", "", lambda t: t.place),
    )
}


def _pre_travel_lobes(touches: Touches) -> NDArray[np.float64]:
    """(n_o, 1, n_pt, 4): cos and sin of 2 and 3 psi times the lateral share sin(beta): the lobes
    of a probe's pre-travel in the force azimuth (3: its three kinematic seats; 2: a stylus's
    bending stiffness that differs in two directions), um per um of lobe."""
    psi = np.radians(touches.psi_deg)[..., None]
    k = np.array([2.0, 2.0, 3.0, 3.0])
    trig = np.where(np.arange(4) % 2 == 0, np.cos(k * psi), np.sin(k * psi))
    return trig * lateral_share(touches)[..., None]


@dataclass(frozen=True)
class ShapeGroup:
    """One group of error functions: its variable (for an axis: its joint angle), what it is in
    ISO 230 words, and its components (symbol, unit, lever column)."""

    key: str  # "b_angular": the shape's id is "shape_" + key
    variable: str  # "b_joint_deg" (the time groups: "time", the touch time or the campaign's order)
    axis: str | None  # "A", "B", None (the probe)
    kind: str  # effect.KINDS
    words: str  # "angular positioning of the B axis"
    components: tuple[tuple[str, str], ...]  # (symbol, unit) per component
    plausible: tuple[float, float]  # of each value, in the unit
    lever: Callable[[Touches], NDArray[np.float64]]  # (n_o, 1, n_pt, n_components)

    def variable_of(self, touches: Touches) -> ShapeVariable:
        if self.variable == "time":
            return SHAPE_VARIABLES["time_s" if touches.times_s is not None else "campaign_fraction"]
        return SHAPE_VARIABLES[self.variable]


# Plausible values of an error function: generous bounds of a PH20-class head's residual errors
# after its own mapping, twice the catalog's cyclic ranges (a step or a dent need not be small
# where the mapping never looked): 0-6 arcsec for rotations, 0-3 um for translations and lobes.
ROTATION_PLAUSIBLE_ARCSEC = (0.0, 6.0)
TRANSLATION_PLAUSIBLE_UM = (0.0, 3.0)


def _axis_groups(axis: str) -> list[ShapeGroup]:
    """The four ISO 230-7 component groups of an axis; columns of its screw (motions.X ... ABOUT_Z)."""
    a = axis == "A"
    own, radial, axial, tilt = (ABOUT_X, (Y, Z), X, (ABOUT_Y, ABOUT_Z)) if a else (ABOUT_Z, (X, Y), Z, (ABOUT_X, ABOUT_Y))
    symbols = {X: "EX", Y: "EY", Z: "EZ", ABOUT_X: "EA", ABOUT_Y: "EB", ABOUT_Z: "EC"}

    def lever(columns: tuple[int, ...]) -> Callable[[Touches], NDArray[np.float64]]:
        return lambda touches: screw_deviation(touches, axis)[..., list(columns)]

    def group(name: str, kind: str, columns: tuple[int, ...], unit: str, what: str) -> ShapeGroup:
        plausible = ROTATION_PLAUSIBLE_ARCSEC if unit == "arcsec" else TRANSLATION_PLAUSIBLE_UM
        components = tuple((symbols[c] + axis, unit) for c in columns)
        return ShapeGroup(
            f"{axis.lower()}_{name}",
            f"{axis.lower()}_joint_deg",
            axis,
            kind,
            f"{what} of the {axis} axis",
            components,
            plausible,
            lever(columns),
        )

    return [
        group("angular", "angular_positioning", (own,), "arcsec", "angular positioning"),
        group("radial", "radial_motion", radial, "um", "radial motion"),
        group("axial", "axial_motion", (axial,), "um", "axial motion"),
        group("tilt", "tilt_motion", tilt, "arcsec", "tilt motion"),
    ]


SHAPE_GROUPS: dict[str, ShapeGroup] = {
    g.key: g
    for g in (
        *_axis_groups("A"),
        *_axis_groups("B"),
        ShapeGroup(
            "probe_time",
            "time",
            None,
            "probe",
            "pre-travel lobes of the probe (2 and 3 per turn of the force azimuth) changing over the campaign",
            (("cos2psi", "um"), ("sin2psi", "um"), ("cos3psi", "um"), ("sin3psi", "um")),
            TRANSLATION_PLAUSIBLE_UM,
            _pre_travel_lobes,
        ),
    )
}


class ErrorFunction(Effect):
    """A group's error functions, tabulated at knots (the module docstring); make its class with
    `error_function(group, knots, periodic)`."""

    group: ClassVar[ShapeGroup]
    knots: ClassVar[tuple[float, ...]]
    periodic: ClassVar[bool]
    candidate = False  # in no catalog: the diagnosis's shape step proposes it (diagnosis/shapes.py)

    variable: ClassVar[str | None] = None  # the variable a shapes file named (the time group: time_s or campaign_fraction)

    def table(self, claimed: bool = True, spread: NDArray[np.float64] | None = None) -> dict[str, Any]:
        """This shape as a table of the shapes file (shapes_file_text; a study's chain holds it too):
        its values at its knots, and their U (k = 2; zeros when not given)."""
        values = self.values()
        spread = np.zeros_like(values) if spread is None else np.asarray(spread, dtype=float)
        variable = self.variable or (
            "time_s" if "touch_times" in self.needs else "campaign_fraction" if self.group.variable == "time" else self.group.variable
        )
        return {
            "id": self.id,
            "group": self.group.key,
            "variable": variable,
            "periodic": self.periodic,
            "claimed": claimed,
            "x": list(self.knots),
            "component": [
                {"symbol": symbol, "unit": unit, "value": [float(v) for v in row], "U": [float(u) for u in band]}
                for (symbol, unit), row, band in zip(self.group.components, values, spread)
            ],
        }

    def values(self) -> NDArray[np.float64]:
        """(n_components, K): each component's value at the knots, in its unit."""
        return np.array([self.params[p.name] for p in self.parameters]).reshape(len(self.group.components), len(self.knots))

    def coefficients(self) -> NDArray[np.float64]:
        """The values in roughness coordinates, z = L' v per component (L: the class's, _class_roughness)."""
        return (self.values() @ _class_roughness(type(self))[0]).ravel()

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        """The values at the knots from roughness coordinates: v = L^-T z per component."""
        factor = _class_roughness(type(self))[0]
        z = np.asarray(coef, dtype=float).reshape(len(self.group.components), len(self.knots))
        values = np.linalg.solve(factor.T, z.T).T
        return {p.name: float(v) for p, v in zip(self.parameters, values.ravel())}

    def function(self, x: ArrayLikeFloat) -> NDArray[np.float64]:
        """(..., n_components): the functions at x, in their units."""
        return hat_functions(np.asarray(x, dtype=float), np.array(self.knots), self.periodic) @ self.values().T

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        variable = self.group.variable_of(touches)
        index, weight = hat_neighbours(variable.values(touches), np.array(self.knots), self.periodic)  # (..., 2)
        lever = self.group.lever(touches)  # (n_o, 1, n_pt, C)
        # X L^-T per component: each component's hat columns in roughness coordinates (the rows of
        # L^-T of each touch's two knots: no product with the other K - 2 zeros).
        inverse_t = _class_roughness(type(self))[1]
        rows = weight[..., :1] * inverse_t[index[..., 0]] + weight[..., 1:] * inverse_t[index[..., 1]]  # (..., K)
        columns = lever[..., :, None] * rows[..., None, :]
        columns = columns.reshape(columns.shape[:-2] + (-1,))
        names = [p.name for p in self.parameters]
        if columns.shape[1] == 1:
            return full_shape(columns, touches), names
        return columns, names

    def evidence(self, touches: Touches) -> Evidence:
        variable = self.group.variable_of(touches)
        largest = int(np.argmax(np.abs(self.values()).max(axis=1)))
        symbol, unit = self.group.components[largest]
        return Evidence(
            variable.label,
            np.broadcast_to(variable.values(touches), touches.shape),
            weight=np.broadcast_to(self.group.lever(touches)[..., largest], touches.shape),
            y_label=f"{symbol} ({unit})",
        )

    def dominant_period(self, weight_x: NDArray[np.float64], seen: NDArray[np.float64]) -> float | None:
        """The cycles per revolution of one sinusoid that explains at least half of the curve over the
        angles the rings sample (weight_x) and at least half of what the rings see of it, to 0.1
        cycle (of such, the one whose lesser share is largest); else None. `seen`: the effect's columns
        (rows, c) as the out-of-sample residual sees them. The two readings fail apart: a slow wave
        the interpolator predicts anyway is barely seen, yet may dominate the values (the roughness
        penalty spares it); within a ring's short sweep of a joint, what is seen of a step or a dent
        is a slope that some sinusoid follows."""
        readings = [self._curve_reading(weight_x), self._seen_reading(seen)]
        if readings[0] is None:
            return None
        top = min(180.0, 180.0 / float(np.diff(self.knots).min()))  # to the knots' Nyquist

        def shares(cycles: NDArray[np.float64]) -> NDArray[np.float64]:
            return np.minimum(*(_sinusoid_shares(cycles, *reading) for reading in readings))

        # Every half cycle, then to 0.1 cycle about the three best (a peak is a cycle wide over a turn).
        coarse = np.arange(1.0, top + 1e-9, 0.5)
        near = coarse[np.argsort(shares(coarse))[-3:]]
        fine = np.unique(np.clip(np.round((near[:, None] + np.arange(-0.4, 0.45, 0.1)).ravel(), 1), 1.0, top))
        each = shares(fine)
        best = int(np.argmax(each))
        return float(fine[best]) if each[best] >= 0.5 else None

    def _curve_reading(self, weight_x: NDArray[np.float64]) -> tuple[NDArray[np.float64], None, NDArray[np.float64]] | None:
        """The main curve over the sampled angles (deg), read at the knots and half-way between
        them (the curve is linear between its knots), in the plain metric; None: too few."""
        knots = np.array(self.knots)
        grid = np.sort(np.concatenate([knots, 0.5 * (knots[1:] + knots[:-1])]))
        sampled = np.unique(weight_x)
        at = np.clip(np.searchsorted(sampled, grid), 1, sampled.size - 1)
        nearest = np.minimum(np.abs(grid - sampled[at - 1]), np.abs(grid - sampled[at]))
        x = grid[nearest <= np.diff(knots).max() / 2]  # where touches sample the curve
        if x.size < 8:
            return None
        curve = self.function(x)
        return x, None, curve[:, int(np.argmax((curve**2).sum(axis=0)))]

    def _seen_reading(self, seen: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """The component seen most, at the knots (deg), in the metric of what the rings see of it
        (seen: its columns in roughness coordinates, as basis() gives them)."""
        count = len(self.knots)
        columns = seen.reshape(seen.shape[0], len(self.group.components), count)
        seen_most = (np.einsum("rck,ck->rc", columns, self.coefficients().reshape(-1, count)) ** 2).sum(axis=0)
        main = int(np.argmax(seen_most))
        block = np.ascontiguousarray(columns[:, main])
        factor = _class_roughness(type(self))[0]  # on the values: X L^-T L^T, so its Gram is L (X'X) L^T
        return np.array(self.knots), factor @ (block.T @ block) @ factor.T, self.values()[main]


def _class_roughness(cls: type[ErrorFunction]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(L, L^-T) of a class: knots.roughness of its defaults, kept on the class (it lives as long)."""
    if "_roughness" not in cls.__dict__:
        cls._roughness = roughness(np.array([p.default for p in cls.parameters]).reshape(-1, len(cls.knots)), cls.periodic)  # type: ignore[attr-defined]
    return cls.__dict__["_roughness"]


def _sinusoid_shares(
    cycles: NDArray[np.float64], x_deg: NDArray[np.float64], gram: NDArray[np.float64] | None, values: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(m,): the share of `values` at x_deg (n,) beyond their level that sin and cos of each number
    of cycles per turn explain, by least squares with a constant in the metric `gram` (n, n; None:
    the plain one)."""
    phase = np.radians(x_deg[:, None] * cycles[None, :])
    basis = np.stack([np.sin(phase), np.cos(phase), np.ones_like(phase)], axis=-1)  # (n, m, 3)
    weighted = basis if gram is None else (gram @ basis.reshape(basis.shape[0], -1)).reshape(basis.shape)
    # What nothing sees (a constant the circle fit takes).
    floor = 1e-12 * max(float(len(values) if gram is None else np.trace(gram)), 1e-300)
    normal = np.einsum("kmi,kmj->mij", basis, weighted) + floor * np.eye(3)
    dot = np.einsum("kmi,k->mi", weighted, values)
    explained = np.einsum("mi,mi->m", dot, np.linalg.solve(normal, dot[..., None])[..., 0])
    ones = np.ones(len(values))
    metric_ones = ones if gram is None else gram @ ones  # the metric is symmetric
    level = float((metric_ones @ values) ** 2 / (float(metric_ones @ ones) + floor))
    total = float(values @ (values if gram is None else gram @ values)) - level
    return (explained - level) / total if total > 0 else np.zeros_like(explained)


ArrayLikeFloat = NDArray[np.float64] | float


def value_name(symbol: str, index: int) -> str:
    """The parameter of a component's value at knot `index`: 'ECB_007'."""
    return f"{symbol}_{index:03d}"


@cache
def error_function(group_key: str, knots: tuple[float, ...], periodic: bool) -> type[ErrorFunction]:
    """The ErrorFunction class of a group at these knots (made once per group and knots)."""
    if group_key not in SHAPE_GROUPS:
        raise InputError(f"no shape group {group_key!r} (known: {', '.join(SHAPE_GROUPS)})", column="group")
    group = SHAPE_GROUPS[group_key]
    if len(knots) < 2 or np.any(np.diff(knots) <= 0):
        raise InputError(f"shape {group_key}: the knots must be at least two and strictly increasing", column="x")
    parameters = tuple(
        Parameter(value_name(symbol, j), unit, 0.0, f"{symbol} at {x:g}", plausible=group.plausible)
        for symbol, unit in group.components
        for j, x in enumerate(knots)
    )
    return type(
        f"ErrorFunction_{group_key}",
        (ErrorFunction,),
        {
            "id": f"shape_{group_key}",
            "name": f"{group.words[0].upper()}{group.words[1:]} as a function of {group.variable.replace('_', ' ')}",
            "axis": group.axis,
            "kind": group.kind,
            "symbol": ", ".join(s for s, _ in group.components) if group.axis else "",
            "group": group,
            "knots": tuple(float(k) for k in knots),
            "periodic": bool(periodic),
            "parameters": parameters,
            "teaching": f"An error function no catalog holds: {group.words}, tabulated at {len(knots)} knots (docs/methods/shapes.md).",
        },
    )
