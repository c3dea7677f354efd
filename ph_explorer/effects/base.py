"""The interface of a physical effect, and the lever arms every effect shares.

An effect is one physical mechanism of the head, the probe or the ring that moves the recorded
points. It gives, for every touch of a campaign (a `ph_explorer.kinematics.Touches`):

- `forward(touches, rng)`: the radial deviation of each touch in um, *before* the least-squares
  circle fit (the twin applies the fit afterwards), shaped (n_orientations, n_repetitions, n_points);
- `basis(touches, **structural)`: the same contribution written as columns whose coefficients are
  the effect's parameters (or a linearisation of them), shaped (n_o, n_rep, n_pt, n_cols) in um per
  unit coefficient, with the column names;
- `from_coefficients(coef, **structural)`: the physical parameters (units of `parameters`) that a
  fit of the basis columns found;
- `coefficients(**structural)`: the coefficients of its own parameters, so that for a linear effect
  `forward == basis @ coefficients` (the tests check this).

Sign convention: a touch reads the wall at R + p - d . u_k, where p is the pre-travel of the probe
(the head keeps moving outward after contact) and d the displacement of the real ball centre from
where the head's kinematic model puts it (u_k: outward radial direction of point k). Deviations
are positive outward.

Writing your own effect
-----------------------
Put a subclass of `Effect` in any Python file and pass the file to the tools (for example
`ph-explorer diagnose --effects my_effects.py`, or `ph_explorer.effects.load_user_effects(path)`);
every Effect subclass defined in that file joins the catalog under its `id`. Minimal example
(see assets/effects_example.py for a complete one)::

    import numpy as np
    from ph_explorer.effects.base import Effect, Parameter

    class StylusBending(Effect):
        id = "stylus_bending"
        name = "Stylus bending under the probing force"
        teaching = "The stylus bends by the trigger force; it adds pre-travel along the force ..."
        parameters = (Parameter("amplitude_um", "um", 0.1, "extra pre-travel at full lateral share"),)
        structural = {}

        def basis(self, touches, **structural):
            lateral = np.sin(np.radians(touches.beta_deg))            # (n_o, 1, n_pt)
            column = np.broadcast_to(lateral, touches.shape)[..., None]  # (n_o, n_rep, n_pt, 1)
            return column, ["amplitude_um"]

Rules: every array is shaped like the touches (broadcast the repetition axis of length 1 when the
effect does not change between repetitions); units are um for deviations; `forward` defaults to
`basis @ coefficients` for a linear effect whose parameters are its coefficients (as above), so a
linear effect only needs `basis`; a non-linear or random one overrides `forward`. Free non-linear
parameters a diagnosis should scan go in `structural` as {name: tuple of values}, and `basis`
accepts them as keyword arguments.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ph_explorer.errors import InputError
from ph_explorer.geometry import ARCSEC_PER_DEG, ball_centres, radial_directions, rot_z
from ph_explorer.kinematics import Touches

# Radians per second of arc, and um per mm.
RAD_PER_ARCSEC = np.pi / (180.0 * ARCSEC_PER_DEG)
UM_PER_MM = 1000.0


@dataclass(frozen=True)
class Parameter:
    """A physical parameter of an effect, with its unit and default value."""

    name: str
    unit: str
    default: float
    description: str


class Effect:
    """One physical mechanism: forward model, linear basis and parameters (see module docstring)."""

    id: ClassVar[str] = ""
    name: ClassVar[str] = ""
    teaching: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    structural: ClassVar[dict[str, tuple]] = {}

    def __init__(self, **params: float) -> None:
        known = {p.name: p for p in self.parameters}
        unknown = sorted(set(params) - set(known))
        if unknown:
            raise InputError(
                f"effect {self.id!r} has no parameter {unknown[0]!r} (known: {', '.join(known) or 'none'})",
                column=unknown[0],
            )
        values: dict[str, float] = {}
        for p in self.parameters:
            value = params.get(p.name, p.default)
            try:
                values[p.name] = float(value)
            except (TypeError, ValueError):
                raise InputError(f"effect {self.id!r}: parameter {p.name!r} must be a number, got {value!r}", column=p.name)
            if not np.isfinite(values[p.name]):
                raise InputError(f"effect {self.id!r}: parameter {p.name!r} must be finite", column=p.name)
        self.params = values

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        return f"{type(self).__name__}({inner})"

    # -- structural (non-linear) parameters --------------------------------------------------------
    def structural_values(self, **overrides: Any) -> dict[str, Any]:
        """This effect's structural parameters (from its params), with any overrides."""
        out = {k: self.params[k] for k in self.structural if k in self.params}
        out.update(overrides)
        return out

    # -- the model -------------------------------------------------------------------------------
    def forward(self, touches: Touches, rng: np.random.Generator) -> NDArray[np.float64]:
        """Radial deviation of every touch before the circle fit, (n_o, n_rep, n_pt) um."""
        columns, _ = self.basis(touches, **self.structural_values())
        return np.broadcast_to(columns @ self.coefficients(), touches.shape).copy()

    def basis(self, touches: Touches, **structural: Any) -> tuple[NDArray[np.float64], list[str]]:
        """Columns (n_o, n_rep, n_pt, n_cols) in um per unit coefficient, and their names."""
        raise NotImplementedError

    def coefficients(self, **structural: Any) -> NDArray[np.float64]:
        """The basis coefficients of this effect's own parameters (default: the parameters in order)."""
        return np.array([self.params[p.name] for p in self.parameters if p.name not in self.structural])

    def from_coefficients(self, coef: NDArray[np.float64], **structural: Any) -> dict[str, float]:
        """Physical parameters from fitted basis coefficients (default: coefficients are parameters)."""
        names = [p.name for p in self.parameters if p.name not in self.structural]
        out = {n: float(c) for n, c in zip(names, np.asarray(coef, dtype=float))}
        out.update({k: float(v) for k, v in structural.items()})
        return out

    def describe(self) -> dict[str, Any]:
        """A plain description (id and parameters) for sidecars and reports."""
        return {"id": self.id, **self.params}


