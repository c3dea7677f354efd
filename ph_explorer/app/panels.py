"""Side panels of one browser: each panel owns its GUI elements and fills them from core results.

Panels never compute physics: they format what ph_explorer.app.dataset (i.e. the core) returns.
The Physics tab is in physics_panel.py.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path

import numpy as np
import viser
from numpy.typing import NDArray

from ph_explorer.app.dataset import Dataset
from ph_explorer.app.orientation_view import OrientationView
from ph_explorer.app.scene import BAND_COLORS, curve_color, hex_color
from ph_explorer.campaign import Campaign, orientation_label  # noqa: F401 (the app's panels import it from here)
from ph_explorer.figures.charts import bar_chart_svg, line_chart_svg
from ph_explorer.figures.orientation_map import MapFigure
from ph_explorer.figures.polar import CURVE_ORDER, LEGEND_LABELS, MAGNIFICATION_RANGE, PolarScale, curves_svg
from ph_explorer.geometry import wrap_deg
from ph_explorer.paper.tables import tables_markdown as orientation_tables_markdown

PAPER_PRESETS: dict[str, tuple[float, float]] = {
    "A15 B-20": (15.0, -20.0),
    "A75 B40": (75.0, 40.0),
    "A45 B-20": (45.0, -20.0),
    "A43 B90": (43.0, 90.0),
}
NO_CHOICE = "(choose)"
DEFAULT_MAGNIFICATION = 10000.0
MAX_UPR = 16


def wrap_b(b_deg: float) -> float:
    """B into [-180, 180), keeping 180 as written (both ends of the slider)."""
    return 180.0 if b_deg == 180.0 else float(wrap_deg(b_deg))


class ControlsPanel:
    """Orientation sliders, presets, curve switches, magnification, band, legend and camera views."""

    def __init__(self, gui: viser.GuiApi, a_deg: float, b_deg: float, a_range: tuple[float, float]) -> None:
        with gui.add_folder("Orientation"):
            self.a = gui.add_slider("A (deg)", *a_range, 1.0, float(a_deg), hint="tilt of the stylus, 0 = down")
            self.b = gui.add_slider("B (deg)", -180.0, 180.0, 1.0, float(b_deg), hint="turn about the quill axis")
            self.presets = gui.add_button_group("Paper", tuple(PAPER_PRESETS))
            self.worst = gui.add_dropdown("Worst", (NO_CHOICE,), hint="the orientations where the map's figure is largest")
            self.worst_targets: dict[str, tuple[float, float]] = {}  # option -> its orientation
            # Anything slow the session does with its data (a scenario switch, an upload): what and how far.
            self.busy_text = gui.add_markdown("", visible=False)
            self.busy = gui.add_progress_bar(0.0, visible=False)
        with gui.add_folder("Curves", expand_by_default=False):
            self.magnification = gui.add_slider(
                "Magnification", *MAGNIFICATION_RANGE, DEFAULT_MAGNIFICATION, hint="x: chart mm per mm of radial deviation"
            )
            self.show = {
                name: gui.add_checkbox(label, True)
                for name, label in (
                    ("measured", "Measured mean"),
                    ("network", "Network"),
                    ("trilinear", "Trilinear"),
                    ("gp", "Gaussian process"),
                    ("hybrid", "Hybrid"),
                )
            }
            self.repetitions = gui.add_checkbox("Each repetition (faint)", False)
            self.band = gui.add_dropdown("Monte Carlo band", ("none",), hint="95 % band of a model's Monte Carlo")
            self.band_of = gui.add_dropdown(
                "Band of",
                tuple(BAND_OF),
                hint="one touch's deviation, or the mean of the campaign's repetitions: the one to compare with the measured mean",
            )
            self.band_model_error = gui.add_checkbox(
                "Band: model uncertainty",
                initial_value=True,
                hint="With the model's own error (cross-validated, calibrated on the check rings); untick: the repeatability alone",
            )
            self.legend = gui.add_html("")
            self.follow = gui.add_checkbox("Camera follows the ring", True, hint="each move puts the ring in front of you")
            self.view_ring = gui.add_button_group("View", ("ring + head", "along the axis", "whole field"))

    def set_models(self, names: Sequence[str]) -> None:
        # A model's checkbox exists only while the model does (a hybrid after its first refit).
        for name, box in self.show.items():
            box.visible = name == "measured" or name in names
        self.band.options = ("none", *names)
        self.legend.content = legend_html(["measured", *names, "repetitions", "reference"])

    def set_a_range(self, low: float, high: float) -> None:
        """The A slider's range for new data (its value kept inside)."""
        self.a.min, self.a.max = float(low), float(high)
        if not low <= self.a.value <= high:
            self.a.value = float(np.clip(self.a.value, low, high))

    def set_worst(self, worst: Iterable[tuple[float, float, float]], figure: MapFigure, name: str) -> None:
        """The rings with the largest values of the map's figure, each with its value and unit."""
        self.worst_targets = {f"{orientation_label(a, b)} ({figure.text(v)})": (a, b) for a, b, v in worst}
        self.worst.options = (NO_CHOICE, *self.worst_targets)
        self.worst.value = NO_CHOICE
        self.worst.hint = f"largest values of the map's figure: {name}"

    def shown(self) -> dict[str, bool]:
        return {name: bool(box.value) and box.visible for name, box in self.show.items()}

    def band_kind(self) -> str:
        """What the band bounds: "touch" or "mean" (bands.gaussian_band's band)."""
        return BAND_OF[self.band_of.value]

    def working(self, text: str, fraction: float) -> None:
        """Show a slow step in progress under the orientation (above the fold)."""
        self.busy_text.content = f"_{text}_"
        self.busy_text.visible = self.busy.visible = True
        self.busy.value = float(np.clip(100.0 * fraction, 0.0, 100.0))

    def idle(self) -> None:
        self.busy_text.visible = self.busy.visible = False


