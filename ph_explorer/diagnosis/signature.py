"""The signature of what is left: the out-of-sample residual described in the head's own variables.

When the model fails beyond noise and no catalog effect explains it (verdict `partial` or
`unexplained`), `signature` says how the residual depends on each variable a touch has (VARIABLES
and approach_direction): per variable a periodic probe (`Periodic`, m cycles per revolution or per
span) and a localised one (`Localised`, a Gaussian bump), each as f(x) * {1, cos theta, sin theta}
(radial and in the ring's plane). Significance is the search's own noise null (NULL_MARGIN).
Probes are Effect subclasses with candidate = False, registered in no catalog.

Method: docs/methods/signature.md.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from ph_explorer.diagnosis.candidates import DIGITS, Candidate
from ph_explorer.diagnosis.evidence import binned_evidence
from ph_explorer.diagnosis.search import NULL_MARGIN, CandidateSearch
from ph_explorer.effects.effect import Effect, Evidence, Parameter
from ph_explorer.errors import InputError
from ph_explorer.geometry import wrap_deg
from ph_explorer.kinematics import Touches
from ph_explorer.models import least_squares
from ph_explorer.models.least_squares import Design

CYCLES = tuple(float(m) for m in range(1, 41))
WIDTHS_DEG = (5.0, 10.0, 20.0)
CENTRES_FULL_TURN = 36  # an angle covered over more than FULL_TURN_DEG: every 10 deg
CENTRES_PARTIAL = 24  # an angle over part of a turn: spread over the range the campaign covers
CENTRES_SPAN = 36  # time and order: spread over the span
FULL_TURN_DEG = 300.0
RING_HARMONICS = (2, 3, 4)
# Less than this share of the residual is rounding, not a signature: a term the interpolator
# predicts exactly (a function of the ring angle alone) leaves ~1e-17 beside a null of 0.
MIN_FRACTION = 1e-6


@dataclass(frozen=True)
class Variable:
    """One variable of a touch: its JSON name, axis label, unit and values.

    unit: "deg" for angles, "s" (time) or "touch" (order) for variables read over their span,
    "sign" for an approach direction. per_ring: constant over a ring (A0, B0).
    """

    name: str
    label: str
    unit: str
    values: Callable[[Touches], NDArray[np.float64]]  # broadcastable to touches.shape
    per_ring: bool = False
    needs: frozenset[str] = frozenset()

    @property
    def angle(self) -> bool:
        return self.unit == "deg"

    def span(self, touches: Touches) -> tuple[float, float]:
        """(start, length) over which the cycles of a periodic term count: the campaign's first
        touch to its last for time, the N positions of a circle for order."""
        if self.unit == "touch":
            return 0.0, float(touches.shape[-1])
        x = self.values(touches)
        return float(x.min()), max(float(np.ptp(x)), 1e-9)


def order_in_repetition(touches: Touches) -> NDArray[np.float64]:
    """Each touch's position 0..N-1 in its circle's scan order, (n_o, n_rep, n_pt)."""
    return np.argsort(np.argsort(touches.order, axis=-1, kind="stable"), axis=-1).astype(float)


VARIABLES: dict[str, Variable] = {
    v.name: v
    for v in (
        Variable("a_joint_deg", "A joint angle at the touch (deg)", "deg", lambda t: t.a_deg),
        Variable("b_joint_deg", "B joint angle at the touch (deg)", "deg", lambda t: t.b_deg),
        Variable("a0_deg", "nominal A0 of the ring (deg)", "deg", lambda t: t.orientations[:, 0, None, None], per_ring=True),
        Variable("b0_deg", "nominal B0 of the ring (deg)", "deg", lambda t: t.orientations[:, 1, None, None], per_ring=True),
        Variable("probe_azimuth_deg", "force azimuth in the probe frame (deg)", "deg", lambda t: t.psi_deg),
        Variable("ring_angle_deg", "point angle on the ring (deg)", "deg", lambda t: t.theta_deg[None, None, :]),
        Variable("time_s", "touch time (s)", "s", lambda t: t.times_s, needs=frozenset({"touch_times"})),
        Variable("order_in_repetition", "position in the circle's scan order", "touch", order_in_repetition),
    )
}
APPROACH = "approach_direction"
APPROACH_SIGNS = {
    "A": Variable(APPROACH, "A joint approach sign", "sign", lambda t: t.a_approach),
    "B": Variable(APPROACH, "B joint approach sign", "sign", lambda t: t.b_approach),
}
ALL: tuple[str, ...] = (*VARIABLES, APPROACH)
# The JSON keys of an entry's setting, by the variable's unit: (periodic, localised centre, width).
KEYS = {
    "deg": ("cycles_per_rev", "centre_deg", "width_deg"),
    "s": ("cycles_per_span", "centre_s", "width_s"),
    "touch": ("cycles_per_span", "centre_touch", "width_touches"),
}


def ring_shapes(touches: Touches, per_ring: bool) -> NDArray[np.float64]:
    """(1, 1, n_pt, s): the ring patterns a function multiplies: 1, cos theta, sin theta for a
    touch variable; cos(k theta), sin(k theta), k in RING_HARMONICS, for A0/B0."""
    theta = np.radians(touches.theta_deg)
    if per_ring:
        k_theta = theta[:, None] * np.array(RING_HARMONICS, dtype=float)
        shapes = np.stack([np.cos(k_theta), np.sin(k_theta)], axis=-1).reshape(len(theta), -1)
    else:
        shapes = np.stack([np.ones_like(theta), np.cos(theta), np.sin(theta)], axis=-1)
    return shapes[None, None]


class _Probe(Effect):
    """A signature probe: functions of one variable times ring patterns (never a candidate)."""

    candidate: ClassVar[bool] = False
    kind: ClassVar[str] = ""

    def __init__(self, variable: Variable | str, grid: dict[str, tuple[float, ...]], **params: float) -> None:
        if isinstance(variable, str):
            if variable not in VARIABLES:
                raise InputError(f"no signature variable {variable!r} (known: {', '.join(ALL)})")
            variable = VARIABLES[variable]
        self.variable = variable
        self.id = f"signature_{self.kind}_{variable.name}"  # type: ignore[misc]
        self.name = f"{self.kind} in {variable.name}"  # type: ignore[misc]
        self.needs = variable.needs  # type: ignore[misc]
        self.scan = dict(grid)  # type: ignore[misc]
        super().__init__(**{n: v[0] for n, v in self.scan.items()} | params)

    def scan_grid(self) -> list[dict[str, float]]:  # type: ignore[override]
        names = list(self.scan)
        return [dict(zip(names, values)) for values in itertools.product(*(self.scan[n] for n in names))]

    def with_settings(self, **settings: float) -> _Probe:
        return type(self)(self.variable, self.scan, **{**self.params, **settings})

    def function(self, touches: Touches) -> NDArray[np.float64]:
        """(..., g): the functions of the variable, broadcastable to touches.shape + (g,)."""
        raise NotImplementedError

    def evidence_x(self, touches: Touches) -> tuple[str, NDArray[np.float64], NDArray[np.float64] | None]:
        """(label, x, bin edges or None) the evidence is read against."""
        x = self.variable.values(touches)
        edges = np.linspace(-180.0, 180.0, 73) if self.variable.angle and np.ptp(x) > FULL_TURN_DEG else None
        return self.variable.label, x, edges

    def basis(self, touches: Touches) -> tuple[NDArray[np.float64], list[str]]:
        f = self.function(touches)  # (n_o, n_rep or 1, n_pt or 1, g)
        shapes = ring_shapes(touches, self.variable.per_ring)  # (1, 1, n_pt, s)
        cols = f[..., :, None] * shapes[..., None, :]
        cols = cols.reshape(*cols.shape[:-2], -1)
        return cols, [f"{self.id}_{i}" for i in range(cols.shape[-1])]

    def from_coefficients(self, coef: NDArray[np.float64]) -> dict[str, float]:
        """Amplitudes from the coefficients laid out (function g, ring pattern s): for A0/B0 each
        ring harmonic's (k2_um ...); else the radial change and the ball's displacement."""
        c = np.asarray(coef, dtype=float).reshape(-1, ring_shapes_count(self.variable.per_ring))
        # sum of squares over the functions: the amplitude of A sin(m x + phi) (or of one bump)
        if self.variable.per_ring:
            per_k = np.sqrt((c.reshape(len(c), len(RING_HARMONICS), 2) ** 2).sum(axis=(0, 2)))
            out = {"amplitude_um": float(np.sqrt((per_k**2).sum()))}
            out |= {f"k{k}_um": float(a) for k, a in zip(RING_HARMONICS, per_k)}
        else:
            out = {"radial_um": float(np.sqrt((c[:, 0] ** 2).sum())), "displacement_um": float(np.sqrt((c[:, 1:] ** 2).sum()))}
            if len(c) == 1:  # one function: signed height, and the displacement's direction
                out["radial_um"] = float(c[0, 0])
                out["displacement_direction_deg"] = float(np.degrees(np.arctan2(c[0, 2], c[0, 1])) % 360.0)
        return out | self.settings()

    def evidence(self, touches: Touches) -> Evidence:
        label, x, edges = self.evidence_x(touches)
        return Evidence(label, x, edges=edges)


def ring_shapes_count(per_ring: bool) -> int:
    return 2 * len(RING_HARMONICS) if per_ring else 3


AMPLITUDES = (
    Parameter("radial_um", "um", 0.0, "radial change at the touch"),
    Parameter("displacement_um", "um", 0.0, "displacement of the ball in the ring's plane"),
    Parameter("displacement_direction_deg", "deg", 0.0, "its direction in the ring frame, from e1", period=360.0),
)


class Periodic(_Probe):
    """sin(m x), cos(m x): m cycles per revolution of an angle, or per span (time, order)."""

    kind = "periodic"
    parameters = (Parameter("cycles", "cycles", 1.0, "cycles per revolution (angles) or per span (time, order)"), *AMPLITUDES)

    def __init__(self, variable: Variable | str, grid: dict[str, tuple[float, ...]] | None = None, **params: float) -> None:
        super().__init__(variable, grid or {"cycles": CYCLES}, **params)

    def phase(self, touches: Touches) -> NDArray[np.float64]:
        """m x in radians, x an angle or its place along the span (one span = one turn)."""
        x = self.variable.values(touches)
        m = self.params["cycles"]
        if self.variable.angle:
            return m * np.radians(x)
        start, length = self.variable.span(touches)
        return m * 2.0 * np.pi * (x - start) / length

    def function(self, touches: Touches) -> NDArray[np.float64]:
        phase = self.phase(touches)
        return np.stack([np.sin(phase), np.cos(phase)], axis=-1)

    def evidence_x(self, touches: Touches) -> tuple[str, NDArray[np.float64], NDArray[np.float64] | None]:
        what = self.variable.label if self.variable.angle else f"{self.variable.label} over its span"
        x = np.mod(np.degrees(self.phase(touches)), 360.0)
        return f"{self.params['cycles']:g} x {what}, phase mod 360 (deg)", x, np.linspace(0.0, 360.0, 37)


class Localised(_Probe):
    """exp(-((x - c) / w)^2 / 2): a bump at c of width w (angles wrapped), in the variable's unit."""

    kind = "localised"
    parameters = (
        Parameter("centre", "", 0.0, "centre of the bump, in the variable's unit"),
        Parameter("width", "", 10.0, "width (standard deviation) of the bump, in the variable's unit"),
        *AMPLITUDES,
    )

    def __init__(self, variable: Variable | str, grid: dict[str, tuple[float, ...]] | None = None, **params: float) -> None:
        default = {"centre": tuple(np.arange(-180.0, 180.0, 360.0 / CENTRES_FULL_TURN)), "width": WIDTHS_DEG}
        super().__init__(variable, grid or default, **params)
        if grid is None and not self.variable.angle:
            raise ValueError(f"a localised probe in {self.variable.name} needs its grid: localised_grid(variable, touches)")

    def function(self, touches: Touches) -> NDArray[np.float64]:
        distance = self.variable.values(touches) - self.params["centre"]
        if self.variable.angle:
            distance = wrap_deg(distance)
        return np.exp(-0.5 * (distance / self.params["width"]) ** 2)[..., None]


