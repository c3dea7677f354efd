"""Polar roundness plots as roundness instruments draw them (ISO 4291, ISO 12181-1 conventions).

The deviations of a ring are drawn about the least-squares reference circle (the campaign's
deviations are already relative to it: harmonics 0 and 1 removed) on a chart where a radius is
`base + magnification x deviation`. The base radius is chosen from the deviations to be drawn so
that the magnified profile never reaches the centre (a profile through the centre turns inside
out and can no longer be read); scale circles are placed at round steps in um and labelled with
the deviation they stand for. `polar_svg` draws the flat chart; `curves_svg` draws a ring's named curves on it in the colours
the explorer uses everywhere (its panel and 3D scene, a report).

Chart lengths are in mm (the explorer's 3D scene draws the chart on the ring at true scale).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

# The explorer's magnification slider: min, max, step (x, chart um per um of deviation).
MAGNIFICATION_RANGE = (1000.0, 20000.0, 500.0)
# The innermost point of a profile keeps at least this share of the base radius from the centre.
INNER_CLEARANCE = 0.3
# Round deviation steps (um) between scale circles, and how many intervals a chart shows at most.
SCALE_STEPS_UM = (0.01, 0.02, 0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 2.5, 5.0, 10.0, 20.0, 50.0)
MAX_INTERVALS = 6
# Scale circles closer than this share of the base radius would crowd the chart.
MIN_SPACING = 0.1

# One color per curve (RGB 0-255), shared by the explorer's scene, its legend and charts, and a report.
CURVE_COLORS: dict[str, tuple[int, int, int]] = {
    "measured": (30, 30, 30),
    "repetitions": (150, 150, 150),
    "network": (31, 119, 180),
    "trilinear": (230, 120, 20),
    "hybrid": (40, 160, 60),
    "gp": (148, 103, 189),
    "reference": (120, 120, 120),
}
BAND_COLORS: dict[str, tuple[int, int, int]] = {
    "network": (150, 190, 235),
    "trilinear": (250, 200, 150),
    "hybrid": (160, 220, 160),
    "gp": (215, 195, 235),
}
LEGEND_LABELS = {
    "measured": "measured mean",
    "repetitions": "each repetition",
    "reference": "LS reference circle (dashed: scale circles, um)",
}
CURVE_ORDER = ("measured", "network", "trilinear", "gp", "hybrid")


def curve_color(name: str) -> tuple[int, int, int]:
    return CURVE_COLORS.get(name, (140, 60, 160))


def hex_color(rgb: tuple[int, int, int]) -> str:
    return "#{:02x}{:02x}{:02x}".format(*tuple(int(c) for c in rgb))


def offered_magnifications() -> NDArray[np.float64]:
    """Every magnification the explorer's slider offers."""
    low, high, step = MAGNIFICATION_RANGE
    return np.arange(low, high + 0.5 * step, step)


def scale_label(value_um: float) -> str:
    """The text of a scale circle: the deviation it stands for, in um ("+0.5 um", "0 um")."""
    return "0 um" if value_um == 0.0 else f"{value_um:+g} um"


@dataclass(frozen=True)
class PolarScale:
    """A polar chart: radius = base_mm + magnification x deviation; scale circles at circles_um."""

    magnification: float
    base_mm: float  # the least-squares reference circle on the chart
    step_um: float  # deviation between neighbouring scale circles
    circles_um: tuple[float, ...]  # the scale circles' deviations, 0 (the reference circle) included

    @property
    def mm_per_um(self) -> float:
        return self.magnification * 1e-3

    def radius_mm(self, deviation_um: ArrayLike) -> NDArray[np.float64]:
        """Chart radius (mm) of deviations in um."""
        return self.base_mm + self.mm_per_um * np.asarray(deviation_um, dtype=float)

    def labelled_circles(self) -> list[tuple[str, float]]:
        """(label, radius in mm) of each scale circle, innermost first."""
        return [(scale_label(v), float(self.radius_mm(v))) for v in self.circles_um]

    @property
    def outer_mm(self) -> float:
        return float(self.radius_mm(max(self.circles_um)))

    def caption(self) -> str:
        """What an instrument prints beside its chart: the magnification and the scale step."""
        return f"x{self.magnification:g}, {self.step_um:g} um / division"


