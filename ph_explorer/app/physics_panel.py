"""The Physics tab of one browser: diagnose -> tick effects -> refit -> the error history.

Formats what ph_explorer.diagnosis returns (Diagnosis, Candidate, Step); computes nothing. Fitted
parameters are written by their effect (`Effect.parameters_text`), so a user's own effect is shown
like a built-in one.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import viser

from ph_explorer.app.accessibility import bring_into_view
from ph_explorer.app.panels import NO_CHOICE
from ph_explorer.diagnosis import VERDICTS, Candidate, Diagnosis, NestedAfter, Step
from ph_explorer.diagnosis.separation import CONFOUNDED
from ph_explorer.diagnosis.shapes import Shape
from ph_explorer.effects import Catalog
from ph_explorer.figures.charts import evidence_svg, history_svg, line_chart_svg
from ph_explorer.figures.decision_text import DecisionWords
from ph_explorer.figures.diagnosis_text import breakable, left_next, report_sections, shared_text, signature_text
from ph_explorer.figures.history_text import chosen_text, gain_text, nested_summary, step_label
from ph_explorer.figures.shape_text import shape_svg
from ph_explorer.planning.deciding import DECIDE_BUDGET, Decision


def fit_html(result: Diagnosis, catalog: Catalog, limit: int = 4) -> str:
    """The effects the diagnosis found (else those beyond noise): parameters +- U (k = 2, jackknife
    over orientations) and identifiability: the other candidates each shares its variance with on
    this campaign (above separation.CONFOUNDED the two cannot be told apart), and what is left."""
    shown = list(result.found) or [c for c in result.candidates if c.beyond_noise or c.significant][:limit]
    cell = "padding:2px 4px;vertical-align:top;"
    rows = []
    for c in shown:
        untold = [p for p in c.confounded_with if not p.told_apart]
        told = [p for p in c.confounded_with if p.told_apart]
        if untold:
            shared = "; ".join(shared_text(c.effect, p, catalog) for p in untold[:3])
            ident = f'<span style="color:#b35900">confounded: {shared}: this campaign cannot tell them apart</span>'
        elif told:
            shared = "; ".join(shared_text(c.effect, p, catalog) for p in told[:3])
            ident = f"told apart by the rings, though {shared}"
        else:
            ident = f"identifiable: shares under {100 * CONFOUNDED:.0f} % of its variance with every other candidate"
        rows.append(
            # Its status beside its name: a candidate shown when nothing is found is not a claim.
            f'<tr style="border-bottom:1px solid #eee"><td style="{cell}font-weight:600;overflow-wrap:anywhere">{breakable(c.effect)}'
            f'<div style="font-weight:400;color:#555">{c.status}</div></td>'
            f'<td style="{cell}">{catalog[c.effect].parameters_text(c.params, c.params_u)}<div style="color:#555">{ident}</div></td></tr>'
        )
    if not rows:
        rows.append(f'<tr><td style="{cell}" colspan="2">No effect explains more than noise would.</td></tr>')
    left = [signature_text(entry) for entry in result.signature if entry["significant"]]
    if left:
        rest = "; ".join(left[:3])
        leftover = f"<b>Left unexplained</b> (share of the residual, its noise share): {rest}."
    elif result.verdict in ("missing", "none"):
        leftover = "<b>Left unexplained:</b> nothing above noise" + (" once the found effects are in." if result.found else ".")
    else:
        leftover = "<b>Left unexplained:</b> beyond noise, with no pattern in the head's variables."
    return (
        '<table style="width:96%;border-collapse:collapse;font-size:0.75em;line-height:1.3em;table-layout:fixed">'
        '<colgroup><col style="width:30%"><col style="width:70%"></colgroup>'
        f'<tr style="border-bottom:1px solid #bbb;text-align:left"><th style="{cell}">effect</th><th style="{cell}">fitted &plusmn; U (k = 2); identifiability</th></tr>'
        + "".join(rows)
        + f'</table><div style="font-size:0.75em;line-height:1.3em;margin-top:3px;width:96%">{leftover}</div>'
    )


def verdicts_markdown(verdict: str) -> str:
    """The verdicts a diagnosis can give, this campaign's marked: what the verdict could have been."""
    rows = [f"- {'**' + key + '** ✔' if key == verdict else key}: {meaning}" for key, meaning in VERDICTS.items()]
    return f"_The {len(VERDICTS)} verdicts:_\n\n" + "\n".join(rows)