class Sign(_Probe):
    """+-1 by the sign of one joint's approach into the touch, nothing scanned."""

    kind = "sign"
    parameters = AMPLITUDES

    def __init__(self, joint: str, grid: dict[str, tuple[float, ...]] | None = None, **params: float) -> None:
        if joint not in APPROACH_SIGNS:
            raise ValueError("joint must be 'A' or 'B'")
        self.joint = joint
        super().__init__(APPROACH_SIGNS[joint], {}, **params)
        self.id = f"signature_sign_{joint.lower()}_approach"  # type: ignore[misc]

    def with_settings(self, **settings: float) -> Sign:
        return Sign(self.joint, **{**self.params, **settings})

    def function(self, touches: Touches) -> NDArray[np.float64]:
        return self.variable.values(touches)[..., None]

    def evidence_x(self, touches: Touches) -> tuple[str, NDArray[np.float64], NDArray[np.float64] | None]:
        return self.variable.label, self.variable.values(touches), np.array([-1.5, 0.0, 1.5])


def localised_grid(variable: Variable, touches: Touches) -> dict[str, tuple[float, ...]]:
    """The centres and widths a Localised probe scans on these touches (docs/methods/signature.md)."""
    x = variable.values(touches)
    if variable.angle:
        if np.ptp(x) > FULL_TURN_DEG:
            centres = np.arange(-180.0, 180.0, 360.0 / CENTRES_FULL_TURN)
        else:
            centres = np.linspace(float(x.min()), float(x.max()), CENTRES_PARTIAL)
        return {"centre": tuple(float(c) for c in centres), "width": WIDTHS_DEG}
    start, length = float(x.min()), max(float(np.ptp(x)), 1e-9)
    centres = np.linspace(start, start + length, CENTRES_SPAN)
    return {"centre": tuple(float(c) for c in centres), "width": tuple(length * w / 360.0 for w in WIDTHS_DEG)}