def deviation_bounds(values: Iterable[ArrayLike]) -> tuple[float, float]:
    """The lowest and highest finite deviation (um) of every array given (0, 0 when none)."""
    arrays = [np.asarray(v, dtype=float).ravel() for v in values]
    finite = np.concatenate([a[np.isfinite(a)] for a in arrays]) if arrays else np.zeros(0)
    if finite.size == 0:
        return 0.0, 0.0
    return float(finite.min()), float(finite.max())


# The share of a campaign's touches beyond which one ring's chart alone makes room: a stray touch
# (debris, a bad contact) rescales its own ring, not every ring of the campaign.
CAMPAIGN_TOUCH_SHARE = 0.999


def campaign_bounds(deviations: ArrayLike) -> tuple[float, float]:
    """The deviations (um) every chart of a campaign keeps room for, so that it does not jump
    between orientations: its touches' 0.1 and 99.9 percentiles (0, 0 when none is finite). A
    chart adds its own ring's touches and curves (polar_scale)."""
    values = np.asarray(deviations, dtype=float)
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return 0.0, 0.0
    low, high = np.quantile(finite, [1.0 - CAMPAIGN_TOUCH_SHARE, CAMPAIGN_TOUCH_SHARE])
    return float(low), float(high)


def polar_scale(magnification: float, values: Iterable[ArrayLike], min_base_mm: float) -> PolarScale:
    """The chart for these deviations (um) at this magnification.

    The base radius is min_base_mm (e.g. the bore radius, to draw on the ring) unless the lowest
    deviation, magnified, would bring the profile within INNER_CLEARANCE x base of the centre;
    then it grows, rounded up to 2.5 mm so that a chart does not jitter between orientations.
    """
    lowest, highest = deviation_bounds(values)
    mm_per_um = float(magnification) * 1e-3
    depth = max(0.0, -lowest) * mm_per_um  # how far below the base the profile dips, mm
    base = float(min_base_mm)
    if depth > (1.0 - INNER_CLEARANCE) * base:
        base = 2.5 * math.ceil(depth / (1.0 - INNER_CLEARANCE) / 2.5)
    lo, hi = min(lowest, 0.0), max(highest, 0.0)
    step = SCALE_STEPS_UM[-1]
    for candidate in SCALE_STEPS_UM:
        intervals = math.ceil(hi / candidate - 1e-9) - math.floor(lo / candidate + 1e-9)
        if candidate * mm_per_um >= MIN_SPACING * base and intervals <= MAX_INTERVALS:
            step = candidate
            break
    k_low = min(-1, math.floor(lo / step + 1e-9))
    k_high = max(1, math.ceil(hi / step - 1e-9))
    # A circle is drawn only where it keeps off the centre as the profile does.
    circles = tuple(round(k * step, 10) for k in range(k_low, k_high + 1) if base + k * step * mm_per_um >= INNER_CLEARANCE * base * 0.5)
    return PolarScale(float(magnification), base, step, circles)


@dataclass(frozen=True)
class PolarSeries:
    """One profile on a chart: (n_pt,) or (n_curves, n_pt) deviations in um, point k at 360 k / n_pt deg."""

    label: str
    deviations_um: NDArray[np.float64]
    color: str  # CSS colour
    width: float = 2.0
    opacity: float = 1.0


