"""The diagnosis in a report (ph_explorer/figures/html_report.py): the verdict, the within-noise tests, the
effects in the model with their parameters +- U, the history of the check-ring error as a chart
and a table, the honest nested figures, where it fails, the study's runs, and what a teaching
scenario hid (only when revealed).

Effects are named through `EffectNames`: by id, or, in a teaching scenario's report that does not
reveal, by a letter (see figures/html_report.py).
"""

from __future__ import annotations

import html
import re
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ph_explorer.campaign import Campaign, orientation_label, orientation_match
from ph_explorer.diagnosis.results import RING_VERDICTS, VERDICTS, Diagnosis, NestedAfter, Step
from ph_explorer.diagnosis.study import Study
from ph_explorer.diagnosis.within_noise import CHECK_TOLERANCE
from ph_explorer.effects import Catalog
from ph_explorer.figures.charts import evidence_svg, history_svg, step_names
from ph_explorer.figures.diagnosis_text import report_sections, signature_text
from ph_explorer.figures.history_text import chosen_text, nested_rings, step_label
from ph_explorer.figures.noise_text import tested_models
from ph_explorer.figures.orientation_map import MapFigure
from ph_explorer.figures.ring_text import ring_reason

MAX_FAILING_LISTED = 15  # the worst failing rings named; the map's colours show every ring


def _e(text: Any) -> str:
    return html.escape(str(text))


class EffectNames:
    """How the report names an effect: by its id, or, in a teaching scenario's report that does not
    reveal, by a letter in the order the report meets them ("effect A"), every effect alike: a name,
    an id or even which of them is the hidden one would give the answer away."""

    def __init__(self, campaign: Campaign, catalog: Catalog, reveal: bool) -> None:
        self.teaching = bool((campaign.scenario or {}).get("hidden")) and not reveal
        self.aliases: dict[str, str] = {}
        # The effects a diagnosis can name (touch noise is none: its id is the word "noise", as in "within noise").
        named = {effect_id: cls for effect_id, cls in catalog.items() if cls.candidate}
        words = {effect_id: effect_id for effect_id in named} | {cls.name: effect_id for effect_id, cls in named.items()}
        self._ids = words
        # Whole words only (an id's letters inside a longer id are another effect), longest first; not a
        # parameter's name, which its value and U or unit follow (gravity's "lobing 0.1 +- 0.05 um").
        parameter = r"(?!\s+[-+]?[\d.]+(?:e[-+]?\d+)?\s+(?:\+-|um\b))"
        self._pattern = re.compile(
            "|".join(rf"(?<![A-Za-z_]){re.escape(w)}(?![A-Za-z_]){parameter}" for w in sorted(words, key=len, reverse=True))
        )

    def label(self, effect_id: str) -> str:
        if not self.teaching:
            return effect_id
        if effect_id not in self.aliases:
            self.aliases[effect_id] = f"effect {chr(ord('A') + len(self.aliases))}"
        return self.aliases[effect_id]

    def text(self, text: str) -> str:
        """Text with every effect's id or name written as `label` writes it."""
        if not self.teaching:
            return text
        return self._pattern.sub(lambda m: self.label(self._ids[m.group(0)]), text)


# -- the diagnosis -----------------------------------------------------------------------------------


