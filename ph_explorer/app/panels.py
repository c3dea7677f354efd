"""Side panels of one browser: each panel owns its GUI elements and fills them from core results.

Panels never compute physics: they format what ph_explorer.app.dataset (i.e. the core) returns.
"""

from __future__ import annotations

from typing import Any, Iterable, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from ph_explorer.app.dataset import Dataset, OrientationView
from ph_explorer.app.scene import BAND_COLORS, curve_color, hex_color

PAPER_PRESETS: dict[str, tuple[float, float]] = {
    "A15 B-20": (15.0, -20.0),
    "A75 B40": (75.0, 40.0),
    "A45 B-20": (45.0, -20.0),
    "A43 B90": (43.0, 90.0),
}
NO_CHOICE = "(choose)"
MAX_UPR = 16


def orientation_label(a_deg: float, b_deg: float) -> str:
    return f"A{a_deg:g} B{b_deg:g}"


def parse_orientation_label(label: str) -> tuple[float, float] | None:
    """'A43 B90 ...' -> (43.0, 90.0)."""
    try:
        a_part, b_part = label.split()[:2]
        return float(a_part[1:]), float(b_part[1:])
    except (ValueError, IndexError):
        return None


def _fmt(value: Any) -> str:
    return "—" if value is None or (isinstance(value, float) and not np.isfinite(value)) else f"{value:.2f}"


class ControlsPanel:
    """Orientation sliders, presets, curve switches, magnification, band, legend and camera views."""

    def __init__(self, gui: Any, a_deg: float, b_deg: float) -> None:
        with gui.add_folder("Orientation"):
            self.a = gui.add_slider("A (deg)", 0.0, 115.0, 1.0, float(a_deg), hint="tilt of the stylus, 0 = down")
            self.b = gui.add_slider("B (deg)", -180.0, 180.0, 1.0, float(b_deg), hint="turn about the quill axis")
            self.presets = gui.add_button_group("Paper", tuple(PAPER_PRESETS))
            self.worst = gui.add_dropdown("Worst", (NO_CHOICE,), hint="the orientations where the field's figure is largest")
            self.status = gui.add_markdown("")
        with gui.add_folder("Curves"):
            self.magnification = gui.add_slider("Magnification", 1000.0, 20000.0, 500.0, 5000.0, hint="x: radial deviation scale")
            self.show = {
                name: gui.add_checkbox(label, True)
                for name, label in (
                    ("measured", "Measured mean"),
                    ("network", "Network"),
                    ("trilinear", "Trilinear"),
                    ("hybrid", "Hybrid"),
                )
            }
            self.repetitions = gui.add_checkbox("Each repetition (faint)", False)
            self.band = gui.add_dropdown("Monte Carlo band", ("none",), hint="95 % of simulated measurements of a model")
            self.legend = gui.add_html("")
            self.view_head = gui.add_button("View the head")
            self.view_ring = gui.add_button("View the ring (along its axis)")

    def set_models(self, names: Sequence[str]) -> None:
        for name, box in self.show.items():
            box.disabled = name != "measured" and name not in names
        self.band.options = ("none", *names)
        self.legend.content = legend_html(["measured", "repetitions", *names])

    def set_worst(self, worst: Iterable[tuple[float, float, float]], unit_note: str) -> None:
        options = [NO_CHOICE] + [f"{orientation_label(a, b)} ({v:.3g})" for a, b, v in worst]
        self.worst.options = tuple(options)
        self.worst.value = NO_CHOICE
        self.worst.hint = f"largest values of the field's figure ({unit_note})"

    def shown(self) -> dict[str, bool]:
        return {name: bool(box.value) and not box.disabled for name, box in self.show.items()}


def legend_html(names: Iterable[str]) -> str:
    items = []
    for name in names:
        color = hex_color(curve_color(name))
        items.append(
            f'<span style="display:inline-block;margin-right:10px;white-space:nowrap">'
            f'<span style="display:inline-block;width:18px;height:4px;background:{color};vertical-align:middle;'
            f'margin-right:4px"></span>{name}</span>'
        )
    bands = [n for n in names if n in BAND_COLORS]
    if bands:
        swatches = "".join(
            f'<span style="display:inline-block;width:14px;height:10px;background:{hex_color(BAND_COLORS[n])};'
            f'vertical-align:middle;margin:0 4px 0 6px"></span>{n}'
            for n in bands
        )
        items.append(f'<div style="white-space:nowrap">Monte Carlo 95 % band:{swatches}</div>')
    return '<div style="font-size:0.8em;line-height:1.8em">' + "".join(items) + "</div>"


class TablesPanel:
    """The paper's Tables 1-3 for the current orientation (markdown)."""

    def __init__(self, gui: Any) -> None:
        with gui.add_folder("Tables 1-3 (paper)"):
            self.markdown = gui.add_markdown("")

    def update(self, view: OrientationView, dataset: Dataset) -> None:
        self.markdown.content = tables_markdown(view, dataset)


