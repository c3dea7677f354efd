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
DEFAULT_MAGNIFICATION = 10000.0
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
            self.magnification = gui.add_slider(
                "Magnification", 1000.0, 20000.0, 500.0, DEFAULT_MAGNIFICATION, hint="x: radial deviation scale"
            )
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
            self.follow = gui.add_checkbox("Camera follows the ring", True, hint="each move puts the ring in front of you")
            self.view_ring = gui.add_button_group("View", ("ring + head", "along the axis", "whole field"))

    def set_models(self, names: Sequence[str]) -> None:
        for name, box in self.show.items():
            box.disabled = name != "measured" and name not in names
        self.band.options = ("none", *names)
        self.legend.content = legend_html(["measured", *names, "repetitions", "reference"])

    def set_worst(self, worst: Iterable[tuple[float, float, float]], unit_note: str) -> None:
        options = [NO_CHOICE] + [f"{orientation_label(a, b)} ({v:.3g})" for a, b, v in worst]
        self.worst.options = tuple(options)
        self.worst.value = NO_CHOICE
        self.worst.hint = f"largest values of the field's figure ({unit_note})"

    def shown(self) -> dict[str, bool]:
        return {name: bool(box.value) and not box.disabled for name, box in self.show.items()}


LEGEND_LABELS = {"measured": "measured mean", "repetitions": "each repetition", "reference": "circle R, ±1 um"}


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


class TablesPanel:
    """The paper's Tables 1-3 for the current orientation (markdown)."""

    def __init__(self, gui: Any) -> None:
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
        self.source = gui.add_markdown("")
        self.scenario = gui.add_dropdown("Scenario", (NO_CHOICE, *scenarios), hint="a campaign simulated by the twin")
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


# Error history: one colour per reference, solid = MAE of the step, dashed = that step's noise floor.
HISTORY_SERIES = (
    {"label": "step"},
    {"label": "MAE vs mean", "stroke": "#2a9d3c", "width": 2, "points": {"show": True, "size": 7}},
    {"label": "floor (mean)", "stroke": "#2a9d3c", "width": 1, "dash": (6.0, 4.0), "points": {"show": False}},
    {"label": "MAE vs single", "stroke": "#7b3fa0", "width": 2, "points": {"show": True, "size": 7}},
    {"label": "floor (single)", "stroke": "#7b3fa0", "width": 1, "dash": (6.0, 4.0), "points": {"show": False}},
)
EVIDENCE_SERIES = (
    {"label": "x"},
    {"label": "out-of-sample residual", "stroke": "#444444", "width": 0, "points": {"show": True, "size": 5, "fill": "#444444"}},
    {"label": "candidate, fitted", "stroke": "#d62728", "width": 2, "points": {"show": False}},
)


def parameter_text(name: str, value: float, unit: str) -> str:
    """'amplitude_arcsec', 0.95, 'arcsec' -> 'amplitude 0.95 arcsec'; 'cycles_per_rev', 22, '1/rev' -> 'cycles per rev 22'."""
    label = name
    written = unit.replace("/", "_per_")  # 'um/h' is spelled 'um_per_h' in parameter names
    if unit and label.endswith("_" + written):
        label = label[: -len(written) - 1]
    elif unit == "1/rev" and label.endswith("per_rev"):
        unit = ""  # 'cycles per rev' says it
    return f"{label.replace('_', ' ')} {value:.3g}" + (f" {unit}" if unit else "")


def parameters_text(params: Mapping[str, float], units: Mapping[str, str]) -> str:
    return ", ".join(parameter_text(k, float(v), units.get(k, "")) for k, v in params.items())


def step_label(added: Sequence[str], baseline: str) -> str:
    return f"baseline ({baseline})" if not added else "+ " + " + ".join(added)


def history_data(steps: Sequence[Any]) -> tuple[NDArray[np.float64], ...]:
    """uPlot data of the error history: per step, MAE and floor against the mean and single repetitions."""
    x = np.arange(len(steps), dtype=float)
    get = lambda attr, ref: np.array([float(getattr(s, attr)[ref]) for s in steps])
    return (x, get("mae_um", "mean"), get("noise_floor_um", "mean"), get("mae_um", "single"), get("noise_floor_um", "single"))