def diagnosis_section(study: Study | None, diagnosis: Diagnosis | None, catalog: Catalog, names: EffectNames) -> list[str]:
    """The diagnosis: the report's words (figures.diagnosis_text) on the run's record (`diagnosis`,
    else the study's), then the study's model, candidates, signature, history and runs."""
    parts = ['<section id="diagnosis"><h2>4. The diagnosis</h2>']
    if study is None:
        return parts + [
            "<p>This campaign has not been diagnosed: <code>ph-explorer diagnose</code> or the explorer's Diagnose makes a "
            "study, and <code>ph-explorer report --study</code> puts it here.</p></section>"
        ]
    record = diagnosis if diagnosis is not None else study.diagnosis
    if record is None:  # a study written before the record (format 1): its verdict only
        verdict = str(study.verdict)
        parts.append(f'<p class="verdict">Verdict: {_e(verdict)} - {_e(VERDICTS.get(verdict, "not a verdict of this version"))}.</p>')
    else:
        sections = {s.key: s for s in report_sections(record, catalog, name=names.text)}
        verdict = sections.pop("verdict")
        parts.append(f'<p class="verdict">{_e(verdict.title)}</p>' + "".join(f"<p>{_e(line)}</p>" for line in verdict.lines))
        for key in ("claims", "suggested"):
            if key in sections:
                lines = "".join(f"<li>{_e(line.strip())}</li>" for line in sections[key].lines)
                parts.append(f'<h3>{_e(sections[key].title)}</h3><ul class="{key}">{lines}</ul>')
        parts += _noise_tests(record)
    parts += _chain_table(study, catalog, names)
    if record is not None and record.found and not names.teaching:  # a teaching text says what the effect is
        parts.append(f'<p class="note">{_e(record.found[0].teaching)}</p>')
    if record is not None:
        parts += _ranking(record, catalog, names)
        parts += _signature(record, names)
    parts += _history(study.steps, names)
    parts += _nested(record.nested if record is not None and record.nested is not None else study.nested_after, names)
    parts += _where_it_fails(record)
    parts += _runs(study, names)
    parts.append("</section>")
    return parts


def _noise_tests(record: Diagnosis) -> list[str]:
    rows = []
    for key, model in tested_models(record):
        test = record.within_noise.get(key)
        if test is None:
            continue
        together = "—" if test.check_exceedance is None else f"{test.check_exceedance:.2f}"
        rows.append(
            f"<tr><td>{_e(model)}</td><td>{test.failing_rings}</td><td>{test.statistic:.1f}</td><td>{test.critical:.1f}</td>"
            f"<td>{test.p_value:.3g}</td><td>{together}</td><td class='t'>{'fails' if test.fails else 'within noise'}</td></tr>"
        )
    if not rows:
        return ["<p>One repetition: no repetition spread, so 'within noise' could not be tested.</p>"]
    return [
        "<h3>Within-noise test</h3><table><tr><th>model</th><th>rings beyond their noise</th><th>statistic</th>"
        "<th>critical value</th><th>p</th><th>check rings together</th><th>campaign</th></tr>" + "".join(rows) + "</table>",
        '<p class="note">The statistic sums how far the rings exceed their noise (all but the worst); the campaign fails above '
        f"the critical value (false-alarm rate 2 %), or when the check rings together (the worst left out) exceed {CHECK_TOLERANCE:g} "
        "times what their noise gives at 1 %.</p>",
    ]


def _chain_table(study: Study, catalog: Catalog, names: EffectNames) -> list[str]:
    if not study.chain:
        return [f"<h3>Effects in the model</h3><p>None: the model is the baseline ({_e(study.baseline)}) alone.</p>"]
    rows = []
    for link in study.chain:
        cls = catalog.get(link.effect)
        fitted = cls.parameters_text(link.params, link.params_u or None) if cls is not None else ""
        settings = ", ".join(f"{k} {v:g}" for k, v in link.settings.items())
        label = names.label(link.effect) if names.teaching or cls is None else f"{cls.name} ({link.effect})"
        rows.append(f'<tr><td>{_e(label)}</td><td class="t">{_e(settings)}</td><td class="t">{_e(fitted) or "not fitted"}</td></tr>')
    return [
        "<h3>Effects in the model, fitted parameters +- U (k = 2)</h3>",
        "<table><tr><th>effect</th><th>scanned settings</th><th>fitted parameters +- expanded uncertainty</th></tr>"
        + "".join(rows)
        + "</table>",
    ]


RANKED_SHOWN = 8  # the report's candidate table: the best this many