def nested_markdown(nested: NestedAfter) -> str:
    """The honest "after" (nested cross-validation): the renderer's sentence, its figures as a table."""
    rows = [("before", nested.before_um), ("after", nested.after_um), ("noise floor", nested.noise_floor_um)]
    table = ["| | vs mean, um | vs single, um |", "|---|---|---|"] + [
        f"| {name} | {f['mean']:.3f} | {f['single']:.3f} |" for name, f in rows
    ]
    said = gain_text(nested) if nested.gain is not None else ""
    gain = [said[:1].upper() + said[1:] + "."] if said else []
    return "\n\n".join([nested_summary(nested), "\n".join(table), f"Set in the folds: {chosen_text(nested)}.", *gain])


def candidates_html(candidates: Sequence[Candidate], catalog: Catalog, limit: int = 8) -> str:
    """The ranked candidates: explained share, fall of the held-out error, what noise explains, significance."""
    cell = "padding:2px 4px;"
    head = (
        # 96 %: the panel's scrollbar takes the rest of its width.
        '<table style="width:96%;border-collapse:collapse;font-size:0.75em;line-height:1.3em;table-layout:fixed">'
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
            params = f'<div style="font-weight:400;color:#1f6f2f">{catalog[c.effect].parameters_text(c.params, c.params_u)}</div>'
        mark = '<span title="significant" style="color:#2a9d3c">&#10004;</span>' if c.significant else ""
        rows.append(
            f'<tr style="border-bottom:1px solid #eee;text-align:right;vertical-align:top;{style}">'
            f'<td style="text-align:left;{cell}overflow-wrap:anywhere">{rank}. {breakable(c.effect)}{params}</td>'
            f'<td style="{cell}">{100.0 * c.explained_fraction:.1f}&nbsp;%</td>'
            f'<td style="{cell}">{100.0 * c.error_reduction:.0f}&nbsp;%</td>'
            f'<td style="{cell}">{100.0 * c.noise_fraction:.2f}&nbsp;%</td><td style="{cell}">{mark}</td></tr>'
        )
    more = f'<div style="font-size:0.75em;color:#777">… and {len(candidates) - limit} more</div>' if len(candidates) > limit else ""
    legend = (
        '<div style="font-size:0.72em;color:#666;margin-top:3px;width:96%">explains: share of what the baseline cannot predict '
        "out of sample; error &darr;: fall of the check-ring rms error; noise: the most the same scan explains on "
        "pure noise; &#10004;: significant.</div>"
    )
    return head + "".join(rows) + "</table>" + more + legend


class PhysicsPanel:
    """Diagnose -> add an effect -> refit -> the error falls; reveal the hidden effect."""

    def __init__(self, gui: viser.GuiApi, catalog: Catalog, study: bool = False) -> None:
        self.catalog = catalog
        self.nested: NestedAfter | None = None  # the last diagnosis's honest "after" (nested cross-validation)
        # The operator's study (serve --study): which, how far it got; empty without one.
        self.study_line = gui.add_markdown("")
        # The loop first, compact, near the top of the tab (issue 15: above the fold at 1440x900):
        # Diagnose -> verdict -> tick the found effect -> Refit -> the error fall -> Reveal; the
        # details (candidates, the tests' figures, the teaching text, evidence, history table) in "More".
        self.diagnose = gui.add_button("Diagnose", hint="where the loaded model fails out of sample, and which catalog effect is missing")
        self.status = gui.add_markdown("")
        self.progress = gui.add_progress_bar(0.0, visible=False)
        self.verdict = gui.add_markdown("")
        # A shape no catalog holds (diagnosis.shapes): its curve against its variable, with its band.
        self.shape_chart = gui.add_html("", visible=False)
        # When the rings cannot decide (a confounded pair, a suggestion): the rings that would, on
        # the map as crosses; the twin measures them for a teaching scenario.
        self.decide = gui.add_button(
            "Rings that would decide",
            visible=False,
            hint="the rings to measure next that would tell confounded candidates apart or confirm a suggestion",
        )
        self.budget = gui.add_number(
            "Rings at most", DECIDE_BUDGET, min=3, max=30, step=1, visible=False, hint="how many rings you would measure to decide"
        )
        self.decision = gui.add_markdown("")
        self.measure = gui.add_button(
            "Measure them",
            visible=False,
            hint="the digital twin measures the proposed rings after the campaign; they join it as check rings",
        )
        self.download_rings = gui.add_button(
            "Download rings.csv", visible=False, hint="the proposed rings for a CMM program (A_deg, B_deg, order, reason)"
        )
        # The effects the diagnosis found, ready to tick; every other effect in a collapsed folder.
        self.gui = gui
        self.found_folder = gui.add_folder("Effects found: tick, then Refit", visible=False)
        self.refit = gui.add_button("Refit the hybrid", hint="fit the ticked effects + the trilinear part; measure on the check rings")
        self.refit_progress = gui.add_progress_bar(0.0, visible=False)
        self.refit_status = gui.add_markdown("")
        self.fall = gui.add_markdown("")
        # The history right under the fall, above Reveal: still in view once the truth is shown.
        # The same SVG chart as the report's (figures.charts): steps named on the axis, round ticks.
        self.history = gui.add_html("", visible=False)
        self.reveal = gui.add_button("Reveal the hidden effect", visible=False, hint="teaching scenarios: what the twin hid in the data")
        self.revealed = gui.add_markdown("")
        # The diagnosis's results (issue 15 item 6): a signature plot (a candidate's, or what is left
        # unexplained), the fitted parameters with their uncertainties and identifiability.
        with gui.add_folder("Diagnosis: signature, fit, identifiability", visible=False) as self.results_folder:
            self.fit = gui.add_html("")
            # The plot before its chooser: in view right after Diagnose at 1440x900 (its title names it).
            self.evidence = gui.add_html("")
            self.evidence_of = gui.add_dropdown(
                "Signature of", (NO_CHOICE,), hint="what is left unexplained, or a candidate's residual and fitted term"
            )
            self.evidence_items: dict[str, tuple[str, str, dict]] = {}  # dropdown label -> (title, caption, evidence)
            self.evidence_text = gui.add_markdown("")
        # Measure until you know (planning.adaptive): a teaching scenario's twin measures an adaptive
        # campaign of the same head from its first plan, each plan's rings after a diagnosis, until it stops.
        with gui.add_folder("Measure until you know (the twin)", expand_by_default=False, visible=False) as self.adaptive_folder:
            self.adaptive_start = gui.add_button(
                "Measure the first plan",
                hint="the twin measures the first rings of this head (6 designed, 2 at A0 = 0, 4 check rings), then diagnoses",
            )
            self.adaptive_next = gui.add_button(
                "Measure next", visible=False, hint="the twin measures the next plan's rings; the merged campaign is diagnosed again"
            )
            self.adaptive_status = gui.add_markdown("")
            self.adaptive_chart = gui.add_html("", visible=False)
            self.adaptive_plan = gui.add_markdown("")  # the plan's rings, under the chart (a long list)
        # Every catalog effect, for a refit of your own choice (collapsed: the found ones are above).
        self.other_folder = gui.add_folder("Effects in the hybrid (all)", expand_by_default=False)
        self.effects: dict[str, viser.GuiCheckboxHandle] = {}
        self._place_effects(set())
        with gui.add_folder("More: candidates, tests, history", expand_by_default=False):
            self.summary = gui.add_markdown("")
            self.candidates = gui.add_html("")
            self.verdict_more = gui.add_markdown("")
            self.history_table = gui.add_markdown("")
        self.save_study = gui.add_button(
            "Save study",
            visible=study,
            hint="write this run (the model refitted last, the history, the verdict) to the server's study file",
        )
        self.study_status = gui.add_markdown("")

    def _place_effects(self, found: set[str], shapes: Sequence[Shape] = ()) -> None:
        """A checkbox per catalog effect, labelled by its id (its accessible name): the found ones in
        the open folder, the rest in the collapsed one; what was ticked stays ticked. The shapes
        claimed (what no catalog holds) join the found ones: ticked and refitted like them."""
        ticked = {e for e, box in self.effects.items() if box.value}
        for box in self.effects.values():
            box.remove()
        self.effects = {}
        for folder, wanted in ((self.found_folder, True), (self.other_folder, False)):
            with folder:
                # Every addable effect: the catalog's candidates and the shapes of a file (serve --effects shapes.toml).
                for effect_id, cls in self.catalog.addable().items():
                    if (effect_id in found or any(shape.id == effect_id for shape in shapes)) == wanted:
                        hint = f"{cls.name}: " + ("found by the diagnosis; " if wanted else "") + "add it to the hybrid's physical terms"
                        self.effects[effect_id] = self.gui.add_checkbox(effect_id, effect_id in ticked, hint=hint)
        with self.found_folder:
            for shape in (shape for shape in shapes if shape.id not in self.effects):
                hint = f"a shape no catalog holds: {shape.words}; add it to the hybrid's physical terms"
                self.effects[shape.id] = self.gui.add_checkbox(shape.id, shape.id in ticked, hint=hint)
        self.found_folder.visible = bool(found) or bool(shapes)

    def clear(self) -> None:
        """New data: the diagnosis and history of the old data no longer apply."""
        self.nested = None
        for handle in (
            self.status,
            self.refit_status,
            self.summary,
            self.verdict,
            self.verdict_more,
            self.fall,
            self.evidence_text,
            self.history_table,
            self.revealed,
            self.study_status,
            self.decision,
        ):
            handle.content = ""
        self.decide.visible = self.budget.visible = self.measure.visible = self.download_rings.visible = False
        self.candidates.content = self.evidence.content = self.fit.content = self.shape_chart.content = ""
        self.shape_chart.visible = False
        self.progress.visible = self.refit_progress.visible = False
        self.results_folder.visible = self.history.visible = False
        self.evidence_of.options = (NO_CHOICE,)
        self.evidence_items = {}
        for box in self.effects.values():
            box.value = False
        self._place_effects(set())

    def keep_in_view(self, first: str, last: str | None = None) -> None:
        """The lines a step just wrote, from `first` to `last`, scrolled into the panel's view."""
        bring_into_view(self.gui, first, last)

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

    def show_diagnosis(self, result: Diagnosis, decision: Decision | None = None) -> None:
        """The verdict and what to do next (with the rings that would decide, when found), the candidates, More."""
        # The rings that fail and the baseline's figures are the report's (why, where it fails, the
        # tests, under "More" below the candidates): not worded again here.
        self.summary.content = "**Candidate effects**, best first:"
        self.candidates.content = candidates_html(result.candidates, self.catalog)
        # The report's order (figures.diagnosis_text), in the explorer's words: the verdict and what to do
        # next, the claims' untold partners (their fit is in the table below), shapes and suggestions led
        # by their titles (never read as claims); why, where it fails, tests, partners, teaching under "More".
        short = {s.key: s for s in report_sections(result, self.catalog, front="explorer", decision=decision)}
        full = report_sections(result, self.catalog, "full", front="explorer")
        headline = short["verdict"].title
        keys = [k for k in ("claims", "shapes", "suggested") if k in short]
        lines = [("" if k == "claims" or i else f"**{short[k].title}:** ") + line for k in keys for i, line in enumerate(short[k].lines)]
        shown = [short[key] for key in ("why", "worst_rings") if key in short] + [
            s for s in full if s.key in ("tests", "partners", "teaching")
        ]
        more = [f"**{s.title}**\n\n" + "\n\n".join(s.lines) for s in shown]
        self.nested = result.nested  # the honest "after", shown with the error history
        # The headline and the next step in one paragraph: the loop's controls stay in view at 1440x900.
        self.verdict.content = "\n\n".join([f"**{headline}** {' '.join(short['verdict'].lines)}", *lines])
        self.keep_in_view("Verdict:")
        self.verdict_more.content = "\n\n".join(more) + "\n\n" + verdicts_markdown(result.verdict)
        self._place_effects({c.effect for c in result.found}, result.claimed_shapes)
        self.shape_chart.content = shape_svg(result.shapes[0]) if result.shapes else ""
        self.shape_chart.visible = bool(result.shapes)
        # What is left (the signature) first, then each candidate's evidence, by the label shown in the dropdown.
        self.evidence_items = {}
        next_for_left = left_next(result, "explorer")
        for entry in result.signature:
            if entry["significant"] and entry["evidence"].get("x"):
                label = "left: " + signature_text(entry)
                caption = (
                    f"**What is left** as diagnosed, {signature_text(entry)}: the residual the catalog does not explain, binned "
                    f"against {entry['evidence']['x_label']}, and this term fitted to it. {next_for_left}"
                )
                self.evidence_items[label] = (f"left: {entry['variable']} {entry['kind']}", caption, entry["evidence"])
        self.evidence_items |= {
            c.effect: (c.effect, self._candidate_caption(c), c.evidence) for c in result.candidates if c.evidence.get("x")
        }
        options = tuple(self.evidence_items)
        self.evidence_of.options = options or (NO_CHOICE,)
        self.evidence_of.visible = bool(options)
        self.fit.content = fit_html(result, self.catalog)
        self.results_folder.visible = True
        # Only when rings would decide something, at the budget they need: never a button that says no ring does.
        needed = [q["rings_needed"] for q in (decision.expected.values() if decision else ()) if q.get("rings_needed")]
        self.budget.value = max(needed) if needed and not decision.rings else decision.budget if decision else DECIDE_BUDGET
        self.decide.visible = self.budget.visible = result.leaves_open and (decision is None or bool(decision.rings) or bool(needed))
        self.decision.content = ""
        self.measure.visible = self.download_rings.visible = False

    def show_decision(self, words: DecisionWords, measurable: bool) -> None:
        """The rings that would decide (figures.decision_text.decision_words); Measure them when the twin can."""
        self.decision.content = "\n\n".join(words.paragraphs())
        self.measure.visible = bool(words.rings) and measurable
        self.download_rings.visible = bool(words.rings)

    def _candidate_caption(self, candidate: Candidate) -> str:
        # Short: its parameters +- U are in the table under the plot.
        ev = candidate.evidence
        return (
            f"_**{candidate.name}** ({candidate.status}): every touch's residual with this term put back, and the term, "
            f"after the circle fit, binned against {ev['x_label']}; the curve reaches {ev['fitted_peak']:.3g} ({ev['y_label']})._"
        )

    def show_evidence(self, label: str) -> None:
        """The evidence plot and its caption for a dropdown entry (a candidate, or what is left)."""
        title, caption, ev = self.evidence_items.get(label, ("", "", {}))
        if not ev.get("x"):
            self.evidence.content = self.evidence_text.content = ""
            return
        self.evidence.content = evidence_svg(ev, f"{title}: residual and fit")
        self.evidence_text.content = caption

    def show_history(self, steps: Sequence[Step]) -> None:
        """The error history: MAE against the mean and single repetitions per step, each with its floor."""
        if not steps:
            self.history.visible = False
            self.history_table.content = self.fall.content = ""
            return
        self.history.content = history_svg(steps)  # from zero: the fall is read against the whole error
        # One step is one point: the fall line says it; the chart (and its room) waits for a refit.
        self.history.visible = len(steps) > 1
        lines = ["| step | vs mean (floor) | vs single (floor) |", "|---|---|---|"]
        for k, s in enumerate(steps):
            lines.append(
                f"| {k}: {step_label(s)} | {s.mae_um['mean']:.3f} ({s.noise_floor_um['mean']:.3f}) | "
                f"{s.mae_um['single']:.3f} ({s.noise_floor_um['single']:.3f}) |"
            )
        last = steps[-1]
        ratio = last.mae_um["mean"] / last.noise_floor_um["mean"] if last.noise_floor_um["mean"] else float("nan")
        first = steps[0]
        self.fall.content = (
            # One line: vs the repetition mean, first step -> last (the table under "More" has each step).
            f"Check-ring MAE: {first.mae_um['mean']:.3f} -> **{last.mae_um['mean']:.3f} um**, **{ratio:.2f}x** its floor"
            if len(steps) > 1
            else f"Check-ring MAE (baseline): **{last.mae_um['mean']:.3f} um**, **{ratio:.2f}x** its floor"
        )
        if self.nested is not None:
            lines += ["", nested_markdown(self.nested)]
        self.history_table.content = "\n".join(lines)

    def show_study(self, name: str, runs: int, chain: Sequence[str], verdict: str | None, applies: bool = True) -> None:
        """The study line: which study, how many runs, the chain it reached and its last verdict."""
        if not applies:
            self.study_line.content = (
                f"**Study {name}** belongs to the campaign the server was started with; the data shown now is "
                "another, so it is neither continued nor saved here (reload the page to continue it)."
            )
            self.save_study.visible = False
            return
        self.save_study.visible = True
        if runs == 0:
            self.study_line.content = f"**Study {name}** (new): the first **Save study** writes it, after a diagnosis."
            return
        reached = " + ".join(chain) if chain else "the baseline alone"
        self.study_line.content = (
            f"**Study {name}**: {runs} run{'s' if runs != 1 else ''}; the model it reached: **{reached}**; "
            f"verdict of its last run: **{verdict}**. Diagnose continues from that model; Refit fits it + the ticked effects."
        )

    def show_adaptive(
        self, lines: Sequence[str], points: Sequence[tuple[int, float, float, float]], more: bool, rings: Sequence[str] = ()
    ) -> None:
        """The adaptive campaign so far: its rings and minutes, the plan's head (or the stop), the check
        rings' error of each diagnosis against the rings measured (rings, minutes, MAE, floor, um),
        then the plan's rings."""
        self.adaptive_status.content = "\n\n".join(lines)
        self.adaptive_plan.content = "\n\n".join(rings)
        self.adaptive_next.visible = more
        self.adaptive_chart.visible = len(points) > 1
        if len(points) > 1:
            # Short names: the chart's legend puts three in a row (the title says it is against the mean).
            measured = np.array([p[0] for p in points], dtype=float)
            series = [("check-ring MAE", [p[2] for p in points], "#1f77b4"), ("its floor", [p[3] for p in points], "#999")]
            title = "Check-ring error (vs the mean) against rings measured"
            self.adaptive_chart.content = line_chart_svg(measured, series, title, "rings measured", "um")

    def selected_effects(self) -> list[str]:
        return [e for e, box in self.effects.items() if box.value]
