"""The error map over orientations: one figure per measured ring, drawn flat on A x B axes.

A figure is a value per ring (a roundness, a model's out-of-sample error, its ratio to the floor,
the within-noise test's verdict) with its unit. `map_svg` draws it as a readable chart: B across,
A up, ticks in degrees, a marker per measured ring (check rings as diamonds), the current
orientation marked, and a colour bar with round ticks in the figure's unit (or, for a verdict, a
legend of its categories). The explorer's Map tab and a report use the same SVG.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.figures.charts import nice_ticks, x_axis_svg, y_axis_svg

# A few stops of the viridis colormap (0..1 -> RGB): perceptually uniform, colour-blind safe.
VIRIDIS = np.array(
    [
        [68, 1, 84],
        [72, 40, 120],
        [62, 74, 137],
        [49, 104, 142],
        [38, 130, 142],
        [31, 158, 137],
        [53, 183, 121],
        [109, 205, 89],
        [180, 222, 44],
        [253, 231, 37],
    ],
    dtype=float,
)
NO_VALUE_RGB = 170  # grey: a ring where the figure does not exist (e.g. in sample for a model)
# A verdict's categories, in order of their value (0, 1, ...): calm for "within", red for "exceeds".
CATEGORY_COLORS = ("#8fb3d9", "#d62728", "#ff9f1c", "#2ca02c")
CURRENT = "#111"  # the current orientation's ring and cross hairs
PROPOSED = "#c2185b"  # rings proposed to measure (design --decide): magenta, apart from the bar and the verdicts' colours
A_TICK_DEG = 15.0
B_TICKS_DEG = tuple(range(-180, 181, 60))
STATIC_CACHE = 64  # maps (figure, rings) whose static SVG is kept: a few per browser
_STATIC: OrderedDict[tuple, tuple] = OrderedDict()
_STATIC_LOCK = threading.Lock()


@dataclass(frozen=True)
class MapFigure:
    """A value per measured ring (n_o,), its unit, what it is, and its categories when it is a verdict."""

    values: NDArray[np.float64]  # NaN where the figure does not exist at that ring
    unit: str  # "um", "x floor"; "" for a verdict
    note: str
    categories: tuple[str, ...] = ()  # value k means categories[k] (a verdict); empty: a continuous figure

    def text(self, value: float) -> str:
        """One value as the map and the lists write it, with its unit."""
        if not np.isfinite(value):
            return "—"
        if self.categories:
            return self.categories[int(value)]
        return f"{value:.3g} {self.unit}".strip()


def colormap(values: ArrayLike, low: float, high: float) -> NDArray[np.uint8]:
    """Viridis colours (n, 3) uint8 for values scaled from [low, high]; NaN -> grey."""
    v = np.asarray(values, dtype=float)
    t = np.clip((v - low) / (high - low if high > low else 1.0), 0.0, 1.0)
    x = np.nan_to_num(t) * (len(VIRIDIS) - 1)
    i = np.clip(np.floor(x).astype(int), 0, len(VIRIDIS) - 2)
    w = (x - i)[..., None]
    rgb = (1 - w) * VIRIDIS[i] + w * VIRIDIS[i + 1]
    rgb = np.where(np.isfinite(v)[..., None], rgb, float(NO_VALUE_RGB))
    return rgb.astype(np.uint8)


def value_range(values: ArrayLike) -> tuple[float, float]:
    """The finite values' min and max, (0, 1) when there is none."""
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    return (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)


def ranked_rings(figure: MapFigure, orientations: ArrayLike) -> list[tuple[float, float, float]]:
    """(A, B, value) of every ring with a value, largest first (the worst of an error)."""
    o = np.asarray(orientations, dtype=float)
    finite = np.flatnonzero(np.isfinite(figure.values))
    order = finite[np.argsort(-figure.values[finite], kind="stable")]
    return [(float(o[i, 0]), float(o[i, 1]), float(figure.values[i])) for i in order]


def _hex(rgb: ArrayLike) -> str:
    r, g, b = (int(c) for c in rgb)
    return f"#{r:02x}{g:02x}{b:02x}"


def a_axis_range(orientations: ArrayLike, current_a: float | None = None) -> tuple[float, float]:
    """The A axis: the measured A (and the current one), widened to whole A_TICK_DEG steps."""
    a = np.asarray(orientations, dtype=float).reshape(-1, 2)[:, 0]
    values = np.append(a, [] if current_a is None else [current_a])
    low = math.floor(min(0.0, float(values.min(initial=0.0))) / A_TICK_DEG) * A_TICK_DEG
    high = max(low + A_TICK_DEG, math.ceil(float(values.max(initial=90.0)) / A_TICK_DEG) * A_TICK_DEG)
    return low, high