def _ranking(record: Diagnosis, catalog: Catalog, names: EffectNames) -> list[str]:
    """The run's candidates, best first: what each explains, the fall of the check rings' error,
    what noise alone explains, and its status."""
    candidates = record.candidates
    if not candidates:
        return []
    rows = []
    for rank, c in enumerate(candidates[:RANKED_SHOWN], 1):
        fitted = (
            catalog[c.effect].parameters_text(c.params, c.params_u or None) if c.effect in catalog and c.status != "not significant" else ""
        )
        rows.append(
            f'<tr><td class="t">{rank}. {_e(names.label(c.effect))}</td><td>{100 * c.explained_fraction:.1f} %</td>'
            f'<td>{100 * c.error_reduction:.0f} %</td><td>{100 * c.noise_fraction:.2f} %</td><td class="t">{_e(c.status)}</td>'
            f'<td class="t">{_e(names.text(fitted))}</td></tr>'
        )
    more = f" The best {RANKED_SHOWN} of {len(candidates)}." if len(candidates) > RANKED_SHOWN else ""
    return [
        "<h3>Candidate effects, best first</h3>",
        "<table><tr><th>effect</th><th>explains</th><th>error &darr;</th><th>noise alone</th><th>status</th>"
        f"<th>fitted +- U (k = 2)</th></tr>{''.join(rows)}</table>",
        '<p class="note">explains: share of what the baseline cannot predict out of sample; error &darr;: fall of the '
        f"check rings' error with it; noise alone: the most the same scan explains on pure noise.{more}</p>",
    ]


def signature_plot(record: Diagnosis) -> tuple[str, dict[str, Any]] | None:
    """The run's plot of evidence worth a report, as (title, evidence): the first found effect's
    signature (its residual and fitted term), else what is left unexplained, else the top candidate's."""
    for candidate in [*record.found, *record.suggested]:
        if candidate.evidence.get("x"):
            return f"{candidate.effect} ({candidate.status})", candidate.evidence
    for entry in record.signature:
        if entry["significant"] and entry["evidence"].get("x"):
            return "left unexplained: " + signature_text(entry), entry["evidence"]
    top = next((c for c in record.candidates if c.evidence.get("x")), None)
    return None if top is None else (f"{top.effect} ({top.status}, the best candidate)", top.evidence)


def _signature(record: Diagnosis, names: EffectNames) -> list[str]:
    """The run's signature plot: a residual binned against the head's variable that shows it, and the fitted term."""
    plot = signature_plot(record)
    if plot is None:
        return []
    evidence = dict(plot[1])
    evidence["x_label"], evidence["y_label"] = names.text(evidence["x_label"]), names.text(evidence["y_label"])
    title = names.text(plot[0])
    return [
        "<h3>Signature</h3>",
        f'<figure id="signature-chart" style="max-width:560px">{evidence_svg(evidence, title)}<figcaption>Every touch\'s out-of-sample residual, '
        "binned against the variable that shows it (dots), and the term fitted to it (line).</figcaption></figure>",
    ]


def _history(steps: Sequence[Step], names: EffectNames) -> list[str]:
    if not steps:
        return ["<h3>History</h3><p>The study records no step.</p>"]
    rows = "".join(
        f'<tr><td>{k}</td><td class="t">{_e(step_label(s, names.text))}</td>'
        f"<td>{s.mae_um['mean']:.3f}</td><td>{s.noise_floor_um['mean']:.3f}</td>"
        f"<td>{s.mae_um['single']:.3f}</td><td>{s.noise_floor_um['single']:.3f}</td></tr>"
        for k, s in enumerate(steps)
    )
    return [
        '<h3>History: the check-ring error as effects were added</h3><div class="pair" id="history">',
        f'<figure id="history-chart">{history_svg(steps, [names.text(name) for name in step_names(steps)])}'
        "<figcaption>MAE on the check rings per step (um); dashed: each reference's noise floor.</figcaption></figure>",
        "<div><table><tr><th>step</th><th>model</th><th>MAE vs mean, um</th><th>floor</th><th>MAE vs single, um</th><th>floor</th></tr>"
        f"{rows}</table></div></div>",
    ]