def probes(variables: Sequence[str], touches: Touches) -> list[_Probe]:
    """Every probe of the given variables that can run on these touches."""
    unknown = [v for v in variables if v not in ALL]
    if unknown:
        raise InputError(f"no signature variable {unknown[0]!r} (known: {', '.join(ALL)})")
    out: list[_Probe] = []
    for name in dict.fromkeys(variables):
        if name == APPROACH:
            out += [Sign("B"), Sign("A")]
            continue
        periodic = Periodic(name)
        if not periodic.unmet_needs(touches):  # time_s without touch times: left out
            out += [periodic, Localised(name, localised_grid(VARIABLES[name], touches))]
    return out


def pattern_evidence(search: CandidateSearch, probe: _Probe, fixed: Design | None) -> dict[str, Any]:
    """The residual and the fitted term, each touch weighted by the term's main ring pattern.

    The coefficients (function g x ring pattern s) are split by SVD; the first right vector is the
    ring pattern (e.g. a displacement along e1: cos theta), normalised to unit rms, so that a bin's
    value is the least squares of the residual along that pattern (um).
    """
    design = search.design([probe])
    joint = design if fixed is None else fixed.stacked(design)
    coef = least_squares.fit(joint, search.targets)[0][-design.n_columns :, 0]
    shapes = ring_shapes(search.touches, probe.variable.per_ring)[0, 0]  # (n_pt, s)
    _, _, vt = np.linalg.svd(coef.reshape(-1, shapes.shape[-1]), full_matrices=False)
    pattern = shapes @ vt[0]
    weight = pattern / max(float(np.sqrt(np.mean(pattern**2))), 1e-300)
    mean, within = design.apply(coef)
    fitted = mean[:, None, :] + (0.0 if within is None else within)
    label, x, edges = probe.evidence_x(search.touches)
    evidence = Evidence(label, x, edges=edges, weight=weight, y_label="out-of-sample residual along the fitted ring pattern (um)")
    return binned_evidence(evidence, search.residual, fitted)