def candidates_html(candidates: Sequence[Any], units: Mapping[str, Mapping[str, str]], limit: int = 8) -> str:
    """The ranked candidates: explained share, fall of the held-out error, what noise explains, significance."""
    cell = "padding:2px 4px;"
    head = (
        '<table style="width:100%;border-collapse:collapse;font-size:0.75em;line-height:1.3em;table-layout:fixed">'
        '<colgroup><col style="width:49%"><col style="width:17%"><col style="width:15%"><col style="width:13%">'
        '<col style="width:6%"></colgroup>'
        f'<tr style="border-bottom:1px solid #bbb;text-align:right"><th style="text-align:left;{cell}">effect</th>'
        f'<th style="{cell}" title="share of the out-of-sample residual it explains">explains</th>'
        f'<th style="{cell}" title="fall of the held-out rms error against the reference that exposes it">error&nbsp;&darr;</th>'
        f'<th style="{cell}" title="the most the same scan explains on pure noise">noise</th><th></th></tr>'
    )
    rows = []
    for rank, c in enumerate(candidates[:limit], 1):
        style = "font-weight:600;" if c.significant else "color:#777;"
        params = ""
        if c.significant:  # a non-significant fit's parameters describe noise: not shown as findings
            params = f'<div style="font-weight:400;color:#1f6f2f">{parameters_text(c.params, units.get(c.effect, {}))}</div>'
        mark = '<span title="significant" style="color:#2a9d3c">&#10004;</span>' if c.significant else ""
        rows.append(
            f'<tr style="border-bottom:1px solid #eee;text-align:right;vertical-align:top;{style}">'
            f'<td style="text-align:left;{cell}overflow-wrap:anywhere">{rank}. {c.effect}{params}</td>'
            f'<td style="{cell}">{100.0 * c.explained_fraction:.1f}&nbsp;%</td>'
            f'<td style="{cell}">{100.0 * c.error_reduction:.0f}&nbsp;%</td>'
            f'<td style="{cell}">{100.0 * c.noise_fraction:.2f}&nbsp;%</td><td style="{cell}">{mark}</td></tr>'
        )
    more = f'<div style="font-size:0.75em;color:#777">… and {len(candidates) - limit} more</div>' if len(candidates) > limit else ""
    legend = (
        '<div style="font-size:0.72em;color:#666;margin-top:3px">explains: share of what the baseline cannot predict '
        "out of sample; error &darr;: fall of the check-ring rms error; noise: the most the same scan explains on "
        "pure noise; &#10004;: significant.</div>"
    )
    return head + "".join(rows) + "</table>" + more + legend