def _nested(nested: NestedAfter | None, names: EffectNames) -> list[str]:
    if nested is None:
        return []
    before, after, floor = nested.before_um, nested.after_um, nested.noise_floor_um

    def cell(value: float) -> str:
        return "—" if not np.isfinite(value) else f"{value:.3f}"

    return [
        "<h3>The honest after: nested cross-validation</h3>",
        f"<p>Each of {nested.folds} folds of {_e(nested_rings(nested))} is predicted by the claims fitted without it, each at the setting its scan there prefers.</p>",
        "<table><tr><th></th><th>MAE vs mean, um</th><th>MAE vs single, um</th></tr>"
        f"<tr><td>before</td><td>{cell(before['mean'])}</td><td>{cell(before['single'])}</td></tr>"
        f"<tr><td>after</td><td>{cell(after['mean'])}</td><td>{cell(after['single'])}</td></tr>"
        f"<tr><td>noise floor</td><td>{cell(floor['mean'])}</td><td>{cell(floor['single'])}</td></tr></table>",
        f"<p>Set in the folds: {_e(chosen_text(nested, names.text))}.</p>",
    ]


def _where_it_fails(record: Diagnosis | None) -> list[str]:
    parts = ['<h3 id="where-it-fails">Where it fails</h3>']
    if record is None:
        return parts + ["<p>The study records no diagnosis of this version: diagnose again to see where it fails.</p>"]
    if not record.tested:
        return parts + ["<p>One repetition: no ring can be tested against its noise.</p>"]
    rings = record.failing_rings()
    if not rings:
        return parts + ["<p>No ring exceeds its noise (the within-noise test, ring level 1 %).</p>"]
    rows = "".join(
        f'<tr><td>{_e(orientation_label(r.a_deg, r.b_deg))}</td><td class="t">{"check ring" if r.held_out else "leave-one-out"}</td>'
        f'<td>{r.mae_um["mean"]:.3f}</td><td>{r.floor_um["mean"]:.3f}</td><td>{r.ratio:.1f}</td><td class="t">{_e(ring_reason(r))}</td></tr>'
        for r in rings[:MAX_FAILING_LISTED]
    )
    more = f" The worst {MAX_FAILING_LISTED} are listed; the map shows every ring." if len(rings) > MAX_FAILING_LISTED else ""
    return parts + [
        f"<p>{len(rings)} of {len(record.rings)} rings exceed their noise under the baseline, worst first (out-of-sample MAE "
        f"against the repetition mean over its own floor).{more}</p>",
        f"<table><tr><th>ring</th><th>predicted</th><th>MAE, um</th><th>floor, um</th><th>x floor</th><th>exceeds</th></tr>{rows}</table>",
    ]


def _runs(study: Study, names: EffectNames) -> list[str]:
    if not study.runs:
        return []
    rows = "".join(
        f'<tr><td>{k}</td><td class="t">{_e(run.date)}</td><td class="t">{_e(names.text(", ".join(run.added))) or "nothing"}</td>'
        f'<td class="t">{_e(run.verdict)}</td></tr>'
        for k, run in enumerate(study.runs, 1)
    )
    return ["<h3>Runs of the study</h3>", f"<table><tr><th>run</th><th>date</th><th>added</th><th>verdict</th></tr>{rows}</table>"]


def reveal_section(campaign: Campaign, catalog: Catalog, study: Study | None) -> list[str]:
    scenario = campaign.scenario or {}
    hidden = [e for e in scenario.get("effects", []) if e.get("hidden")] or [{"id": i} for i in scenario.get("hidden", [])]
    parts = ['<section id="reveal"><h2>5. Revealed: what the scenario hid</h2>']
    if not hidden:
        return parts + ["<p>This campaign records no hidden effect (it is not a teaching scenario).</p></section>"]
    fitted = {link.effect: link for link in (study.chain if study is not None else ())}
    rows = []
    for entry in hidden:
        effect_id = str(entry["id"])
        cls = catalog.get(effect_id)
        truth = {k: float(v) for k, v in entry.items() if k not in ("id", "hidden")}
        found = fitted.get(effect_id)
        truth_text = cls.parameters_text(truth) if cls is not None and truth else ", ".join(f"{k} {v:g}" for k, v in truth.items())
        found_text = cls.parameters_text(found.params, found.params_u or None) if cls is not None and found else "not in the study's model"
        name = f"{cls.name} ({effect_id})" if cls is not None else effect_id
        rows.append(f"<tr><td>{_e(name)}</td><td>{_e(truth_text)}</td><td>{_e(found_text)}</td></tr>")
    return parts + [
        "<table><tr><th>hidden effect</th><th>truth</th><th>fitted (+- U, k = 2)</th></tr>" + "".join(rows) + "</table></section>"
    ]