def tables_markdown(view: OrientationView, dataset: Dataset) -> str:
    t = view.tables
    names = ["measured", *dataset.model_names] if view.measured else list(dataset.model_names)
    heading = orientation_label(view.a_deg, view.b_deg)
    if not view.measured:
        heading += " — not measured: model **predictions** only"
    elif view.held_out:
        heading += " — measured, held out of training (check ring)"
    else:
        heading += " — measured, a training ring"
    lines = [f"**{heading}**", ""]
    header = "| um | " + " | ".join(names) + " |"
    rule = "|---|" + "---|" * len(names)
    lines += ["Table 1 — range, Table 2 — max |deviation|", "", header, rule]
    lines.append("| range | " + " | ".join(_fmt(t["range_um"].get(n)) for n in names) + " |")
    lines.append("| max abs | " + " | ".join(_fmt(t["max_abs_um"].get(n)) for n in names) + " |")
    lines.append("")
    if t["mae_um"]:
        models = list(t["mae_um"])
        lines += ["Table 3 — mean absolute simulation error", "", "| um | " + " | ".join(models) + " |", "|---|" + "---|" * len(models)]
        lines.append("| vs mean | " + " | ".join(_fmt(t["mae_um"][m]["mean"]) for m in models) + " |")
        lines.append("| vs single | " + " | ".join(_fmt(t["mae_um"][m]["single"]) for m in models) + " |")
        floor = dataset.noise_floor_um
        if floor:
            lines += ["", f"Noise floor: {floor['mean']:.3f} um vs mean, {floor['single']:.3f} um vs single repetitions."]
        if not view.held_out:
            lines += ["", "_A training ring: the models saw it, so Table 3 here is in sample._"]
    else:
        lines.append("Table 3 needs a measurement at this orientation.")
    return "\n".join(lines)


def deviation_chart_data(view: OrientationView, shown: Mapping[str, bool]) -> tuple[tuple[NDArray, ...], tuple[dict, ...]]:
    """uPlot data and series: deviation (um) against point number for the shown curves."""
    names = [n for n in ("measured", "network", "trilinear", "hybrid") if n in view.curves and shown.get(n, True)]
    n_pt = next(iter(view.curves.values())).size if view.curves else 64
    x = np.arange(n_pt, dtype=float)
    data = (x, *(np.asarray(view.curves[n], dtype=float) for n in names))
    series = ({"label": "point"}, *({"label": n, "stroke": hex_color(curve_color(n)), "width": 2} for n in names))
    if not names:  # uPlot needs a y series: an honest flat zero labelled as such
        data = (x, np.zeros(n_pt))
        series = ({"label": "point"}, {"label": "no curve shown", "stroke": "#bbbbbb", "width": 1})
    return data, series


def harmonic_chart_data(view: OrientationView, shown: Mapping[str, bool], max_upr: int = MAX_UPR) -> tuple[tuple[NDArray, ...], tuple[dict, ...]]:
    """uPlot data and series drawing grouped bars: amplitude (um) per UPR 2..max_upr for each curve.

    uPlot has no bar renderer without JavaScript callbacks, so each bar is drawn as a filled
    rectangle path (0 -> a -> a -> 0) on a shared x axis where the other curves sit at 0.
    """
    names = [n for n in ("measured", "network", "trilinear", "hybrid") if n in view.spectra and shown.get(n, True)]
    if not names:
        x = np.array([2.0, float(max_upr)])
        return (x, np.zeros(2)), ({"label": "UPR"}, {"label": "no curve shown", "stroke": "#bbbbbb"})
    upr = np.arange(2, max_upr + 1)
    width = 0.8 / len(names)
    xs, ys = [], {n: [] for n in names}
    for k in upr:
        for j, n in enumerate(names):
            left = k - 0.4 + j * width
            xs += [left, left + 0.02 * width, left + 0.98 * width, left + width]
            spectrum = view.spectra[n]
            amp = float(spectrum[k]) if k < spectrum.size else 0.0
            for m in names:
                ys[m] += [0.0, amp, amp, 0.0] if m == n else [0.0, 0.0, 0.0, 0.0]
    data = (np.array(xs), *(np.array(ys[n]) for n in names))
    series = (
        {"label": "UPR"},
        *(
            {"label": n, "stroke": hex_color(curve_color(n)), "fill": hex_color(curve_color(n)) + "99", "width": 1, "points": {"show": False}}
            for n in names
        ),
    )
    return data, series


class ChartsPanel:
    """Deviation against point number, and the harmonic (UPR) bar chart, for the shown curves."""

    def __init__(self, gui: Any, view: OrientationView, shown: Mapping[str, bool]) -> None:
        with gui.add_folder("Charts"):
            data, series = deviation_chart_data(view, shown)
            self.deviation = gui.add_uplot(
                data,
                series,
                title="Deviation (um) against point number",
                aspect=1.6,
                scales={"x": {"time": False}},
                axes=({"label": "point"}, {"label": "um"}),
            )
            data, series = harmonic_chart_data(view, shown)
            self.harmonics = gui.add_uplot(
                data,
                series,
                title="Harmonics: amplitude (um) per UPR",
                aspect=1.6,
                scales={"x": {"time": False}},
                axes=({"label": "UPR"}, {"label": "um"}),
            )

    def update(self, view: OrientationView, shown: Mapping[str, bool]) -> None:
        data, series = deviation_chart_data(view, shown)
        if tuple(self.deviation.series) != series:
            self.deviation.series = series
        self.deviation.data = data
        data, series = harmonic_chart_data(view, shown)
        if tuple(self.harmonics.series) != series:
            self.harmonics.series = series
        self.harmonics.data = data