def entry(probe: _Probe, candidate: Candidate, search: CandidateSearch, fixed: Design | None) -> dict[str, Any]:
    """One signature entry (see `signature`) from the probe's Candidate."""
    explained, noise = float(candidate.explained_fraction), float(candidate.noise_fraction)
    out: dict[str, Any] = {"variable": probe.variable.name, "kind": probe.kind}
    if isinstance(probe, Sign):
        out["joint"] = probe.joint
    else:
        cycles_key, centre_key, width_key = KEYS[probe.variable.unit]
        settings = {**probe.settings(), **candidate.settings}
        if isinstance(probe, Periodic):
            out[cycles_key] = float(settings["cycles"])
        else:
            out[centre_key] = round(float(settings["centre"]), 3)
            out[width_key] = round(float(settings["width"]), 3)
    scanned = set(probe.scan)
    out |= {
        "explained_fraction": round(explained, DIGITS),
        "noise_fraction": round(noise, DIGITS),
        "significant": bool(explained > MIN_FRACTION and explained > NULL_MARGIN * noise),
        "params": {k: round(v, DIGITS) for k, v in candidate.params.items() if k not in scanned},
        "params_u": {k: round(v, DIGITS) for k, v in candidate.params_u.items() if k not in scanned},
        "evidence": candidate.evidence,
    }
    if explained > MIN_FRACTION:
        out["evidence"] = pattern_evidence(search, probe.with_settings(**candidate.settings), fixed)
    return out


def signature(search: CandidateSearch, fixed: Design | None = None, variables: Sequence[str] = ALL) -> list[dict[str, Any]]:
    """What the out-of-sample residual left beyond `fixed` (the effects found, as search.design of
    them) looks like in each variable: a periodic and a localised entry per variable (two sign
    entries, A and B, for approach_direction), best first: significant ones first, then by the
    share of the residual explained.

    Each entry is a dict: "variable", "kind" ("periodic" | "localised" | "sign"), its setting,
    "explained_fraction", "noise_fraction", "significant", "params", "params_u" and "evidence"
    (every key: docs/methods/signature.md). Probes that cannot run on the campaign (time_s without
    touch times) are left out.
    """
    out = [entry(probe, search.score(probe, fixed), search, fixed) for probe in probes(variables, search.touches)]
    out.sort(key=lambda e: (e["significant"], e["explained_fraction"]), reverse=True)
    return out