class PhysicsPanel:
    """Diagnose -> add an effect -> refit -> the error falls; reveal the hidden effect.

    Formats what ph_explorer.diagnosis returns (Diagnosis, Candidate, Step); computes nothing.
    """

    def __init__(self, gui: Any, effect_names: Mapping[str, str]) -> None:
        self.diagnose = gui.add_button("Diagnose", hint="where the trilinear baseline fails out of sample, and which catalog effect is missing")
        self.status = gui.add_markdown("")
        self.progress = gui.add_progress_bar(0.0, visible=False)
        self.summary = gui.add_markdown("")
        self.candidates = gui.add_html("")
        self.verdict = gui.add_markdown("")
        self.evidence_of = gui.add_dropdown("Evidence of", (NO_CHOICE,), visible=False, hint="a candidate's residual and fitted terms")
        self.evidence = gui.add_uplot(
            (np.array([0.0, 1.0]), np.zeros(2), np.zeros(2)),
            EVIDENCE_SERIES,
            title="Evidence",
            aspect=1.6,
            scales={"x": {"time": False}},
            axes=({"label": "x"}, {"label": "um"}),
            visible=False,
        )
        self.evidence_text = gui.add_markdown("")
        self.effects_label = gui.add_markdown("**Effects in the hybrid** (tick, then Refit):")
        # Labelled by id (as in the candidates table): the panel's label column is narrow.
        self.effects = {
            effect_id: gui.add_checkbox(effect_id, False, hint=f"{name}: add it to the hybrid's physical terms")
            for effect_id, name in effect_names.items()
        }
        self.refit = gui.add_button("Refit the hybrid", hint="fit the ticked effects + the trilinear part; measure on the check rings")
        self.refit_progress = gui.add_progress_bar(0.0, visible=False)
        self.refit_status = gui.add_markdown("")
        self.history = gui.add_uplot(
            (np.array([0.0]), np.zeros(1), np.zeros(1), np.zeros(1), np.zeros(1)),
            HISTORY_SERIES,
            title="Check-ring MAE per step (um), dashed: noise floor",
            aspect=1.5,
            scales={"x": {"time": False, "range": [-0.5, 0.5]}},
            axes=({"label": "step"}, {"label": "um"}),
            visible=False,
        )
        self.history_table = gui.add_markdown("")
        self.reveal = gui.add_button("Reveal the hidden effect", hint="teaching scenarios: what the twin hid in the data")
        self.revealed = gui.add_markdown("")
        self.effect_names = dict(effect_names)

    def clear(self) -> None:
        """New data: the diagnosis and history of the old data no longer apply."""
        for handle in (self.status, self.refit_status, self.summary, self.verdict, self.evidence_text, self.history_table, self.revealed):
            handle.content = ""
        self.candidates.content = ""
        self.progress.visible = self.refit_progress.visible = False
        self.evidence.visible = self.evidence_of.visible = self.history.visible = False
        self.evidence_of.options = (NO_CHOICE,)
        for effect_id, box in self.effects.items():
            box.label = effect_id
            box.value = False

    def show_progress(self, text: str, fraction: float | None, refit: bool = False) -> None:
        bar, status = (self.refit_progress, self.refit_status) if refit else (self.progress, self.status)
        bar.visible = True
        bar.animated = fraction is None
        if fraction is not None:
            bar.value = float(np.clip(100.0 * fraction, 0.0, 100.0))
        status.content = f"_{text}_"

    def done(self, text: str, refit: bool = False) -> None:
        bar, status = (self.refit_progress, self.refit_status) if refit else (self.progress, self.status)
        bar.value = 100.0
        bar.visible = False
        status.content = text

    def show_diagnosis(self, result: Any, units: Mapping[str, Mapping[str, str]]) -> None:
        floor, base = result.noise_floor_um, result.baseline_mae_um
        n_check, n_fail = int(result.held_out.sum()), int(result.failing.sum())
        self.summary.content = (
            f"**Where it fails:** {n_fail} of {len(result.failing)} orientations are worse than their noise floor "
            f"(out of sample). On the {n_check} check rings the {result.baseline_model} baseline has MAE "
            f"**{base['mean']:.3f} um** vs the mean (floor {floor['mean']:.3f}) and **{base['single']:.3f} um** vs "
            f"single repetitions (floor {floor['single']:.3f}).\n\n**Candidate effects**, best first:"
        )
        self.candidates.content = candidates_html(result.candidates, units)
        if result.verdict == "missing":
            best = result.candidates[0]
            self.verdict.content = (
                f"**Verdict: a missing effect — {best.name} ({best.effect})**, "
                f"{parameters_text(best.params, units.get(best.effect, {}))}.\n\n_{best.teaching}_\n\nTick it below and refit."
            )
        else:
            self.verdict.content = (
                "**Verdict: no missing effect found** — no candidate explains more than noise would "
                "and lowers the held-out error materially."
            )
        for c in result.candidates:
            box = self.effects.get(c.effect)
            if box is not None:
                box.label = c.effect + (" ✔" if c.significant else "")
        options = tuple(c.effect for c in result.candidates if c.evidence.get("x"))
        self.evidence_of.options = options or (NO_CHOICE,)
        self.evidence_of.visible = bool(options)

    def show_evidence(self, candidate: Any, units: Mapping[str, str]) -> None:
        ev = candidate.evidence
        if not ev.get("x"):
            self.evidence.visible = False
            self.evidence_text.content = ""
            return
        data = (np.asarray(ev["x"], float), np.asarray(ev["residual"], float), np.asarray(ev["fitted"], float))
        self.evidence.title = f"{candidate.effect}: residual and fit, {ev['y_label']}"
        self.evidence.axes = ({"label": ev["x_label"]}, {"label": ev["y_label"]})
        self.evidence.data = data
        self.evidence.visible = True
        flag = "significant" if candidate.significant else "not significant"
        self.evidence_text.content = (
            f"**{candidate.name}** ({flag}): {parameters_text(candidate.params, units)}. "
            f"Every touch's out-of-sample residual, binned against {ev['x_label']}.\n\n_{candidate.teaching}_"
        )

    def show_history(self, steps: Sequence[Any], baseline: str) -> None:
        """The error history: MAE against the mean and single repetitions per step, each with its floor."""
        if not steps:
            self.history.visible = False
            self.history_table.content = ""
            return
        self.history.data = history_data(steps)
        self.history.scales = {"x": {"time": False, "range": [-0.5, len(steps) - 0.5]}}
        self.history.axes = ({"label": "step", "splits": tuple(float(k) for k in range(len(steps)))}, {"label": "um"})
        self.history.visible = True
        lines = ["| step | vs mean (floor) | vs single (floor) |", "|---|---|---|"]
        for k, s in enumerate(steps):
            lines.append(
                f"| {k}: {step_label(s.added, baseline)} | {s.mae_um['mean']:.3f} ({s.noise_floor_um['mean']:.3f}) | "
                f"{s.mae_um['single']:.3f} ({s.noise_floor_um['single']:.3f}) |"
            )
        last = steps[-1]
        ratio = last.mae_um["mean"] / last.noise_floor_um["mean"] if last.noise_floor_um["mean"] else float("nan")
        lines += ["", f"Last step: **{ratio:.2f}x** the noise floor of the mean (um, on the check rings)."]
        self.history_table.content = "\n".join(lines)

    def selected_effects(self) -> list[str]:
        return [e for e, box in self.effects.items() if box.value]
