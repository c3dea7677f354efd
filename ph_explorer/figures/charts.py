"""Flat SVG charts with round ticks: the shared axes (`nice_ticks`, `x_axis_svg`, `y_axis_svg`), the
signature plot of a candidate or of what is left (`evidence_svg`), the error history of a
diagnosis (`history_svg`), and curves or grouped bars (`line_chart_svg`, `bar_chart_svg`: the
deviation against point number, the harmonics). The explorer and the report draw the same strings.

Figures: docs/explorer.md.
"""

from __future__ import annotations

import html
import math
import re
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:  # the charts stay light: the map imports nice_ticks from here
    from ph_explorer.diagnosis.results import Step

# The signature chart: the binned out-of-sample residual as dots, the fitted term as a line.
RESIDUAL_COLOR, FITTED_COLOR = "#444444", "#d62728"
# The history chart: one colour per reference (solid the step's MAE, dashed its noise floor).
HISTORY_COLORS = {"mean": "#1f77b4", "single": "#d95f02"}
HISTORY_TITLE = "Check-ring MAE (um) per step"
GRID = "#e2e2e2"


def nice_ticks(low: float, high: float, count: int = 5) -> list[float]:
    """Round tick values (steps of 1, 2, 2.5 or 5 x 10^k) inside [low, high], about `count` of them."""
    if not (np.isfinite(low) and np.isfinite(high)) or high <= low:
        return [float(low)] if np.isfinite(low) else []
    raw = (high - low) / max(count - 1, 1)
    power = 10.0 ** math.floor(math.log10(raw))
    steps = [m * power for m in (0.5, 1.0, 2.0, 2.5, 5.0, 10.0)]
    step = next(s for s in steps if s >= raw)
    ticks: list[float] = []
    for step in [s for s in steps if s <= step][::-1]:  # finer steps until at least 3 ticks fall inside
        first = math.ceil(low / step - 1e-9) * step
        ticks = [round(first + k * step, 12) for k in range(int((high - first) / step + 1e-9) + 1)]
        if len(ticks) >= 3:
            break
    return ticks


def x_axis_svg(
    ticks: Iterable[float],
    x_of: Callable[[float], float],
    top: float,
    bottom: float,
    font_size: float,
    grid: bool = True,
    label_gap: float = 12,
) -> list[str]:
    """Tick labels under the plot at x_of(tick), with a vertical grid line each unless grid is False."""
    parts = []
    for t in ticks:
        x = float(x_of(t))
        line = f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{bottom}" stroke="{GRID}"/>' if grid else ""
        parts.append(line + f'<text x="{x:.1f}" y="{bottom + label_gap}" font-size="{font_size:g}" text-anchor="middle">{t:g}</text>')
    return parts


def y_axis_svg(
    ticks: Iterable[float],
    y_of: Callable[[float], float],
    left: float,
    right: float,
    font_size: float,
    zero_stroke: str = GRID,
) -> list[str]:
    """A horizontal grid line per tick across the plot and its label left of it; zero_stroke marks 0."""
    parts = []
    for t in ticks:
        y = float(y_of(t))
        stroke = zero_stroke if t == 0 else GRID
        parts.append(
            f'<line x1="{left}" y1="{y:.1f}" x2="{right}" y2="{y:.1f}" stroke="{stroke}"/>'
            f'<text x="{left - 4}" y="{y + 3.5:.1f}" font-size="{font_size:g}" text-anchor="end">{t:g}</text>'
        )
    return parts