def diagnosis_figures(result: Diagnosis, orientations: ArrayLike | None = None) -> dict[str, MapFigure]:
    """The diagnosis's per-ring figures for the error map, at `orientations` (the campaign's; default:
    the rings the diagnosis judged): out-of-sample MAE over its floor, and each ring's verdict (no
    verdict where the test could not run: one repetition); a suspect ring, left out, is its own verdict."""
    suspects = result.suspect_rings
    judged = [(r.a_deg, r.b_deg) for r in result.rings]
    where = np.asarray(judged if orientations is None else orientations, dtype=float).reshape(-1, 2)
    ratio_of = np.concatenate([result.out_of_sample_mae_um["mean"] / result.out_of_sample_floor_um["mean"], [s.ratio for s in suspects]])
    failing = result.failing.astype(float) if result.tested else np.full(len(result.rings), np.nan)
    verdict_of = np.concatenate([failing, np.full(len(suspects), float(len(RING_VERDICTS)))])
    match = orientation_match(where, judged + [(s.a_deg, s.b_deg) for s in suspects])
    found = match.any(axis=1)
    at = match.argmax(axis=1)
    ratio = np.where(found, ratio_of[at] if len(ratio_of) else np.nan, np.nan)
    verdict = np.where(found, verdict_of[at] if len(verdict_of) else np.nan, np.nan)
    return {
        "diagnosis: out-of-sample MAE / its floor": MapFigure(
            ratio, "x floor", "each ring's out-of-sample MAE over its own floor; training rings leave-one-out, check rings by the baseline"
        ),
        "diagnosis: ring verdict (within-noise test)": MapFigure(
            verdict,
            "",
            "each ring's within-noise test (ring level 1 %) on the baseline's out-of-sample residual; a ring measured badly is left out",
            (*RING_VERDICTS, "measured badly: left out, remeasure"),
        ),
    }


# -- the rings that would decide ---------------------------------------------------------------------
def decision_section(decision: Mapping[str, Any], names: EffectNames) -> list[str]:
    """The rings to measure next (planning.deciding), in measuring order with their reasons, and each
    question the budget cannot decide."""
    rows = "".join(
        f"<tr><td>{r['order']}</td><td>{_e(orientation_label(r['A_deg'], r['B_deg']))}</td><td>{_e(names.text(r['reason']))}</td></tr>"
        for r in decision.get("rings", [])
    )
    minutes = decision.get("minutes")
    parts = ['<section id="decide"><h2>Rings that would decide</h2>']
    if rows:
        parts.append(
            f"<p>What the diagnosis leaves open, and the rings that would decide it once measured (as check rings; about "
            f"{_e(f'{minutes:.0f}') if minutes is not None else '?'} minutes of CMM time by this campaign's cadence):</p>"
            f"<table><tr><th>order</th><th>ring</th><th>why</th></tr>{rows}</table>"
        )
    for label, expected in decision.get("expected", {}).items():
        if not expected.get("decided_by_rings"):
            parts.append(
                f"<p>{_e(names.text(label))}: no ring of this budget decides it (power {100 * expected.get('power', 0.0):.0f} %).</p>"
            )
    if not rows and not any(not e.get("decided_by_rings") for e in decision.get("expected", {}).values()):
        parts.append(f"<p>{_e(decision.get('note', ''))}</p>")
    parts.append("</section>")
    return parts