class FieldPanel:
    """Which per-orientation figure colours the error field, its scale, and whether it shows."""

    def __init__(self, gui: Any, names: Sequence[str]) -> None:
        with gui.add_folder("Error field"):
            self.figure = gui.add_dropdown("Colour by", tuple(names))
            self.show = gui.add_checkbox("Show the field", True)
            self.scale = gui.add_html("")
            self.note = gui.add_markdown("")

    def set_names(self, names: Sequence[str]) -> None:
        self.figure.options = tuple(names)

    def set_scale(self, low: float, high: float, note: str, computing: bool = False) -> None:
        if computing:
            self.scale.content = "<em>computing…</em>"
            self.note.content = ""
            return
        self.scale.content = (
            '<div style="font-size:0.8em">'
            f'<div style="height:10px;background:linear-gradient(to right,#440154,#3e4a89,#26828e,#35b779,#fde725)"></div>'
            f'<div style="display:flex;justify-content:space-between"><span>{low:.3g}</span><span>{high:.3g}</span></div>'
            "</div>"
        )
        self.note.content = f"_{note}. Large markers: held-out rings; red: the current orientation; click a marker to go there._"


class DataPanel:
    """Where the session's data came from; scenario picker and CSV upload, with the reader's error line."""

    def __init__(self, gui: Any, scenarios: Sequence[str]) -> None:
        with gui.add_folder("Data", expand_by_default=False):
            self.source = gui.add_markdown("")
            self.scenario = gui.add_dropdown(
                "Scenario",
                (NO_CHOICE, *scenarios) if scenarios else ("(twin not in this build)",),
                disabled=not scenarios,
            )
            self.upload = gui.add_upload_button("Upload a campaign CSV", mime_type=".csv,text/csv,text/plain")
            self.message = gui.add_markdown("")

    def set_source(self, dataset: Dataset) -> None:
        c = dataset.campaign
        notes = "".join(f"\n- {n}" for n in dataset.notes)
        self.source.content = (
            f"**{dataset.label}** — {c.n_orientations} orientations x {c.n_repetitions} repetitions x "
            f"{c.n_points} points; repetition sigma {c.noise_sigma_um():.3f} um.{notes}"
        )

    def show_error(self, line: str) -> None:
        self.message.content = f"**Not loaded** — {line}\n\nThe session keeps its current data."

    def show_info(self, text: str) -> None:
        self.message.content = text


class PhysicsPanel:
    """Diagnose -> add an effect -> refit -> the error falls; reveal the hidden effect.

    Built against ph_explorer.diagnosis (diagnose, HybridModel); when it is not in this build the
    widgets stay disabled with an honest label and no figures.
    """

    def __init__(self, gui: Any, available: bool, effect_names: Mapping[str, str]) -> None:
        with gui.add_folder("Physics: diagnose and add effects", expand_by_default=False):
            self.status = gui.add_markdown(
                ""
                if available
                else "_The diagnosis core (ph_explorer.diagnosis) is not in this build yet: diagnose, effects and refit are disabled._"
            )
            self.diagnose = gui.add_button("Diagnose", disabled=not available)
            self.result = gui.add_markdown("")
            self.effects = {
                effect_id: gui.add_checkbox(name, False, disabled=not available, hint=f"add {effect_id} to the hybrid")
                for effect_id, name in effect_names.items()
            }
            self.refit = gui.add_button("Refit the hybrid", disabled=not available)
            self.progress = gui.add_progress_bar(0.0, visible=False)
            self.history = gui.add_uplot(
                (np.array([0.0, 1.0]), np.zeros(2), np.zeros(2)),
                ({"label": "step"}, {"label": "MAE (um)", "stroke": "#2a9d3c", "width": 2}, {"label": "noise floor", "stroke": "#999999", "dash": (5.0, 5.0)}),
                title="Out-of-sample MAE per step",
                aspect=1.8,
                scales={"x": {"time": False}},
                visible=False,
            )
            self.reveal = gui.add_button("Reveal the hidden effect", disabled=not available)
            self.revealed = gui.add_markdown("")

    def show_history(self, steps: Sequence[tuple[str, float]], floor: float | None) -> None:
        if not steps:
            self.history.visible = False
            return
        x = np.arange(len(steps), dtype=float)
        y = np.array([v for _, v in steps], dtype=float)
        if x.size == 1:  # uPlot draws a line from two points at least
            x, y = np.array([0.0, 1.0]), np.repeat(y, 2)
        f = np.full(x.size, np.nan if floor is None else floor)
        self.history.data = (x, y, f)
        self.history.visible = True

    def selected_effects(self) -> list[str]:
        return [e for e, box in self.effects.items() if box.value]