def evidence_svg(evidence: dict, title: str) -> str:
    """A signature plot as a flat SVG chart, like the polar plot and the map: the binned out-of-sample
    residual (dots) and the fitted term (line) against the variable the evidence is read against,
    round ticks on both axes (nice_ticks), the units in the axis titles."""
    x = np.asarray(evidence["x"], dtype=float)
    residual, fitted = np.asarray(evidence["residual"], dtype=float), np.asarray(evidence["fitted"], dtype=float)
    # The y title runs above the plot, not up its side: a long one ("out-of-sample residual along
    # the fitted ring pattern (um)") is longer than the plot is tall.
    width, height, left, right, top, bottom = 400.0, 188.0, 40.0, 10.0, 34.0, 138.0
    x_low, x_high = float(x.min()), float(x.max())
    x_pad = 0.02 * (x_high - x_low if x_high > x_low else 1.0)  # the end bins' dots inside the frame
    x_low, x_high = x_low - x_pad, x_high + x_pad
    values = np.concatenate([residual[np.isfinite(residual)], fitted[np.isfinite(fitted)], [0.0]])
    y_low, y_high = float(values.min()), float(values.max())
    pad = 0.08 * (y_high - y_low if y_high > y_low else 1.0)  # dots off the frame
    y_low, y_high = y_low - pad, y_high + pad
    x_span = x_high - x_low if x_high > x_low else 1.0

    def sx(v: NDArray[np.float64] | float) -> NDArray[np.float64]:
        return left + (np.asarray(v, dtype=float) - x_low) / x_span * (width - left - right)

    def sy(v: NDArray[np.float64] | float) -> NDArray[np.float64]:
        return bottom - (np.asarray(v, dtype=float) - y_low) / (y_high - y_low) * (bottom - top)

    parts = [
        f'<svg viewBox="0 0 {width:g} {height:g}" width="100%" role="img" '
        f'aria-label="signature plot {title}" style="font-family:sans-serif;background:#fff">',
        f'<text x="2" y="14" font-size="11.5" font-weight="600">{_escaped(title)}</text>',
        f'<rect x="{left}" y="{top}" width="{width - left - right}" height="{bottom - top}" fill="#fafafa" stroke="#888"/>',
    ]
    parts += x_axis_svg(nice_ticks(x_low, x_high), sx, top, bottom, font_size=10)
    parts += y_axis_svg(nice_ticks(y_low, y_high, 4), sy, left, width - right, font_size=10, zero_stroke="#999")
    parts.append(
        f'<text x="{(left + width - right) / 2:.1f}" y="{bottom + 26}" font-size="10.5" text-anchor="middle">{_escaped(evidence["x_label"])}</text>'
    )
    parts.append(f'<text x="{left}" y="{top - 5}" font-size="10.5">{_escaped(evidence["y_label"])}</text>')
    order = np.argsort(x, kind="stable")
    line = " L".join(f"{a:.1f},{b:.1f}" for a, b in zip(sx(x[order]), sy(fitted[order])) if np.isfinite(b))
    parts.append(f'<path d="M{line}" fill="none" stroke="{FITTED_COLOR}" stroke-width="2"/>')
    parts += [f'<circle cx="{a:.1f}" cy="{b:.1f}" r="2.6" fill="{RESIDUAL_COLOR}"/>' for a, b in zip(sx(x), sy(residual)) if np.isfinite(b)]
    legend_y = height - 5  # under the x axis title, clear of it
    parts.append(
        f'<circle cx="{left + 4}" cy="{legend_y - 3.5}" r="2.6" fill="{RESIDUAL_COLOR}"/>'
        f'<text x="{left + 11}" y="{legend_y}" font-size="10">out-of-sample residual, binned</text>'
        f'<line x1="{left + 190}" y1="{legend_y - 3.5}" x2="{left + 206}" y2="{legend_y - 3.5}" stroke="{FITTED_COLOR}" stroke-width="2"/>'
        f'<text x="{left + 210}" y="{legend_y}" font-size="10">the term, fitted</text>'
    )
    parts.append("</svg>")
    return "".join(parts)


def step_names(steps: Sequence[Step]) -> list[str]:
    """Each step by what it added: "baseline", then "+ b_axis_cyclic" (the effects new at that step);
    a refit of the same effects is "refitted", one that took effects out "- lobing"."""
    names: list[str] = []
    before: list[str] | None = None
    for step in steps:
        new = [e for e in step.added if e not in (before or [])]
        gone = [e for e in (before or []) if e not in step.added]
        if not step.added:
            names.append("baseline")
        elif new:
            names.append("+ " + " + ".join(new))
        else:
            names.append("- " + " - ".join(gone) if gone else "refitted")
        before = list(step.added)
    return names


def wrapped(text: str, chars: int) -> list[str]:
    """text in lines of about `chars` characters, broken after a space or an underscore (effect ids)."""
    lines, line = [], ""
    for token in re.findall(r"[^ _]+[ _]?|[ _]", text):
        if line and len(line) + len(token.rstrip()) > chars:
            lines.append(line.rstrip())
            line = ""
        line += token
    return [*lines, line.rstrip()] if line.strip() else lines


