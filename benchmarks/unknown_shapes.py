"""Effects no catalog holds, in families, for the population's unknown-shape heads (issue 55).

Test-only twin effects: they make the data of a head and are never in a catalog the diagnosis
uses. Each family is a mechanism of a real head with random parameters over plausible ranges
(docs/methods/random_heads.md, "Unknown shapes"); `unknown_shape_head(seed)` draws a family, its
parameters and a random head (design, background, noise law: twin.random_heads) to hold it. Each
shape's size is set by what it does to the check rings: its own out-of-sample error there, through
the circle fit and the interpolator, is `visibility` times the campaign's noise floor (1 to 3),
so that the population tests what the diagnosis says of an effect a user would see, not whether
it sees one below the noise. A badly measured ring and touch outliers keep their physical size.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from benchmarks.multi_effects import REPLACEMENT_STRIDE, REPLACEMENTS
from ph_explorer import metrics
from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.detection import hidden_effect_of
from ph_explorer.effects.effect import Effect, Parameter, joint_angle_deg, rotation_deviation_um_per_arcsec
from ph_explorer.effects.probe import lateral_share
from ph_explorer.errors import InputError
from ph_explorer.geometry import wrap_deg
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import Touches, campaign_touches
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.twin import Scenario
from ph_explorer.twin.random_heads import design_of, random_campaign, random_head

VISIBILITY = (1.0, 3.0)  # the shape's out-of-sample rms at the check rings, in noise floors (vs the mean)


class _Unknown(Effect):
    """An effect of a shape no catalog holds: it only makes data (forward), never fitted."""

    candidate: ClassVar[bool] = False
    family: ClassVar[str] = ""
    truth_variables: ClassVar[tuple[str, ...]] = ()  # the signature variables that read it (its joint, time, ...)

    def forward(self, touches: Touches, rng: np.random.Generator) -> NDArray[np.float64]:
        return np.broadcast_to(self.shape(touches), touches.shape).copy()

    def shape(self, touches: Touches) -> NDArray[np.float64]:
        raise NotImplementedError


class _AxisShape(_Unknown):
    """An angular positioning error of one axis, a function f(joint angle) in arcsec times the lever."""

    axis_code: ClassVar[str] = "axis"  # parameter: 0 for A, 1 for B

    @property
    def joint(self) -> str:
        return "AB"[int(self.params["axis"])]

    def shape(self, touches: Touches) -> NDArray[np.float64]:
        angle = joint_angle_deg(touches, self.joint)
        return self.error_arcsec(angle, touches) * rotation_deviation_um_per_arcsec(touches, self.joint)

    def error_arcsec(self, angle_deg: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
        raise NotImplementedError


AXIS = Parameter("axis", "", 1.0, "0: the A axis, 1: the B axis")
AMPLITUDE = Parameter("amplitude_arcsec", "arcsec", 1.0, "size of the angular error", plausible=(0.0, 6.0))
PHASE = Parameter("phase_deg", "deg", 0.0, "phase", period=360.0)


class AxisStep(_AxisShape):
    """An encoder glitch or a reassembled scale: the axis's angular position is off by a constant
    over part of its turn, a step up and a step down."""

    id, family, name = "unknown_axis_step", "step", "A step in an axis's angular position over part of its turn"
    parameters = (
        AXIS,
        AMPLITUDE,
        Parameter("start_deg", "deg", 0.0, "where the step begins", period=360.0),
        Parameter("width_deg", "deg", 90.0, "how far it lasts"),
    )

    def error_arcsec(self, angle_deg: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
        inside = np.mod(angle_deg - self.params["start_deg"], 360.0) < self.params["width_deg"]
        return self.params["amplitude_arcsec"] * inside


class AxisDent(_AxisShape):
    """A damaged gear tooth or a dent in the encoder track: a bump a few degrees wide."""

    id, family, name = "unknown_axis_dent", "dent", "A local dent in an axis's angular position"
    parameters = (
        AXIS,
        AMPLITUDE,
        Parameter("centre_deg", "deg", 0.0, "joint angle of the dent", period=360.0),
        Parameter("width_deg", "deg", 5.0, "its width (one sigma)"),
    )

    def error_arcsec(self, angle_deg: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
        distance = wrap_deg(angle_deg - self.params["centre_deg"])
        return self.params["amplitude_arcsec"] * np.exp(-0.5 * (distance / self.params["width_deg"]) ** 2)


class AxisNonIntegerPeriod(_AxisShape):
    """A gear stage whose ratio is not a whole number: a cyclic error with a non-integer number of
    cycles per turn of the axis (its phase jumps where the turn closes)."""

    id, family, name = "unknown_non_integer_period", "non_integer_period", "A cyclic error of a non-integer period"
    parameters = (AXIS, AMPLITUDE, PHASE, Parameter("cycles_per_rev", "cycles/rev", 10.5, "cycles per turn, not a whole number"))

    def error_arcsec(self, angle_deg: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
        turn = np.mod(angle_deg, 360.0) / 360.0
        return self.params["amplitude_arcsec"] * np.sin(
            2 * np.pi * self.params["cycles_per_rev"] * turn + np.radians(self.params["phase_deg"])
        )


class AxisDriftingPeriod(_AxisShape):
    """A worn or eccentric worm whose pitch changes along the turn: a chirp, its local period
    drifting from k0 to k0 + dk cycles per turn."""

    id, family, name = "unknown_drifting_period", "drifting_period", "A cyclic error whose period drifts along the axis"
    parameters = (
        AXIS,
        AMPLITUDE,
        PHASE,
        Parameter("cycles_per_rev", "cycles/rev", 20.0, "cycles per turn at the turn's start"),
        Parameter("drift_cycles", "cycles/rev", 4.0, "change of the local period over one turn"),
    )

    def error_arcsec(self, angle_deg: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
        x = np.mod(angle_deg, 360.0) / 360.0
        phase = 2 * np.pi * (self.params["cycles_per_rev"] * x + 0.5 * self.params["drift_cycles"] * x**2)
        return self.params["amplitude_arcsec"] * np.sin(phase + np.radians(self.params["phase_deg"]))


class AxisBeyondScan(_AxisShape):
    """A fine gear (41-60 teeth): a cyclic error beyond the catalog's scan of 1-40 cycles per turn."""

    id, family, name = "unknown_beyond_scan", "beyond_scan", "A cyclic error of 41-60 cycles per turn"
    parameters = (AXIS, AMPLITUDE, PHASE, Parameter("cycles_per_rev", "cycles/rev", 45.0, "cycles per turn, 41-60"))

    def error_arcsec(self, angle_deg: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
        return self.params["amplitude_arcsec"] * np.sin(np.radians(self.params["cycles_per_rev"] * angle_deg + self.params["phase_deg"]))


class AxisCoupled(_AxisShape):
    """A cyclic error of one axis whose size depends on the other axis's angle (the load on its
    bearing changes as the other axis turns the probe's weight)."""

    id, family, name = "unknown_coupled", "coupled", "An axis error whose size depends on the other axis's angle"
    parameters = (
        AXIS,
        AMPLITUDE,
        PHASE,
        Parameter("cycles_per_rev", "cycles/rev", 12.0, "cycles per turn of this axis"),
        Parameter("other_phase_deg", "deg", 0.0, "where the other axis makes it largest", period=360.0),
    )

    def error_arcsec(self, angle_deg: NDArray[np.float64], touches: Touches) -> NDArray[np.float64]:
        other = joint_angle_deg(touches, "B" if self.joint == "A" else "A")
        size = 0.5 + 0.5 * np.cos(np.radians(other - self.params["other_phase_deg"]))
        cycle = np.sin(np.radians(self.params["cycles_per_rev"] * angle_deg + self.params["phase_deg"]))
        return self.params["amplitude_arcsec"] * size * cycle


class SeatWear(_Unknown):
    """The module's seats wear during the campaign: a 3-lobe pre-travel term in the force azimuth
    that grows from nothing to its amplitude over the campaign."""

    id, family, name = "unknown_seat_wear", "seat_wear", "Probe seats wearing during the campaign"
    truth_variables = ("time_s", "touch_order", "probe_azimuth_deg")
    parameters = (Parameter("amplitude_um", "um", 0.3, "3-lobe amplitude at the campaign's end", plausible=(0.0, 0.8)), PHASE)

    def shape(self, touches: Touches) -> NDArray[np.float64]:
        lobes = np.cos(3 * np.radians(touches.psi_deg) + np.radians(self.params["phase_deg"])) * lateral_share(touches)
        return self.params["amplitude_um"] * touches.place * lobes


class StylusKnock(_Unknown):
    """A knock reseats the stylus part-way through the campaign: from then on a 2-lobe term in the
    force azimuth that was not there before."""

    id, family, name = "unknown_stylus_knock", "stylus_knock", "A knock that reseats the stylus during the campaign"
    truth_variables = ("time_s", "touch_order", "probe_azimuth_deg")
    parameters = (
        Parameter("amplitude_um", "um", 0.3, "2-lobe amplitude after the knock", plausible=(0.0, 0.8)),
        PHASE,
        Parameter("at", "", 0.5, "when, as a fraction of the campaign"),
    )

    def shape(self, touches: Touches) -> NDArray[np.float64]:
        lobes = np.cos(2 * np.radians(touches.psi_deg) + np.radians(self.params["phase_deg"])) * lateral_share(touches)
        return self.params["amplitude_um"] * (touches.place >= self.params["at"]) * lobes


class BadRing(_Unknown):
    """One ring measured with a chipped contact or a dirty gauge: a form error in every repetition
    of that ring only."""

    id, family, name = "unknown_bad_ring", "bad_ring", "A ring measured badly"
    truth_variables = ()
    parameters = (
        Parameter("a_deg", "deg", 45.0, "A0 of the ring"),
        Parameter("b_deg", "deg", 40.0, "B0 of the ring"),
        Parameter("amplitude_um", "um", 0.8, "form amplitude", plausible=(0.0, 2.0)),
        Parameter("lobes", "", 3.0, "lobes of the form error"),
        PHASE,
    )

    def shape(self, touches: Touches) -> NDArray[np.float64]:
        at = (np.abs(touches.orientations[:, 0] - self.params["a_deg"]) < 1e-6) & (
            np.abs(touches.orientations[:, 1] - self.params["b_deg"]) < 1e-6
        )
        form = np.cos(self.params["lobes"] * np.radians(touches.theta_deg) + np.radians(self.params["phase_deg"]))
        return self.params["amplitude_um"] * at[:, None, None] * form[None, None, :]


class TouchOutliers(_Unknown):
    """Debris or a sticking trigger: a few per cent of the touches read far off, each once."""

    id, family, name = "unknown_touch_outliers", "touch_outliers", "Touch outliers"
    truth_variables = ()
    parameters = (
        Parameter("share", "", 0.01, "share of the touches hit"),
        Parameter("size_um", "um", 2.0, "how far off", plausible=(0.0, 6.0)),
        Parameter("draw", "", 0.0, "the seed of which touches"),
    )

    def shape(self, touches: Touches) -> NDArray[np.float64]:
        rng = np.random.default_rng(int(self.params["draw"]))
        hit = rng.uniform(size=touches.shape) < self.params["share"]
        return self.params["size_um"] * hit * rng.choice([-1.0, 1.0], size=touches.shape)


AXIS_FAMILIES = (AxisStep, AxisDent, AxisNonIntegerPeriod, AxisDriftingPeriod, AxisBeyondScan, AxisCoupled)
FAMILIES: dict[str, type[_Unknown] | None] = {cls.family: cls for cls in (*AXIS_FAMILIES, SeatWear, StylusKnock, BadRing, TouchOutliers)}
FAMILIES["on_top_of_catalog"] = None  # an axis shape of the families above, beside a hidden catalog effect
ON_TOP_CATALOG = ("b_axis_cyclic", "a_axis_cyclic", "b_axis_tilt_motion", "a_axis_radial_motion", "lobing")


def drawn_shape(cls: type[_Unknown], rng: np.random.Generator, orientations: NDArray[np.float64]) -> _Unknown:
    """The family's shape at unit size with its other parameters drawn (module docstring)."""
    axis = float(rng.integers(0, 2))
    phase = float(rng.uniform(0, 360))
    if cls is AxisStep:
        return cls(axis=axis, amplitude_arcsec=1.0, start_deg=float(rng.uniform(0, 360)), width_deg=float(rng.uniform(20, 180)))
    if cls is AxisDent:
        return cls(axis=axis, amplitude_arcsec=1.0, centre_deg=float(rng.uniform(-180, 180)), width_deg=float(rng.uniform(2, 10)))
    if cls is AxisNonIntegerPeriod:
        whole = int(rng.integers(5, 39))
        return cls(axis=axis, amplitude_arcsec=1.0, phase_deg=phase, cycles_per_rev=whole + float(rng.uniform(0.2, 0.8)))
    if cls is AxisDriftingPeriod:
        drift = float(rng.uniform(2, 8)) * float(rng.choice([-1.0, 1.0]))
        return cls(axis=axis, amplitude_arcsec=1.0, phase_deg=phase, cycles_per_rev=float(rng.uniform(10, 30)), drift_cycles=drift)
    if cls is AxisBeyondScan:
        return cls(axis=axis, amplitude_arcsec=1.0, phase_deg=phase, cycles_per_rev=float(rng.integers(41, 61)))
    if cls is AxisCoupled:
        return cls(
            axis=axis,
            amplitude_arcsec=1.0,
            phase_deg=phase,
            cycles_per_rev=float(rng.integers(3, 31)),
            other_phase_deg=float(rng.uniform(0, 360)),
        )
    if cls is SeatWear:
        return cls(amplitude_um=1.0, phase_deg=phase)
    if cls is StylusKnock:
        return cls(amplitude_um=1.0, phase_deg=phase, at=float(rng.uniform(0.2, 0.8)))
    if cls is BadRing:
        a, b = orientations[int(rng.integers(len(orientations)))]
        return cls(
            a_deg=float(a), b_deg=float(b), amplitude_um=float(rng.uniform(0.4, 1.0)), lobes=float(rng.integers(2, 6)), phase_deg=phase
        )
    return TouchOutliers(share=float(rng.uniform(0.005, 0.03)), size_um=float(rng.uniform(1.0, 4.0)), draw=float(rng.integers(2**31)))


SIZED = {"amplitude_arcsec", "amplitude_um"}  # the parameters visibility scales


def at_visibility(shape: _Unknown, campaign: Campaign, visibility: float) -> _Unknown:
    """The shape scaled so that its out-of-sample rms at the check rings (the search's view: after
    each ring's circle fit, less what the interpolator predicts of it from the training rings) is
    `visibility` times the campaign's noise floor against the repetition mean."""
    touches = campaign_touches(campaign)
    held = campaign.holdout_mask()
    seen = OutOfSampleSmoother(campaign.orientations, ~held).residual(
        remove_size_and_centre(shape.forward(touches, np.random.default_rng(0)))
    )
    rms = float(np.sqrt(np.mean(seen[held].mean(axis=1) ** 2)))
    floor = metrics.noise_floor(campaign.noise_sigma_um(), campaign.n_repetitions)["mean"]
    factor = visibility * floor / metrics.MEAN_ABS_PER_SIGMA / rms if rms > 0 else 0.0
    return type(shape)(**{k: v * factor if k in SIZED else v for k, v in shape.params.items()})


def plausible(shape: _Unknown) -> bool:
    """Whether its size lies within its family's plausible range (and is not nothing)."""
    sized = [p for p in shape.parameters if p.name in SIZED]
    return all(p.admits(shape.params[p.name]) and shape.params[p.name] > 0 for p in sized)


DRAWS = 50  # draws of a family's shape tried on one head before it is replaced by the seed's next


def catalog_companion(seed: int, rng: np.random.Generator, design: str) -> tuple[Effect, float]:
    """A catalog effect at 1-3x its detection limit on this head (hidden_effect_of), the first of
    ON_TOP_CATALOG in a drawn order that reaches it within its plausible range."""
    for effect_id in rng.permutation(ON_TOP_CATALOG):
        try:
            return hidden_effect_of(seed, str(effect_id), None, design)
        except InputError:
            continue
    raise InputError(f"no catalog effect of {', '.join(ON_TOP_CATALOG)} fits head {seed} plausibly", option="--unknown-families")


@dataclass(frozen=True)
class UnknownHead:
    """A head of the population's unknown-shape part: its campaign and what it hides."""

    campaign: Campaign
    family: str
    truth: dict[str, Any]  # the unknown shape's id and parameters, its visibility, its catalog companion (on top)
    scenario: Scenario | None = None  # the head, to measure it at other rings (benchmarks/adaptive.py)


def unknown_shape_head(seed: int, family: str | None = None, design: str | None = None) -> UnknownHead:
    """The random head of `seed` with one shape of `family` (drawn from the seed when None). A shape
    that would need an implausible size to be seen on the head's design is no head of the world a
    method could be asked about: its other parameters are drawn again (DRAWS times), then the
    head is replaced by the next of the seed's stream (multi_effects' REPLACEMENTS)."""
    if family is not None and family not in FAMILIES:
        raise InputError(f"no family {family!r} ({', '.join(FAMILIES)})", option="--unknown-families")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 55]))
    family = family if family is not None else str(rng.choice(list(FAMILIES)))
    cls = FAMILIES[family] or AXIS_FAMILIES[int(rng.integers(len(AXIS_FAMILIES)))]
    visibility = float(rng.uniform(*VISIBILITY))
    for head in (int(seed) + REPLACEMENT_STRIDE * k for k in range(REPLACEMENTS)):
        drawn_design = design_of(head, design)
        plain = random_campaign(head, drawn_design)  # the head alone: where its check rings are, its noise
        for _ in range(DRAWS):
            shape = drawn_shape(cls, rng, plain.orientations)
            if cls not in (BadRing, TouchOutliers):
                shape = at_visibility(shape, plain, visibility)
            if plausible(shape):
                break
        else:
            continue
        hidden: list[Effect] = [shape]
        truth: dict[str, Any] = {"id": shape.id, "family": cls.family, **shape.params, "visibility": visibility, "head_seed": head}
        if family == "on_top_of_catalog":
            companion, strength = catalog_companion(head, rng, drawn_design)
            hidden.append(companion)
            truth["catalog"] = {"id": companion.id, **companion.params, "strength": strength}
        return UnknownHead(random_campaign(head, drawn_design, hidden), family, truth, random_head(head, drawn_design, hidden))
    raise RuntimeError(f"no {cls.family} shape is visible at a plausible size on seed {seed} nor its replacements")