def legend_html(names: Iterable[str]) -> str:
    items = []
    for name in names:
        color = hex_color(curve_color(name))
        label = LEGEND_LABELS.get(name, name)
        height = "2px" if name in ("repetitions", "reference") else "4px"
        items.append(
            f'<span style="display:inline-block;margin-right:10px;white-space:nowrap">'
            f'<span style="display:inline-block;width:18px;height:{height};background:{color};vertical-align:middle;'
            f'margin-right:4px"></span>{label}</span>'
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


# What the Monte Carlo band bounds: the option shown -> bands.gaussian_band's band.
BAND_OF = {"one touch": "touch", "the mean of the repetitions": "mean"}


class PolarPanel:
    """The flat polar chart of the current orientation, always facing the user (an SVG)."""

    def __init__(self, gui: viser.GuiApi) -> None:
        self.plot = gui.add_html("")

    def update(
        self,
        scale: PolarScale,
        view: OrientationView,
        shown: Mapping[str, bool],
        show_repetitions: bool,
        band: tuple[str, NDArray, NDArray] | None,
        title: str,
    ) -> None:
        """The SVG of the shown curves (the same colours as the 3D scene), repetitions under them."""
        self.plot.content = curves_svg(scale, view.curves, shown, view.repetitions if show_repetitions else None, band, title)


# At 1440x900 the polar plot (square, its legend under it) and the map (400 x 318 in its viewBox)
# fill a 400 px column one above the other; the controls take 400 px at the right, the 3D scene the rest.
FIGURES_WIDTH_PX = 400.0
CONTROLS_WIDTH_PX = 400.0


class FiguresPanel:
    """The flat polar plot and the error map, one above the other, in a panel docked at the left
    edge: in view whatever tab the controls show (the map's own choices are on the Map tab)."""

    def __init__(self, gui: viser.GuiApi) -> None:
        self.panel = gui.add_panel()
        with self.panel.add_tab("Polar plot, A×B errors"):
            self.polar = PolarPanel(gui)
            self.map_plot = gui.add_html("")
        # This browser's placement: the figures at the left, the controls docked at the right (the
        # server docks them for every browser; docking here again keeps them there once a panel
        # joins the left edge).
        self.panel.dock_left()
        gui.main_panel.dock_right()
        self.panel.set_width(FIGURES_WIDTH_PX)
        gui.main_panel.set_width(CONTROLS_WIDTH_PX)


class TablesPanel:
    """The paper's Tables 1-3 for the current orientation (markdown)."""

    def __init__(self, gui: viser.GuiApi) -> None:
        self.task = gui.add_checkbox(
            "RONt ± U of one measurement",
            initial_value=True,
            hint="Each model's Monte Carlo of one N-touch measurement here (its band's components), computed once the sliders rest",
        )
        self.markdown = gui.add_markdown("")

    def update(self, view: OrientationView, dataset: Dataset) -> None:
        self.markdown.content = tables_markdown(view, dataset, bool(self.task.value))


def task_cell(task: Mapping[str, float] | None) -> str:
    """'1.111 ± 0.327' with no-break spaces: the figure and its U never part in a narrow panel."""
    return "…" if task is None else f"{task['value']:.3f}\u00a0±\u00a0{task['U']:.3f}"


def tables_markdown(view: OrientationView, dataset: Dataset, with_task: bool = False) -> str:
    ront = note = None
    if with_task:
        # Beside Table 1: the range of one measurement as a distribution (issue 17, the task's RONt).
        tasks = {n: dataset.cached_task(n, view.a_deg, view.b_deg) for n in dataset.model_names}
        if view.measured:
            tasks["measured"] = dataset.measured_task(view.measured_index)
        ront = {n: task_cell(task) for n, task in tasks.items()}
        measured = "measured, the mean of the repetitions and twice their spread; " if view.measured else ""
        note = (
            f"_RONt ± U (k = 2) of one measurement of {dataset.campaign.n_points} touches: {measured}"
            "a model, its Monte Carlo with every component of its band (… while it computes)._"
        )
    return orientation_tables_markdown(
        view.tables, view.a_deg, view.b_deg, dataset.model_names, dataset.noise_floor_um, view.measured, view.held_out, ront, note or ""
    )


def deviation_chart(view: OrientationView, shown: Mapping[str, bool]) -> tuple[str, dict[str, NDArray[np.float64]]]:
    """The deviation (um) against point number of the shown curves, as an SVG chart, and what it drew."""
    drawn = {n: np.asarray(view.curves[n], dtype=float) for n in CURVE_ORDER if n in view.curves and shown.get(n, True)}
    n_pt = next(iter(view.curves.values())).size if view.curves else 64
    series = [(LEGEND_LABELS.get(n, n), v, hex_color(curve_color(n))) for n, v in drawn.items()]
    title = "Deviation against point number" + ("" if series else ": no curve shown")
    return line_chart_svg(np.arange(n_pt, dtype=float), series, title, "point number", "deviation (um)"), drawn


def harmonic_chart(view: OrientationView, shown: Mapping[str, bool], max_upr: int = MAX_UPR) -> tuple[str, dict[str, NDArray[np.float64]]]:
    """The amplitude (um) per UPR 2..max_upr of the shown curves, as grouped bars, and what it drew."""
    upr = np.arange(2, max_upr + 1)
    drawn = {}
    for n in (n for n in CURVE_ORDER if n in view.spectra and shown.get(n, True)):
        spectrum = np.zeros(upr.size)  # 0 beyond a curve's spectrum
        part = np.asarray(view.spectra[n], dtype=float)[2 : max_upr + 1]
        spectrum[: part.size] = part
        drawn[n] = spectrum
    series = [(LEGEND_LABELS.get(n, n), v, hex_color(curve_color(n))) for n, v in drawn.items()]
    title = "Harmonics: amplitude per UPR" + ("" if series else ": no curve shown")
    return bar_chart_svg(upr, series, title, "UPR (undulations per revolution)", "amplitude (um)"), drawn


class ChartsPanel:
    """The deviation and harmonic charts of the current orientation (flat SVG, the shared axes)."""

    def __init__(self, gui: viser.GuiApi, view: OrientationView, shown: Mapping[str, bool]) -> None:
        self.deviation, self.harmonics = gui.add_html(""), gui.add_html("")
        self.drawn: dict[str, dict[str, NDArray[np.float64]]] = {}  # chart -> curve -> values drawn (tests read it)
        self.update(view, shown)

    def update(self, view: OrientationView, shown: Mapping[str, bool]) -> None:
        for key, handle, chart in (("deviation", self.deviation, deviation_chart), ("harmonics", self.harmonics, harmonic_chart)):
            svg, self.drawn[key] = chart(view, shown)
            if handle.content != svg:
                handle.content = svg


class DataPanel:
    """Where the session's data came from; scenario picker and CSV upload, with the reader's error line."""

    def __init__(self, gui: viser.GuiApi, scenarios: Mapping[str, str]) -> None:
        """scenarios: name -> its purpose, shown beside the name (a teacher picks by what each is for)."""
        self.source = gui.add_markdown("")
        self.names = {(f"{name} · {purpose}" if purpose else name): name for name, purpose in scenarios.items()}
        self.scenario = gui.add_dropdown("Scenario", (NO_CHOICE, *self.names), hint="a campaign simulated by the twin")
        self.upload = gui.add_upload_button("Upload a campaign CSV", mime_type=".csv,text/csv,text/plain")
        # The command line reads NAME.toml beside NAME.csv; a browser sends one file at a time.
        self.sidecar = gui.add_upload_button(
            "Upload its sidecar TOML", mime_type=".toml,application/toml,text/plain", hint="the uploaded CSV's check rings and geometry"
        )
        self.message = gui.add_markdown("")

    def set_source(self, dataset: Dataset) -> None:
        c = dataset.campaign
        notes = "".join(f"\n- {n}" for n in dataset.notes)
        self.source.content = (
            f"**{dataset.label}** — {c.n_orientations} orientations x {c.n_repetitions} repetitions x "
            f"{c.n_points} points; repetition sigma {c.noise_sigma_um():.3f} um.{notes}"
        )

    def show_loaded(self, campaign: Campaign, sidecar: str | None) -> None:
        """What an upload was read with: its sidecar's check rings and geometry, or the defaults."""
        checks, length = int(campaign.holdout_mask().sum()), campaign.geometry.pivot_to_ball_mm
        if sidecar is None:
            self.message.content = (
                f"Loaded **{campaign.source}** without a sidecar: {checks} check rings by the default rule, pivot to "
                f"ball {length:g} mm. If it has a sidecar TOML (its check rings, its geometry), upload it too."
            )
        else:
            self.message.content = f"Loaded **{campaign.source}** with its sidecar **{Path(sidecar).name}**: {checks} check rings, pivot to ball {length:g} mm."

    def show_error(self, line: str) -> None:
        self.message.content = f"**Not loaded** — {line}\n\nThe session keeps its current data."

    def forget(self, keep: str) -> None:
        """New data: the scenario box names no scenario unless the data is that scenario (`keep`)."""
        if self.chosen() != keep:
            self.scenario.value = NO_CHOICE

    def chosen(self) -> str | None:
        """The scenario chosen in the box, by name; None for no choice."""
        return self.names.get(self.scenario.value)

    def label_of(self, name: str) -> str:
        """The box's entry for a scenario name (as a browser would choose it)."""
        return next(label for label, n in self.names.items() if n == name)

    def show_info(self, text: str) -> None:
        self.message.content = text