def history_svg(steps: Sequence[Step], names: Sequence[str] | None = None) -> str:
    """The error history as a chart: MAE against the repetition mean and single repetitions per step
    (solid, dots), each with its noise floor (dashed), the steps named under the axis (`step_names`,
    or `names`), um up (round ticks), the legend under the names in the lines' own styles."""
    names = list(names) if names is not None else step_names(steps)
    width, left, right, top, plot_h, font = 420.0, 44.0, 10.0, 24.0, 150.0, 10.5
    plot_w = width - left - right
    n = len(steps)
    slot = plot_w / max(n, 1)
    label_lines = [wrapped(name, max(6, int(slot / (0.56 * font)))) for name in names]
    rows = max((len(lines) for lines in label_lines), default=1)
    mae = {ref: np.array([s.mae_um[ref] for s in steps], dtype=float) for ref in HISTORY_COLORS}
    floor = {ref: np.array([s.noise_floor_um[ref] for s in steps], dtype=float) for ref in HISTORY_COLORS}
    values = np.concatenate([*mae.values(), *floor.values()])
    values = values[np.isfinite(values)]
    high = float(values.max()) * 1.1 if values.size else 1.0
    ticks = nice_ticks(0.0, high)
    high = max(high, ticks[-1] if ticks else high)
    xs = left + (np.arange(n) + 0.5) * slot
    bottom = top + plot_h
    legend_top = bottom + 16 + 13 * (rows - 1) + 22  # under the last line of names
    height = legend_top + 2 * 15 + 4

    def y_of(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return bottom - np.asarray(v, dtype=float) / high * plot_h

    parts = [
        f'<svg viewBox="0 0 {width:g} {height:g}" width="100%" role="img" '
        'aria-label="history of the check-ring error" style="font-family:sans-serif;background:#fff">',
        f'<text x="2" y="13" font-size="11.5" font-weight="600">{HISTORY_TITLE}</text>',
        f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="#fafafa" stroke="#888"/>',
    ]
    parts += y_axis_svg(ticks, y_of, left, left + plot_w, font_size=font)
    for x, lines in zip(xs, label_lines):  # each step's name under its slot, on as many lines as it needs
        spans = "".join(f'<tspan x="{x:.1f}" dy="{0 if k == 0 else 13}">{_escaped(line)}</tspan>' for k, line in enumerate(lines))
        parts.append(f'<text x="{x:.1f}" y="{bottom + 16}" font-size="{font:g}" text-anchor="middle">{spans}</text>')
    half = 0.4 * slot  # a floor is a level across its step's width: one step shows it too
    for ref, color in HISTORY_COLORS.items():
        finite = np.isfinite(floor[ref])
        levels = " ".join(f"{x - half:.1f},{y:.1f} {x + half:.1f},{y:.1f}" for x, y in zip(xs[finite], y_of(floor[ref][finite])))
        parts.append(f'<polyline points="{levels}" fill="none" stroke="{color}" stroke-width="2" stroke-dasharray="5 4"/>')
        finite = np.isfinite(mae[ref])
        points = " ".join(f"{x:.1f},{y:.1f}" for x, y in zip(xs[finite], y_of(mae[ref][finite])))
        parts.append(f'<polyline points="{points}" fill="none" stroke="{color}" stroke-width="2.5"/>')
        for x, y, name, value, level in zip(xs, y_of(mae[ref]), names, mae[ref], floor[ref]):
            if math.isfinite(y):  # its figures on hover
                parts.append(
                    f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{color}"><title>{_escaped(name)}: '
                    f"{value:.3f} um vs {ref}, floor {level:.3f}</title></circle>"
                )
    for k, (ref, color) in enumerate(HISTORY_COLORS.items()):  # the legend: each line in its own style
        y = legend_top + 15 * k
        parts.append(
            f'<line x1="{left}" y1="{y - 3.5}" x2="{left + 22}" y2="{y - 3.5}" stroke="{color}" stroke-width="2.5"/>'
            f'<circle cx="{left + 11}" cy="{y - 3.5}" r="3.5" fill="{color}"/>'
            f'<text x="{left + 28}" y="{y}" font-size="{font:g}">MAE vs {ref}</text>'
            f'<line x1="{left + 170}" y1="{y - 3.5}" x2="{left + 192}" y2="{y - 3.5}" stroke="{color}" stroke-width="2" '
            f'stroke-dasharray="5 4"/><text x="{left + 198}" y="{y}" font-size="{font:g}">its noise floor</text>'
        )
    parts.append("</svg>")
    return "".join(parts)


def _escaped(text: str) -> str:
    return html.escape(text, quote=False)


Series = tuple[str, NDArray[np.float64], str]  # a chart's curve or bars: (label, values, colour)
Band = tuple[str, NDArray[np.float64], NDArray[np.float64], str]  # a shaded band: (label, low, high, colour)


def _frame(title: str, aria: str, width: float, height: float, left: float, top: float, plot_w: float, plot_h: float) -> list[str]:
    return [
        f'<svg viewBox="0 0 {width:g} {height:g}" width="100%" role="img" aria-label="{_escaped(aria)}" '
        'style="font-family:sans-serif;background:#fff">',
        f'<text x="2" y="13" font-size="11.5" font-weight="600">{_escaped(title)}</text>',
        f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="#fafafa" stroke="#888"/>',
    ]


def _legend(series: Sequence[Series], left: float, y: float, bars: bool, start: int = 0) -> list[str]:
    """One row per three entries under the x title, each in its series' own style (a line or a
    swatch); `start`: the place of the first entry (entries of another style before it)."""
    parts = []
    for k, (label, _, color) in enumerate(series, start=start):
        x, row = left + (k % 3) * 120.0, y + 14.0 * (k // 3)
        mark = (
            f'<rect x="{x}" y="{row - 8}" width="14" height="9" fill="{color}" fill-opacity="0.7" stroke="{color}"/>'
            if bars
            else f'<line x1="{x}" y1="{row - 3.5}" x2="{x + 16}" y2="{row - 3.5}" stroke="{color}" stroke-width="2"/>'
        )
        parts.append(mark + f'<text x="{x + 20}" y="{row}" font-size="10">{_escaped(label)}</text>')
    return parts


def line_chart_svg(
    x: NDArray[np.float64], series: Sequence[Series], title: str, x_label: str, y_label: str, bands: Sequence[Band] = ()
) -> str:
    """Curves against x (e.g. the deviation against point number), round ticks on both axes (the
    shared helpers), the y title above the plot, the legend under it in the curves' styles; each
    band (label, low, high, colour) a shaded area under the curves."""
    width, left, right, top, plot_h = 400.0, 40.0, 10.0, 34.0, 150.0
    plot_w, bottom = width - left - right, top + plot_h
    edges = [(label, np.concatenate([low, high]), color) for label, low, high, color in bands]
    values = np.concatenate([np.asarray(v, dtype=float).ravel() for _, v, _ in [*series, *edges]] or [np.zeros(1)])
    values = values[np.isfinite(values)]
    low, high = (float(values.min()), float(values.max())) if values.size else (-1.0, 1.0)
    pad = 0.06 * (high - low if high > low else 1.0)
    low, high = low - pad, high + pad
    x_low, x_high = float(np.min(x)), float(np.max(x))
    x_span = x_high - x_low if x_high > x_low else 1.0

    def sx(v: ArrayLike) -> NDArray[np.float64]:
        return left + (np.asarray(v, dtype=float) - x_low) / x_span * plot_w

    def sy(v: ArrayLike) -> NDArray[np.float64]:
        return bottom - (np.asarray(v, dtype=float) - low) / (high - low) * plot_h

    legend_y = bottom + 42.0
    height = legend_y + 14.0 * ((len(series) + len(bands) - 1) // 3) + 8.0
    parts = _frame(title, f"chart {title}", width, height, left, top, plot_w, plot_h)
    parts += x_axis_svg(nice_ticks(x_low, x_high), sx, top, bottom, font_size=10, label_gap=13)
    parts += y_axis_svg(nice_ticks(low, high, 5), sy, left, left + plot_w, font_size=10, zero_stroke="#999")
    parts.append(f'<text x="{left}" y="{top - 5}" font-size="10.5">{_escaped(y_label)}</text>')
    parts.append(f'<text x="{left + plot_w / 2:.1f}" y="{bottom + 27}" font-size="10.5" text-anchor="middle">{_escaped(x_label)}</text>')
    xs = sx(x).tolist()  # Python floats: formatted several times faster than numpy's scalars
    for _, band_low, band_high, color in bands:  # the upper edge forward, the lower back: one closed area
        outline = [*zip(xs, sy(band_high).tolist()), *reversed(list(zip(xs, sy(band_low).tolist())))]
        points = " ".join(f"{a:.1f},{b:.1f}" for a, b in outline if math.isfinite(b))
        parts.append(f'<polygon points="{points}" fill="{color}" fill-opacity="0.55" stroke="none"/>')
    for _, v, color in series:
        points = " ".join(f"{a:.1f},{b:.1f}" for a, b in zip(xs, sy(v).tolist()) if math.isfinite(b))
        parts.append(f'<polyline points="{points}" fill="none" stroke="{color}" stroke-width="1.8" stroke-linejoin="round"/>')
    parts += _legend(series, left, legend_y, bars=False)
    parts += _legend([(label, band_low, color) for label, band_low, _, color in bands], left, legend_y, bars=True, start=len(series))
    parts.append("</svg>")
    return "".join(parts)


def bar_chart_svg(x: NDArray[np.int64], series: Sequence[Series], title: str, x_label: str, y_label: str) -> str:
    """Grouped bars from zero at integer x (e.g. the amplitude per UPR), one colour per series, round
    ticks on both axes (the shared helpers), the legend under the plot in the bars' colours."""
    width, left, right, top, plot_h = 400.0, 40.0, 10.0, 34.0, 150.0
    plot_w, bottom = width - left - right, top + plot_h
    values = np.concatenate([np.asarray(v, dtype=float).ravel() for _, v, _ in series] or [np.zeros(1)])
    high = float(np.nanmax(values)) * 1.08 if values.size and np.nanmax(values) > 0 else 1.0
    ticks = nice_ticks(0.0, high, 4)
    x_low, x_high = float(np.min(x)) - 0.5, float(np.max(x)) + 0.5

    def sx(v: ArrayLike) -> NDArray[np.float64]:
        return left + (np.asarray(v, dtype=float) - x_low) / (x_high - x_low) * plot_w

    def sy(v: ArrayLike) -> NDArray[np.float64]:
        return bottom - np.asarray(v, dtype=float) / high * plot_h

    legend_y = bottom + 42.0
    height = legend_y + 14.0 * ((len(series) - 1) // 3) + 8.0
    parts = _frame(title, f"chart {title}", width, height, left, top, plot_w, plot_h)
    step = max(1, int(np.ceil(len(x) / 8)))  # about eight labelled bars' positions
    parts += x_axis_svg([int(v) for v in x[::step]], sx, top, bottom, font_size=10, grid=False, label_gap=13)
    parts += y_axis_svg(ticks, sy, left, left + plot_w, font_size=10)
    parts.append(f'<text x="{left}" y="{top - 5}" font-size="10.5">{_escaped(y_label)}</text>')
    parts.append(f'<text x="{left + plot_w / 2:.1f}" y="{bottom + 27}" font-size="10.5" text-anchor="middle">{_escaped(x_label)}</text>')
    bar = 0.8 / max(len(series), 1) * plot_w / (x_high - x_low)
    for j, (label, v, color) in enumerate(series):
        v = np.asarray(v, dtype=float)
        starts = (sx(np.asarray(x, dtype=float) - 0.4) + j * bar).tolist()
        tops = sy(np.nan_to_num(v)).tolist()
        name = _escaped(label)
        parts += [
            f'<rect x="{a:.1f}" y="{t:.1f}" width="{bar:.1f}" height="{bottom - t:.1f}" fill="{color}" fill-opacity="0.7">'
            f"<title>{name}, {k}: {value:.3g}</title></rect>"
            for a, t, k, value in zip(starts, tops, np.asarray(x).astype(int).tolist(), v.tolist())
        ]
    parts += _legend(series, left, legend_y, bars=True)
    parts.append("</svg>")
    return "".join(parts)
