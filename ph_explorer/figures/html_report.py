"""A report of a campaign and its diagnosis that stands alone: one HTML file, every figure inside.

The campaign, the error map over orientations, the polar plot and the paper's Tables 1-3 at chosen
orientations, and the diagnosis of a study (verdict, fitted effects with their uncertainty, the
error's history, where it fails, every run; figures/diagnosis_report.py). Figures are inline SVG;
the page needs no script and fetches nothing. A teaching scenario's hidden effects are not named
unless the caller asks to reveal them.

Method: docs/methods/html_report.md.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from markdown_it import MarkdownIt
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign, lattice_axes, orientation_label
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.diagnosis.study import Study, study_campaign
from ph_explorer.effects import DEFAULT_CATALOG, Catalog
from ph_explorer.figures.diagnosis_report import EffectNames, decision_section, diagnosis_figures, diagnosis_section, reveal_section
from ph_explorer.figures.orientation_map import MapFigure, map_svg
from ph_explorer.figures.polar import campaign_bounds, curves_svg, polar_scale
from ph_explorer.harmonics import ron_t
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.folder import campaign_models
from ph_explorer.paper.tables import tables_at, tables_markdown
from ph_explorer.planning.deciding import DECIDE_BUDGET, rings_that_decide

# The explorer's starting magnification; the chart's base radius still keeps every profile off the centre.
MAGNIFICATION = 10000.0
SVG_NAMESPACE = ' xmlns="http://www.w3.org/2000/svg"'

STYLE = """
body{font-family:sans-serif;max-width:1100px;margin:24px auto;padding:0 16px;color:#222;line-height:1.45}
h1{font-size:1.5em;margin-bottom:0.2em} h2{font-size:1.2em;margin-top:1.6em;border-bottom:1px solid #ccc}
h3{font-size:1.05em} table{border-collapse:collapse;margin:6px 0 10px} td,th{border:1px solid #ccc;padding:2px 8px;text-align:right}
td:first-child,th:first-child,td.t{text-align:left} .meta td{text-align:left} .note{color:#555;font-size:0.9em}
figure{margin:8px 0 16px} figcaption{font-size:0.9em;color:#444}
.pair{display:flex;flex-wrap:wrap;gap:24px;align-items:flex-start} .pair>*{flex:1 1 420px;min-width:320px} .pair>figure{max-width:640px}
.verdict{font-size:1.1em;font-weight:600}
"""


def _inline(svg: str) -> str:
    """An SVG for an HTML page: inline SVG takes its namespace from the HTML parser, so the page names no URL."""
    return svg.replace(SVG_NAMESPACE, "", 1)


def _e(text: Any) -> str:
    return html.escape(str(text))


def default_orientations(campaign: Campaign, check: NDArray[np.bool_], diagnosis: Diagnosis | None = None) -> list[tuple[float, float]]:
    """Where a report draws its polar plots when the caller names none: the ring that fails worst
    (the diagnosis's), and the first check ring (of the mask `check`, the rings the models never
    saw); the first ring measured when there is neither."""
    candidates: list[tuple[float, float]] = []
    failing = diagnosis.failing_rings() if diagnosis is not None else []
    if failing:
        candidates.append((failing[0].a_deg, failing[0].b_deg))
    check = np.flatnonzero(check)
    if check.size:
        candidates.append((float(campaign.orientations[check[0], 0]), float(campaign.orientations[check[0], 1])))
    candidates.append((float(campaign.orientations[0, 0]), float(campaign.orientations[0, 1])))
    chosen: list[tuple[float, float]] = []
    for a, b in candidates:  # the worst ring may be the first check ring: drawn once
        if campaign.index_of(a, b) not in [campaign.index_of(*c) for c in chosen]:
            chosen.append((a, b))
    return chosen[:2]


def report_html(
    campaign: Campaign,
    models: Mapping[str, DeviationModel],
    train_mask: NDArray[np.bool_],
    catalog: Catalog,
    orientations: Sequence[tuple[float, float]] | None = None,
    study: Study | None = None,
    diagnosis: Diagnosis | None = None,
    reveal: bool = False,
    created: str = "",
    source: str | None = None,
    decision: Mapping[str, Any] | None = None,
) -> str:
    """The report as one self-contained HTML document (docs/methods/html_report.md).

    models: the models shown beside the measurement ("network", "trilinear", "hybrid", ...);
    train_mask: their training rings (the others are check rings);
    study: a study (ph_explorer.diagnosis.study.Study), the diagnosis it records;
    None for a campaign not diagnosed;
    diagnosis: the run that made it, when at hand: names the failing rings and maps each ring's test;
    orientations: where the polar plots and tables are drawn (default: `default_orientations`);
    reveal: name a teaching scenario's hidden effects, with their true parameters;
    source: what the report calls the campaign (default: campaign.source);
    decision: the rings that would decide what the diagnosis leaves open (planning.deciding, as_dict).
    """
    names = EffectNames(campaign, catalog, reveal)
    check = ~np.asarray(train_mask, dtype=bool)
    chosen = list(orientations) if orientations else default_orientations(campaign, check, diagnosis)
    source = source or campaign.source or "a campaign in memory"
    title = f"ph-explorer report: {source}"
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{_e(title)}</title><style>{STYLE}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
        f'<p class="note">Made by ph-explorer{", " + _e(created) if created else ""}. One file, its figures inside: it needs no network and no script.</p>',
    ]
    parts += _campaign_section(campaign, source, models, check)
    parts += _map_section(campaign, check, chosen[0], diagnosis)
    parts += _orientation_sections(campaign, models, check, chosen)
    parts += diagnosis_section(study, diagnosis, catalog, names)
    if decision is not None and (decision.get("rings") or decision.get("questions")):
        parts += decision_section(decision, names)
    if reveal:
        parts += reveal_section(campaign, catalog, study)
    parts.append("</body></html>")
    return "\n".join(parts) + "\n"


# -- the campaign ------------------------------------------------------------------------------------


def _campaign_section(campaign: Campaign, source: str, models: Mapping[str, DeviationModel], check: NDArray[np.bool_]) -> list[str]:
    g = campaign.geometry
    sigma = campaign.noise_sigma_um()
    floor = campaign.noise_floor_um() if np.isfinite(sigma) else {}
    a_axis, b_axis = lattice_axes(campaign.orientations)
    off_grid = int(campaign.off_grid_mask().sum())
    scenario = campaign.scenario or {}
    rows = [
        ("source", source),
        ("orientations", f"{campaign.n_orientations} ({len(a_axis)} A x {len(b_axis)} B lattice, {off_grid} off the lattice)"),
        ("A0 range, deg", f"{campaign.orientations[:, 0].min():g} to {campaign.orientations[:, 0].max():g}"),
        ("B0 range, deg", f"{campaign.orientations[:, 1].min():g} to {campaign.orientations[:, 1].max():g}"),
        (
            "check rings (held out of training)",
            f"{int(check.sum())}: "
            + ", ".join(orientation_label(a, b) for a, b in campaign.orientations[check][:12])
            + (" ..." if check.sum() > 12 else ""),
        ),
        ("repetitions", campaign.n_repetitions),
        ("points per circle", campaign.n_points),
        ("touch times", "recorded (t_s)" if campaign.times_s is not None else "not recorded"),
        (
            "geometry",
            f"pivot to ball {g.pivot_to_ball_mm:g} mm, ball diameter {g.ball_diameter_mm:g} mm, bore diameter {g.bore_diameter_mm:g} mm",
        ),
        ("repetition sigma per touch", f"{sigma:.4f} um" if np.isfinite(sigma) else "unknown (one repetition)"),
        (
            "noise floor of a ring's MAE",
            f"{floor['mean']:.4f} um vs the repetition mean, {floor['single']:.4f} um vs single repetitions"
            if floor
            else "unknown (one repetition)",
        ),
        ("models shown", ", ".join(models) or "none"),
    ]
    if scenario.get("name"):
        hidden = len(scenario.get("hidden", []))
        rows.insert(
            1, ("scenario", f"{scenario['name']} (simulated by the twin, seed {scenario.get('seed', '?')}; hidden effects: {hidden})")
        )
    body = "".join(f"<tr><th>{_e(k)}</th><td>{_e(v)}</td></tr>" for k, v in rows)
    return ['<section id="campaign"><h2>1. The campaign</h2>', f'<table class="meta">{body}</table></section>']


# -- the error map -----------------------------------------------------------------------------------


def _map_section(campaign: Campaign, check: NDArray[np.bool_], current: tuple[float, float], diagnosis: Diagnosis | None) -> list[str]:
    figures: list[tuple[str, MapFigure]] = []
    if diagnosis is not None:
        figures += list(diagnosis_figures(diagnosis, campaign.orientations).items())[:1]  # each ring's out-of-sample MAE over its own floor
    figures.append(
        ("measured RONt", MapFigure(ron_t(campaign.mean_curves()), "um", "peak to valley of the measured mean curve (ISO 12181)"))
    )
    parts = ['<section id="map"><h2>2. The error map over orientations</h2><div class="pair">']
    for k, (name, figure) in enumerate(figures):
        parts.append(
            f'<figure id="map-{k + 1}">{_inline(map_svg(figure, campaign.orientations, check, current, _e(name)))}'
            f"<figcaption>{_e(name)}: {_e(figure.note)}. Ringed: {_e(orientation_label(*current))}.</figcaption></figure>"
        )
    parts.append("</div></section>")
    return parts


# -- polar plots and Tables 1-3 at chosen orientations ------------------------------------------------


def _orientation_sections(
    campaign: Campaign, models: Mapping[str, DeviationModel], check: NDArray[np.bool_], chosen: Sequence[tuple[float, float]]
) -> list[str]:
    sigma = campaign.noise_sigma_um()
    floor = campaign.noise_floor_um() if np.isfinite(sigma) else {}
    markdown = MarkdownIt("commonmark", {"html": False}).enable("table")
    bore_radius = 0.5 * campaign.geometry.bore_diameter_mm
    bounds = campaign_bounds(campaign.deviations)  # once: every chart of the campaign keeps room for them
    parts = ['<section id="orientations"><h2>3. Polar plots and Tables 1-3</h2>']
    for k, (a, b) in enumerate(chosen, 1):
        index = campaign.index_of(a, b)
        curves: dict[str, NDArray[np.float64]] = {}
        repetitions = None
        if index is not None:
            curves["measured"] = campaign.deviations[index].mean(axis=0)
            repetitions = campaign.deviations[index]
        for name, model in models.items():
            curves[name] = np.asarray(model.predict([[a, b]], n_points=campaign.n_points))[0]
        held_out = index is not None and bool(check[index])
        # The chart's base keeps the campaign's touches (but its rarest), this ring's and these curves off the centre, as in the explorer.
        own = () if repetitions is None else (repetitions,)
        scale = polar_scale(MAGNIFICATION, [bounds, *own, *curves.values()], bore_radius)
        kind = "not measured: predictions" if index is None else ("check ring" if held_out else "training ring")
        chart = curves_svg(scale, curves, {}, repetitions, None, f"{orientation_label(a, b)} ({kind})")
        tables = tables_at(campaign, models, index, curves)
        text = tables_markdown(tables, a, b, list(models), floor, index is not None, held_out)
        parts.append(
            f'<h3>{_e(orientation_label(a, b))}</h3><div class="pair">'
            f'<figure id="polar-{k}">{_inline(chart)}<figcaption>Polar plot about the least-squares circle, '
            f"{_e(scale.caption())}; point numbers and theta counter-clockwise as seen from the head.</figcaption></figure>"
            f'<div id="tables-{k}" class="tables">{markdown.render(text)}</div></div>'
        )
    parts.append("</section>")
    return parts


def diagnosed_report_html(
    campaign: Campaign,
    result: Diagnosis,
    name: str,
    sha256: str,
    model_dir: Path | None = None,
    catalog: Catalog = DEFAULT_CATALOG,
    data_part: str = "trilinear",
    orientations: Sequence[tuple[float, float]] | None = None,
    reveal: bool = False,
    created: str = "",
    loaded: Mapping[str, DeviationModel] | None = None,
) -> str:
    """The report of a campaign just diagnosed (`ph-explorer report` without --study, and each
    campaign of a fleet's --report): the models of `model_dir` (else the trilinear tables fitted
    now; loaded: those models, when the diagnosis loaded them already), the diagnosis as a study
    records it, and the rings that would decide what it leaves open."""
    models, train, _ = campaign_models(campaign, model_dir, loaded)
    study = Study.of_run(result, result.chain, study_campaign(name, sha256, campaign), data_part)
    decision = rings_that_decide(campaign, result, catalog, DECIDE_BUDGET).as_dict()
    return report_html(campaign, models, train, catalog, orientations, study, result, reveal=reveal, created=created, decision=decision)