def map_svg(
    figure: MapFigure,
    orientations: ArrayLike,
    check: ArrayLike,
    current: tuple[float, float] | None = None,
    title: str = "",
    proposed: ArrayLike | None = None,
) -> str:
    """The map as an SVG string (see the module docstring); sized by its viewBox to the panel's width.
    proposed: rings not measured yet (design --decide), drawn as crosses.

    Everything but the current orientation's and the proposed rings' markers is kept for the last
    few (figure, orientations) objects: a slider move redraws those only (the explorer draws the
    map on every move)."""
    o = np.asarray(orientations, dtype=float).reshape(-1, 2)
    a_low, a_high = a_axis_range(o, None if current is None else current[0])
    key = (id(figure), id(orientations), id(check), title, a_low, a_high)
    with _STATIC_LOCK:
        entry = _STATIC.get(key)
    # The objects themselves are kept in the entry, so an id is never another object's.
    if entry is None or entry[0] is not figure or entry[1] is not orientations or entry[2] is not check:
        entry = (figure, orientations, check, *_static_parts(figure, o, np.asarray(check, dtype=bool), title, a_low, a_high))
        with _STATIC_LOCK:
            _STATIC[key] = entry
            while len(_STATIC) > STATIC_CACHE:
                _STATIC.popitem(last=False)
    before, after, x_of, y_of, frame = entry[3:]
    crosses = _proposed_markers(np.asarray(proposed if proposed is not None else [], dtype=float).reshape(-1, 2), x_of, y_of, frame)
    if current is None:
        return before + crosses + after
    left, plot_w, top, bottom = frame
    # The current orientation: a black ring on a white halo with cross hairs, readable on every
    # colour of the bar and distinct from a verdict's red.
    x, y = float(x_of(current[1])), float(y_of(current[0]))
    marker = (
        f'<line x1="{left}" y1="{y:.1f}" x2="{left + plot_w}" y2="{y:.1f}" stroke="{CURRENT}" stroke-width="0.8" stroke-dasharray="3 3"/>'
        f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{bottom}" stroke="{CURRENT}" stroke-width="0.8" stroke-dasharray="3 3"/>'
        f'<circle cx="{x:.1f}" cy="{y:.1f}" r="9" fill="none" stroke="#fff" stroke-width="4.5"/>'
        f'<circle cx="{x:.1f}" cy="{y:.1f}" r="9" fill="none" stroke="{CURRENT}" stroke-width="2.2"/>'
    )
    return before + crosses + marker + after


def _proposed_markers(rings: NDArray[np.float64], x_of: Callable, y_of: Callable, frame: tuple[float, float, float, float]) -> str:
    """Rings proposed, not measured: a bold cross each, named in its tooltip, and their key."""
    if not len(rings):
        return ""
    left, plot_w, top, _ = frame
    parts = []
    for (a, b), x, y in zip(rings, x_of(rings[:, 1]), y_of(rings[:, 0])):
        d = 6.0
        parts.append(
            f'<path d="M{x - d:.1f},{y - d:.1f} L{x + d:.1f},{y + d:.1f} M{x - d:.1f},{y + d:.1f} L{x + d:.1f},{y - d:.1f}" '
            f'stroke="#fff" stroke-width="5"/><path d="M{x - d:.1f},{y - d:.1f} L{x + d:.1f},{y + d:.1f} M{x - d:.1f},{y + d:.1f} '
            f'L{x + d:.1f},{y - d:.1f}" stroke="{PROPOSED}" stroke-width="2.6"><title>A{a:g} B{b:g}: proposed, not measured yet</title></path>'
        )
    parts.append(
        f'<text x="{left + plot_w:.1f}" y="{top - 4:.1f}" font-size="10" fill="{PROPOSED}" font-weight="600" text-anchor="end">'
        "✕ rings that would decide (not measured)</text>"
    )
    return "".join(parts)