# -- shared kinematics of the tip ------------------------------------------------------------------
def radial_unit(touches: Touches) -> NDArray[np.float64]:
    """u_k, outward radial direction of every point, (n_o, 1, n_pt, 3)."""
    return radial_directions(touches.orientations, touches.geometry.points_per_circle)[:, None]


def ball_centre_mm(touches: Touches) -> NDArray[np.float64]:
    """c_k, ball centre of every touch relative to the pivot, mm, (n_o, 1, n_pt, 3)."""
    return ball_centres(touches.orientations, touches.geometry)[:, None]


def rotation_deviation_um_per_arcsec(touches: Touches, axis: str) -> NDArray[np.float64]:
    """Deviation (um) of each touch per arcsec of rotation error of a head axis, (n_o, 1, n_pt).

    A small rotation eps about a unit axis n through the pivot moves the ball by eps (n x c_k); the
    touch reads -eps (n x c_k) . u_k. B turns about machine z, so its lever is the ball's distance
    from z (~ L sin A); A turns about the head's x axis Rz(B_k) x, a lever of the full L.
    """
    c = ball_centre_mm(touches)
    if axis == "B":
        n = np.broadcast_to(np.array([0.0, 0.0, 1.0]), c.shape)
    elif axis == "A":
        n = rot_z(touches.b_deg)[..., :, 0]  # (n_o, 1, n_pt, 3): Rz(B_k) x
    else:
        raise ValueError("axis must be 'A' or 'B'")
    moved = np.cross(n, c)
    return -np.einsum("...i,...i->...", moved, radial_unit(touches)) * RAD_PER_ARCSEC * UM_PER_MM


def joint_angle_deg(touches: Touches, axis: str) -> NDArray[np.float64]:
    """Actual joint angle of A or B at every touch, (n_o, 1, n_pt) deg."""
    if axis == "A":
        return touches.a_deg
    if axis == "B":
        return touches.b_deg
    raise ValueError("axis must be 'A' or 'B'")


def full_shape(array: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
    """Broadcast an (n_o, 1, n_pt[, k]) array over the repetitions, as a new contiguous array."""
    target = touches.shape + array.shape[3:]
    return np.ascontiguousarray(np.broadcast_to(array, target))
