"""The interface of a physical effect, and the lever arms every effect shares.

An effect is one physical mechanism of the head, the probe or the ring that moves the recorded
points: `forward(touches, rng)` is its radial deviation per touch before the circle fit (um),
`basis(touches)` the same as columns, `coefficients()` / `from_coefficients` the map between those
columns' coefficients and its `parameters` (each may declare a plausible range and a period);
`scan`, `needs`, `candidate` and `evidence` describe it. Deviations are positive outward: a touch
reads R + p - d . u_k. A user's own effect is an `Effect` subclass in any Python file.

Method: docs/methods/effects.md.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator, Mapping, Sequence
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


# Where an effect sits, and the kinds of error (ISO 230-1 for a rotary axis's location errors and
# error motions; the rest for the probe, the ring and the environment).
AXES = ("A", "B", "probe", "ring", "environment")
KINDS = (
    "location",
    "angular_positioning",
    "radial_motion",
    "axial_motion",
    "tilt_motion",
    "lost_motion",
    "probe",
    "thermal",
    "form",
    "noise",
)


@dataclass(frozen=True)
class Parameter:
    """A physical parameter of an effect, with its unit and default value.

    plausible: (low, high), the range of the parameter's magnitude |value| for a PH20/TP20-class
    head (None: no bound, e.g. phases, seeds, scanned periods); a fit outside it is implausible.
    period: the value repeats with this period (360.0 for a phase in degrees): differences, and so
    uncertainties, wrap around it (None: not periodic).
    """

    name: str
    unit: str
    default: float
    description: str
    plausible: tuple[float, float] | None = None
    period: float | None = None

    def __post_init__(self) -> None:
        if self.plausible is not None:
            low, high = (float(v) for v in self.plausible)
            if not (0.0 <= low <= high and np.isfinite(high)):
                raise ValueError(f"parameter {self.name!r}: plausible must be (low, high) with 0 <= low <= high, got {self.plausible!r}")
            object.__setattr__(self, "plausible", (low, high))
        if self.period is not None:
            period = float(self.period)
            if not (np.isfinite(period) and period > 0.0):
                raise ValueError(f"parameter {self.name!r}: period must be positive, got {self.period!r}")
            object.__setattr__(self, "period", period)

    def admits(self, value: float) -> bool:
        """Whether |value| lies in the plausible range (always, when there is none); NaN never does."""
        if self.plausible is None:
            return True
        low, high = self.plausible
        return bool(low <= abs(float(value)) <= high)

    def range_text(self) -> str:
        """'0-3 arcsec': the plausible range of the magnitude, with the unit ('' when there is none)."""
        if self.plausible is None:
            return ""
        low, high = self.plausible
        return f"{low:g}-{high:g}" + (f" {self.unit}" if self.unit else "")


class Effect:
    """One physical mechanism: forward model, linear basis and parameters (docs/methods/effects.md).

    An effect describes itself, so that the twin, the diagnosis and the app never name one:
    `scan` is the grid of its non-linear parameters a diagnosis tries (their chosen values are
    the instance's `settings()`), `needs` what a campaign must hold for it to be tested, `candidate`
    whether a model can add it at all, and `evidence` the variable its signature is read against.
    Each of its `parameters` may declare the plausible range of its magnitude
    (`Parameter(..., plausible=(0.0, 3.0))`) and a period (`period=360.0` for a phase);
    `implausible(params)` names the fitted values outside their ranges.
    """

    id: ClassVar[str] = ""
    name: ClassVar[str] = ""
    teaching: ClassVar[str] = ""
    parameters: ClassVar[tuple[Parameter, ...]] = ()
    # Grid of the non-linear parameters a diagnosis scans, {parameter name: values}; each is also a
    # Parameter, and the instance's value of it is the chosen one (settings()).
    scan: ClassVar[dict[str, tuple]] = {}
    # What a campaign must hold (keys of NEEDS) for this effect to be fitted or tested.
    needs: ClassVar[frozenset[str]] = frozenset()
    # False for what no model can add (pure noise): never a candidate of the diagnosis.
    candidate: ClassVar[bool] = True
    # Where the mechanism sits (one of AXES, None for one spanning both joints) and what kind of
    # error it is (one of KINDS), in the vocabulary of ISO 230-1 for the axes; symbol: its ISO 230-1
    # style symbol adapted to the head's axes (docs/twin.md, "Symbols"), "" when ISO 230 names none.
    axis: ClassVar[str | None] = None
    kind: ClassVar[str] = "probe"
    symbol: ClassVar[str] = ""

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
                raise InputError(f"effect {self.id!r}: parameter {p.name!r} must be a number, got {value!r}", column=p.name) from None
            if not np.isfinite(values[p.name]):
                raise InputError(f"effect {self.id!r}: parameter {p.name!r} must be finite", column=p.name)
        self.params = values

    def __repr__(self) -> str:
        inner = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        return f"{type(self).__name__}({inner})"

    def __add__(self, other: Effect | EffectSum) -> EffectSum:
        return EffectSum([self]) + other

    # -- the scanned (non-linear) parameters -------------------------------------------------------
    @classmethod
    def scan_grid(cls) -> list[dict[str, float]]:
        """Every combination of the scanned values, [{name: value, ...}, ...] ([{}] when nothing is scanned)."""
        names = list(cls.scan)
        return [dict(zip(names, values)) for values in itertools.product(*(cls.scan[n] for n in names))]

    def neighbour_settings(self) -> list[dict[str, float]]:
        """Its settings and those one scan step away in each scanned parameter: where a fit of the
        same data may move when rings are added (an n/rev error seen through a lever that turns
        once a revolution reads as n - 1 and n + 1)."""
        near = []
        for name in self.scan:
            values = list(self.scan[name])
            value = self.params[name]
            i = min(range(len(values)), key=lambda k: abs(values[k] - value))
            near.append([value] + [values[k] for k in (i - 1, i + 1) if 0 <= k < len(values) and values[k] != value])
        return [dict(zip(self.scan, combo)) for combo in itertools.product(*near)]

    def settings(self) -> dict[str, float]:
        """The values of the scanned parameters this instance uses (e.g. {"cycles_per_rev": 22})."""
        return {k: self.params[k] for k in self.scan}

    def with_settings(self, **settings: float) -> Effect:
        """A copy of this effect with other values of its scanned parameters."""
        return type(self)(**{**self.params, **settings})

    def unmet_needs(self, touches: Touches) -> list[str]:
        """What the touches lack for this effect (texts from NEEDS); empty when it can be fitted."""
        return [text for need, (text, met) in NEEDS.items() if need in self.needs and not met(touches)]

    # -- the model -------------------------------------------------------------------------------
    def forward(self, touches: Touches, rng: np.random.Generator) -> NDArray[np.float64]:
        """Radial deviation of every touch before the circle fit, (n_o, n_rep, n_pt) um."""
        columns, _ = self.basis(touches)
        return np.broadcast_to(columns @ self.coefficients(), touches.shape).copy()

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        """Columns (n_o, n_rep, n_pt, n_cols) in um per unit coefficient at this instance's settings, and their names."""
        raise NotImplementedError

    def scan_library(self, touches: Touches) -> tuple[NDArray[np.float64], list[NDArray[np.intp]]] | None:
        """Every scan_grid() setting's basis columns at once, when settings share columns (a drift's
        ramp is the same at every time constant): the distinct columns (n_o, n_rep, n_pt, L) and each
        setting's indices into them, in basis() order. None (the default): each setting on its own.
        A scan then makes each distinct column once (docs/diagnosis.md)."""
        return None

    def coefficients(self) -> NDArray[np.float64]:
        """The basis coefficients of this effect's own parameters (default: the unscanned parameters in order)."""
        return np.array([self.params[p.name] for p in self.parameters if p.name not in self.scan])

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        """Physical parameters from fitted basis coefficients (default: coefficients are parameters)."""
        names = [p.name for p in self.parameters if p.name not in self.scan]
        out = {n: float(c) for n, c in zip(names, np.asarray(coef, dtype=float))}
        out.update(self.settings())
        return out

    def evidence(self, touches: Touches) -> Evidence:
        """The variable this effect's signature is read against (default: the point angle theta)."""
        return Evidence("point angle theta (deg)", np.broadcast_to(touches.theta_deg, touches.a_deg.shape))

    def describe(self) -> dict[str, Any]:
        """A plain description (id and parameters) for sidecars and reports."""
        return {"id": self.id, **self.params}

    @classmethod
    def parameters_text(cls, params: Mapping[str, float], uncertainties: Mapping[str, float] | None = None) -> str:
        """'amplitude 0.953 arcsec, phase 30.8 deg, 22 cycles/rev': fitted parameters with their units,
        each with '+- U' where an uncertainty is given and not zero (scanned settings have none)."""
        units = {p.name: p.unit for p in cls.parameters}
        u = uncertainties or {}
        return ", ".join(parameter_text(k, float(v), units.get(k, ""), u.get(k)) for k, v in params.items())

    @classmethod
    def amplitudes(cls) -> list[str]:
        """The parameters that state the effect's size: those with a plausible range, not scanned."""
        return [p.name for p in cls.parameters if p.plausible is not None and p.name not in cls.scan]

    @classmethod
    def implausible(cls, params: Mapping[str, float]) -> list[str]:
        """One line per parameter whose magnitude lies outside its plausible range, e.g.
        ['amplitude 15 arcsec, plausible 0-3 arcsec']; [] when every value is plausible.

        Names that are not parameters of the effect (derived outputs of from_coefficients, such
        as lobing's ratio_6_to_3) and parameters without a range are not judged. A negative value
        is judged by its magnitude, and the line says so.
        """
        declared = {p.name: p for p in cls.parameters}
        out = []
        for name, value in params.items():
            parameter = declared.get(name)
            if parameter is None or parameter.admits(value):
                continue
            what = "plausible magnitude" if float(value) < 0 else "plausible"
            out.append(f"{parameter_text(name, float(value), parameter.unit)}, {what} {parameter.range_text()}")
        return out


class EffectSum:
    """Effects added together (as lmfit composes models): forwards add, bases stand side by side."""

    def __init__(self, effects: Sequence[Effect] = ()) -> None:
        self.effects = list(effects)

    def __add__(self, other: Effect | EffectSum) -> EffectSum:
        more = other.effects if isinstance(other, EffectSum) else [other]
        return EffectSum(self.effects + list(more))

    def __iter__(self) -> Iterator[Effect]:
        return iter(self.effects)

    def __len__(self) -> int:
        return len(self.effects)

    def forward(self, touches: Touches, rng: np.random.Generator) -> NDArray[np.float64]:
        """The sum of every effect's radial deviation, drawn in order (the same rng stream as one by one)."""
        radial = np.zeros(touches.shape)
        for effect in self.effects:
            radial += effect.forward(touches, rng)
        return radial


def parameter_text(name: str, value: float, unit: str, uncertainty: float | None = None) -> str:
    """'amplitude_arcsec', 0.95, 'arcsec' -> 'amplitude 0.95 arcsec' ('amplitude 0.95 +- 0.06 arcsec'
    with an uncertainty); 'cycles_per_rev', 22, 'cycles/rev' -> '22 cycles/rev'."""
    written = unit.replace("/", "_per_")  # units are spelled with _per_ in parameter names ('um/h' -> 'um_per_h')
    label = name[: -len(written)].rstrip("_") if unit and name.endswith(written) else name
    spread = f" +- {uncertainty:.2g}" if uncertainty and np.isfinite(uncertainty) else ""
    number = f"{value:.3g}{spread}" + (f" {unit}" if unit else "")
    return f"{label.replace('_', ' ')} {number}" if label else number


@dataclass(frozen=True)
class Evidence:
    """How an effect's signature is read: its variable at every touch, and how to bin it.

    weight: None when the plotted quantity is the radial residual itself (um); otherwise each
    touch's deviation per unit of the plotted quantity (e.g. um per arcsec of an axis error), so
    that a bin's value is the weighted least squares of the residual in that quantity.
    """

    x_label: str
    x: NDArray[np.float64]  # broadcastable to the touches' shape
    edges: NDArray[np.float64] | None = None  # bin edges; None: 48 bins over the range of x
    weight: NDArray[np.float64] | None = None
    y_label: str = "deviation (um)"


# What an effect may need of a campaign: key -> (what to tell the user, test on the touches).
NEEDS: dict[str, tuple[str, Callable[[Touches], bool]]] = {
    "touch_times": ("needs touch times (a t_s column)", lambda touches: touches.times_s is not None),
}


# -- shared kinematics of the tip ------------------------------------------------------------------
def radial_unit(touches: Touches) -> NDArray[np.float64]:
    """u_k, outward radial direction of every point, (n_o, 1, n_pt, 3)."""
    return touches.memo("radial_unit", lambda: radial_directions(touches.orientations, touches.geometry.points_per_circle)[:, None])


def ball_centre_mm(touches: Touches) -> NDArray[np.float64]:
    """c_k, ball centre of every touch relative to the pivot, mm, (n_o, 1, n_pt, 3)."""
    return touches.memo("ball_centre", lambda: ball_centres(touches.orientations, touches.geometry)[:, None])


def axis_frame(touches: Touches, axis: str) -> NDArray[np.float64]:
    """Columns x, y, z of the frame a head axis sits in, in the machine frame, (n_o, 1, n_pt, 3, 3).

    B sits in the machine frame (it turns about z); A sits in the frame carried by B, Rz(B_k), and
    turns about its x axis. Error motions and location errors of an axis are given in this frame.
    """
    if axis == "B":
        return np.broadcast_to(np.eye(3), touches.b_deg.shape + (3, 3))
    if axis == "A":
        return rot_z(touches.b_deg)
    raise ValueError("axis must be 'A' or 'B'")


def screw_deviation(touches: Touches, axis: str) -> NDArray[np.float64]:
    """Deviation of each touch per unit component of a small-displacement screw of an axis, (n_o, 1, n_pt, 6).

    The screw (delta, eps) displaces the body the axis carries, given in the axis's frame
    (axis_frame) at the pivot, where both nominal axis lines pass. It moves the ball centre by
    d = delta + eps x c_k; by the sign rule the touch reads -d . u_k = -delta . u_k - eps . (c_k x u_k).
    Columns 0-2: per um of translation along the frame's x, y, z; columns 3-5: per arcsec of
    rotation about them (1 arcsec at 1 mm = 4.85e-3 um). Only the part of eps across the ring axis
    has a lever, the axial distance sqrt(L^2 - rho^2): c_k x u_k = sqrt(L^2 - rho^2) s0 x u_k.
    """

    def make() -> NDArray[np.float64]:
        frame = axis_frame(touches, axis)
        u = radial_unit(touches)
        lever = np.cross(ball_centre_mm(touches), u)
        # Components in the axis frame are frame^T v.
        per_um = -np.einsum("...ji,...j->...i", frame, u)
        per_arcsec = -np.einsum("...ji,...j->...i", frame, lever) * RAD_PER_ARCSEC * UM_PER_MM
        return np.concatenate([per_um, per_arcsec], axis=-1)

    return touches.memo(f"screw_{axis}", make)


def rotation_deviation_um_per_arcsec(touches: Touches, axis: str) -> NDArray[np.float64]:
    """Deviation (um) of each touch per arcsec of angular positioning error of a head axis, (n_o, 1, n_pt).

    The screw_deviation column of a rotation about the axis itself: B turns about machine z, so its
    lever is the ball's distance from z (~ L sin A); A turns about the head's x axis Rz(B_k) x, a
    lever of the full L.
    """
    return screw_deviation(touches, axis)[..., 5 if axis == "B" else 3]


def joint_angle_deg(touches: Touches, axis: str) -> NDArray[np.float64]:
    """Actual joint angle of A or B at every touch, (n_o, 1, n_pt) deg."""
    if axis == "A":
        return touches.a_deg
    if axis == "B":
        return touches.b_deg
    raise ValueError("axis must be 'A' or 'B'")


def full_shape(array: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
    """Broadcast an (n_o, 1, n_pt[, k]) array over the repetitions: a read-only view when it is the
    same in every repetition (no copy n_rep times the size), else the array itself (writable: a
    scan library's columns are fitted in place)."""
    target = touches.shape + array.shape[3:]
    return array if array.shape == target else np.broadcast_to(array, target)


def effect_label(effect: Effect) -> str:
    """'b_axis_cyclic 22 cycles/rev': an effect with its scanned settings, as a step names it."""
    settings = effect.settings()
    units = {p.name: p.unit for p in effect.parameters}
    return " ".join([effect.id, *(f"{v:g} {units.get(k, '')}".strip() for k, v in settings.items())])


def settings_label(effect: Effect, settings: list[dict[str, Any]]) -> str:
    """The effect at one setting as a step names it (effect_label), or at several: 'a_axis_tilt_motion 19-21 cycles/rev'."""
    return effect_label(effect.with_settings(**settings[0])) if len(settings) == 1 else f"{effect.id} {settings_text(effect, settings)}"


def settings_text(effect: Effect, settings: list[dict[str, Any]]) -> str:
    """'1-14, 17-21 cycles/rev': settings of the effect's scanned parameters in words, consecutive
    values of one parameter as a range, in its unit."""
    units = {p.name: p.unit for p in effect.parameters}
    if len({tuple(s) for s in settings}) != 1 or len(settings[0]) != 1:
        return "; ".join(", ".join(f"{k} {v:g} {units.get(k, '')}".strip() for k, v in s.items()) for s in settings)
    (name,) = settings[0]
    runs: list[list[float]] = []
    for value in sorted(float(s[name]) for s in settings):
        if runs and value == runs[-1][-1] + 1:
            runs[-1].append(value)
        else:
            runs.append([value])
    return (", ".join(f"{r[0]:g}" if len(r) == 1 else f"{r[0]:g}-{r[-1]:g}" for r in runs) + f" {units.get(name, '')}").strip()