def _static_parts(
    figure: MapFigure, o: NDArray[np.float64], check: NDArray[np.bool_], title: str, a_low: float, a_high: float
) -> tuple[
    str, str, Callable[[ArrayLike], NDArray[np.float64]], Callable[[ArrayLike], NDArray[np.float64]], tuple[float, float, float, float]
]:
    """The map without the current orientation: (SVG before its marker, after it, x_of B, y_of A, (left, plot_w, top, bottom))."""
    width, left, right, top, plot_h = 400.0, 46.0, 12.0, 26.0, 210.0
    plot_w = width - left - right

    def x_of(b: ArrayLike) -> NDArray[np.float64]:
        b = (np.asarray(b, dtype=float) + 180.0) % 360.0 - 180.0
        b = np.where(np.asarray(b) == -180.0, -180.0, b)
        return left + (b + 180.0) / 360.0 * plot_w

    def y_of(a: ArrayLike) -> NDArray[np.float64]:  # A grows upwards
        return top + (a_high - np.asarray(a, dtype=float)) / (a_high - a_low) * plot_h

    bottom = top + plot_h
    bar_y = bottom + 42.0
    height = bar_y + 40.0
    parts = [
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {width:g} {height:g}" width="100%" role="img" '
        f'aria-label="error map {title}" style="font-family:sans-serif;background:#fff">',
        f'<text x="2" y="14" font-size="12" font-weight="600">{title}</text>',
        f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="#fafafa" stroke="#888" stroke-width="1"/>',
    ]
    # B across, A up, with the charts' shared axes; the B labels low enough to clear the A = 0 label.
    parts += x_axis_svg(B_TICKS_DEG, lambda b: float(x_of(b)) if b != 180 else left + plot_w, top, bottom, font_size=11, label_gap=16)
    parts.append(f'<text x="{left + plot_w / 2:.1f}" y="{bottom + 31}" font-size="12" text-anchor="middle">B (deg)</text>')
    a_ticks = np.arange(a_low, a_high + 0.5, A_TICK_DEG * (2 if a_high - a_low > 120 else 1))
    parts += y_axis_svg([float(a) for a in a_ticks], lambda a: float(y_of(a)), left, left + plot_w, font_size=11)
    parts.append(
        f'<text x="11" y="{top + plot_h / 2:.1f}" font-size="12" text-anchor="middle" '
        f'transform="rotate(-90 11 {top + plot_h / 2:.1f})">A (deg)</text>'
    )
    # Markers: the figure's colour; check rings as larger diamonds; rings without a value hollow.
    low, high = value_range(figure.values)
    if figure.categories:
        colors = [CATEGORY_COLORS[int(v) % len(CATEGORY_COLORS)] if np.isfinite(v) else _hex([NO_VALUE_RGB] * 3) for v in figure.values]
    else:
        colors = [_hex(c) for c in colormap(figure.values, low, high)]
    xs, ys = x_of(o[:, 1]), y_of(o[:, 0])
    for i in np.argsort(check, kind="stable"):  # check rings drawn last, on top
        x, y, color = float(xs[i]), float(ys[i]), colors[i]
        fill = color if np.isfinite(figure.values[i]) else "#fff"
        label = f"A{o[i, 0]:g} B{o[i, 1]:g}: {figure.text(float(figure.values[i]))}"
        if check[i]:
            parts.append(
                f'<path d="M{x:.1f},{y - 7:.1f} L{x + 7:.1f},{y:.1f} L{x:.1f},{y + 7:.1f} L{x - 7:.1f},{y:.1f} Z" '
                f'fill="{fill}" stroke="#000" stroke-width="1.4"><title>{label} (check ring)</title></path>'
            )
        else:
            parts.append(
                f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4.6" fill="{fill}" stroke="{"#555" if fill == "#fff" else "#fff"}" '
                f'stroke-width="0.6"><title>{label}</title></circle>'
            )
    before = "".join(parts)
    parts = []
    parts += _scale(figure, low, high, left, plot_w, bar_y)
    parts.append("</svg>")
    return before, "".join(parts), x_of, y_of, (left, plot_w, top, bottom)


def _scale(figure: MapFigure, low: float, high: float, left: float, plot_w: float, bar_y: float) -> list[str]:
    """Under the map: the colour bar with round ticks and the unit, or a verdict's legend; the marker key."""
    key = (
        f'<text x="{left}" y="{bar_y + 36}" font-size="10" fill="#444">● training ring  ◆ check ring  '
        f"○ no value  ringed: current orientation</text>"
    )
    if figure.categories:
        parts = []
        for k, name in enumerate(figure.categories):
            x = left + k * plot_w / max(len(figure.categories), 2)
            parts.append(
                f'<rect x="{x:.1f}" y="{bar_y:.1f}" width="14" height="10" fill="{CATEGORY_COLORS[k % len(CATEGORY_COLORS)]}"/>'
                f'<text x="{x + 18:.1f}" y="{bar_y + 9:.1f}" font-size="10.5">{name}</text>'
            )
        return parts + [key]
    stops = "".join(f'<stop offset="{k / (len(VIRIDIS) - 1):.3f}" stop-color="{_hex(c)}"/>' for k, c in enumerate(VIRIDIS))
    bar_w = plot_w - 40.0  # room for the unit at the right end
    parts = [
        f'<defs><linearGradient id="viridis">{stops}</linearGradient></defs>',
        f'<rect x="{left}" y="{bar_y:.1f}" width="{bar_w:.1f}" height="10" fill="url(#viridis)" stroke="#888" stroke-width="0.5"/>',
        f'<text x="{left + bar_w + 6:.1f}" y="{bar_y + 9:.1f}" font-size="10.5">{figure.unit}</text>',
    ]
    span = high - low if high > low else 1.0
    for t in nice_ticks(low, high):
        x = left + (t - low) / span * bar_w
        parts.append(
            f'<line x1="{x:.1f}" y1="{bar_y + 10:.1f}" x2="{x:.1f}" y2="{bar_y + 14:.1f}" stroke="#333"/>'
            f'<text x="{x:.1f}" y="{bar_y + 24:.1f}" font-size="10" text-anchor="middle">{t:g}</text>'
        )
    return parts + [key]