def _xy(radius: NDArray[np.float64], theta_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Chart points; SVG's y axis points down, so theta turns counter-clockwise as seen."""
    t = np.radians(theta_deg)
    return np.stack([radius * np.cos(t), -radius * np.sin(t)], axis=-1)


@lru_cache(maxsize=16)
def _path_format(n: int) -> str:
    return "M" + " L".join(["%.3f,%.3f"] * n) + " Z"


def _path(points: NDArray[np.float64]) -> str:
    """A closed SVG path through (n, 2) points, 3 decimals: one %-format of all coordinates (the
    explorer draws three on every slider move; a formatted string per point took 4x as long)."""
    return _path_format(len(points)) % tuple(np.asarray(points, dtype=float).ravel().tolist())


def polar_svg(
    scale: PolarScale,
    series: Sequence[PolarSeries],
    title: str = "",
    band: tuple[str, NDArray[np.float64], NDArray[np.float64], str] | None = None,
    point_labels: int = 4,
) -> str:
    """The flat chart as an SVG string: scale circles labelled in um, the LS reference circle, the
    profiles, the point numbers and the direction of theta, the magnification and a legend.

    band: (label, low, high, colour) of a model's 95 % band, drawn as a filled annulus.
    Viewed from the head's side, as the explorer's "along the axis" view shows the ring.
    """
    n_pt = next((s.deviations_um.shape[-1] for s in series), 64)
    theta = 360.0 * np.arange(n_pt) / n_pt
    profile_max = max((float(np.max(scale.radius_mm(s.deviations_um))) for s in series), default=scale.base_mm)
    outer = max(scale.outer_mm, profile_max, scale.base_mm)
    extent, font, stroke = _layout(outer)
    legend_rows = -(-(len(series) + (band is not None)) // 3)  # three entries a row (_chart_frame's legend)
    # Below the last row's baseline, room for its descenders (0.6 font).
    top, height = -extent - 1.6 * font, 2 * extent + 1.6 * font + legend_rows * 1.6 * font + 0.6 * font
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="{-extent:.3f} {top:.3f} {2 * extent:.3f} {height:.3f}" '
        f'width="100%" role="img" aria-label="polar plot {title}" style="font-family:sans-serif;background:#fff">'
    ]
    if title:
        parts.append(f'<text x="{-extent:.3f}" y="{top + font:.3f}" font-size="{font:.3f}" font-weight="600">{title}</text>')
    parts.append(f'<text x="{extent:.3f}" y="{top + font:.3f}" font-size="{font:.3f}" text-anchor="end">{scale.caption()}</text>')
    if band is not None:
        label, low, high, color = band
        parts.append(
            f'<path d="{_path(_xy(scale.radius_mm(high), theta))} {_path(_xy(scale.radius_mm(low), theta)[::-1])}" '
            f'fill="{color}" fill-opacity="0.55" fill-rule="evenodd" stroke="none"/>'
        )
    entries = tuple((s.label, s.color, s.opacity) for s in series) + (((f"{band[0]} 95 % band", band[3], 0.55),) if band else ())
    circles, tail = _chart_frame(scale, outer, n_pt, point_labels, entries)
    parts.append(circles)
    for s in series:
        rows = np.atleast_2d(s.deviations_um)
        for row in rows:
            parts.append(
                f'<path d="{_path(_xy(scale.radius_mm(row), theta))}" fill="none" stroke="{s.color}" '
                f'stroke-width="{s.width * stroke:.3f}" stroke-opacity="{s.opacity:g}" stroke-linejoin="round"/>'
            )
    parts.append(tail)
    return "".join(parts)


def _layout(outer: float) -> tuple[float, float, float]:
    """(extent, font, stroke) of a chart whose outermost circle or profile is at `outer` (mm): the
    half-width of its square, its font size and its line width, one set for the frame and the profiles."""
    extent = 1.28 * outer
    return extent, 0.055 * extent, 0.004 * extent


@lru_cache(maxsize=64)
def _chart_frame(
    scale: PolarScale, outer: float, n_pt: int, point_labels: int, entries: tuple[tuple[str, str, float], ...]
) -> tuple[str, str]:
    """The parts of polar_svg that only the scale, the chart's size and the legend fix: the scale
    circles (under the profiles) and their labels, the point numbers, theta's arrow and the legend
    (over them).
    Kept: the explorer redraws the chart on every slider move, mostly on the same scale."""
    theta = 360.0 * np.arange(n_pt) / n_pt
    numbers_r = 1.08 * outer
    extent, font, stroke = _layout(outer)
    parts: list[str] = []
    labels: list[str] = []
    for text, radius in scale.labelled_circles():
        reference = text == scale_label(0.0)
        dash = "" if reference else f' stroke-dasharray="{3 * stroke:.3f} {3 * stroke:.3f}"'
        color = "#777" if reference else "#bbb"
        parts.append(
            f'<circle cx="0" cy="0" r="{radius:.3f}" fill="none" stroke="{color}" stroke-width="{(2 if reference else 1) * stroke:.3f}"{dash}/>'
        )
        # Labels along the 45-deg radius, drawn over the curves with a white halo: readable where a
        # profile crosses them (most do at the LS circle).
        x, y = _xy(np.array(radius), np.array(45.0))
        labels.append(
            f'<text x="{x:.3f}" y="{y:.3f}" font-size="{0.8 * font:.3f}" paint-order="stroke" stroke="#fff" '
            f'stroke-width="{0.25 * font:.3f}" fill="#555">{text}{" (LS circle)" if reference else ""}</text>'
        )
    circles = "".join(parts)
    parts = labels
    for k in range(0, n_pt, max(1, n_pt // point_labels)):
        x, y = _xy(np.array(numbers_r), np.array(theta[k]))
        parts.append(f'<text x="{x:.3f}" y="{y:.3f}" font-size="{font:.3f}" text-anchor="middle" dominant-baseline="middle">{k}</text>')
    # The direction of theta (and of the point numbers): an arc with an arrowhead beside point 0.
    arc = _xy(np.full(12, 1.17 * outer), np.linspace(8.0, 32.0, 12))
    tip, before = arc[-1], arc[-2]
    direction = (tip - before) / np.linalg.norm(tip - before)
    normal = np.array([-direction[1], direction[0]])
    head = [tip, tip - 0.5 * font * direction + 0.3 * font * normal, tip - 0.5 * font * direction - 0.3 * font * normal]
    parts.append(
        f'<path d="M{" L".join(f"{x:.3f},{y:.3f}" for x, y in arc)}" fill="none" stroke="#333" stroke-width="{1.5 * stroke:.3f}"/>'
    )
    parts.append(f'<path d="{_path(np.array(head))}" fill="#333"/>')
    x, y = _xy(np.array(1.24 * outer), np.array(20.0))
    parts.append(f'<text x="{x:.3f}" y="{y:.3f}" font-size="{font:.3f}" font-style="italic">θ</text>')
    # The legend, three entries a row, under the chart.
    for i, (label, color, opacity) in enumerate(entries):
        x = -extent + (i % 3) * (2 * extent / 3)
        y = extent + (i // 3 + 1) * 1.6 * font
        parts.append(
            f'<rect x="{x:.3f}" y="{y - 0.35 * font:.3f}" width="{1.2 * font:.3f}" height="{0.35 * font:.3f}" fill="{color}" fill-opacity="{opacity:g}"/>'
            f'<text x="{x + 1.5 * font:.3f}" y="{y:.3f}" font-size="{0.85 * font:.3f}">{label}</text>'
        )
    parts.append("</svg>")
    return circles, "".join(parts)


def curves_svg(
    scale: PolarScale,
    curves: Mapping[str, NDArray[np.float64]],
    shown: Mapping[str, bool],
    repetitions: NDArray[np.float64] | None,
    band: tuple[str, NDArray[np.float64], NDArray[np.float64]] | None,
    title: str,
) -> str:
    """The chart of a ring's named curves ("measured" and model names -> (n_pt,) um) in the explorer's
    colours, each repetition (n_rep, n_pt) faint under them when given, a model's band (name, low, high)."""
    series = []
    if repetitions is not None:
        series.append(PolarSeries(LEGEND_LABELS["repetitions"], repetitions, hex_color(curve_color("repetitions")), 0.8, 0.6))
    for name in CURVE_ORDER:
        if name in curves and shown.get(name, True):
            series.append(
                PolarSeries(LEGEND_LABELS.get(name, name), curves[name], hex_color(curve_color(name)), 2.5 if name == "measured" else 2.0)
            )
    drawn_band = (band[0], band[1], band[2], hex_color(BAND_COLORS.get(band[0], (200, 200, 200)))) if band is not None else None
    return polar_svg(scale, series, title, drawn_band)
