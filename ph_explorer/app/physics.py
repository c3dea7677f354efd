"""One browser's physics loop: diagnose -> tick effects -> refit -> the error history; reveal.

Each step is one call of ph_explorer.diagnosis, run on the session's worker thread (never on a
callback thread); the Physics tab (physics_panel.py) shows its progress and results. The loop
reads the session's data through `current()` and hands a changed Dataset back through `show()`,
so it never holds the session itself.

With a study (serve --study), the loop continues it: the history starts with the study's steps,
Diagnose searches on from the model the study reached (its chain), Refit fits that chain + the
ticked effects, and Save study writes the next run to the operator's file (app/study_file.py).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ph_explorer import diagnosis
from ph_explorer.app.dataset import Dataset
from ph_explorer.app.physics_panel import PhysicsPanel
from ph_explorer.app.study_file import APP_DATA_PART, StudyFile, chain_of
from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.diagnosis.study import Study
from ph_explorer.effects import Catalog, Effect, effect_label
from ph_explorer.errors import InputError
from ph_explorer.figures.decision_text import decision_words
from ph_explorer.figures.diagnosis_report import diagnosis_figures
from ph_explorer.io.merge import merged_campaign
from ph_explorer.models.folder import MODEL_TYPES, baseline_of
from ph_explorer.planning import adaptive, closed_loop, plans
from ph_explorer.planning.deciding import DECIDE_BUDGET, Decision, rings_that_decide
from ph_explorer.twin import Scenario, simulate, twin_scenario


def teaching_scenario(campaign: Campaign) -> bool:
    """A teaching scenario: a campaign whose sidecar records hidden effects, the truth Reveal shows.
    A lab's campaign (an upload, a CSV without such a sidecar) is not one: its browser is shown no
    teaching-only control (Reveal, the report's naming of hidden effects)."""
    return bool((campaign.scenario or {}).get("hidden"))


class PhysicsLoop:
    """The diagnosis, the error history (baseline, + effects, ...) and the hybrid of one session."""

    def __init__(
        self,
        panel: PhysicsPanel,
        catalog: Catalog,
        current: Callable[[], Dataset],
        show: Callable[[Dataset], None],
        study: StudyFile | None = None,
        propose: Callable[[NDArray[np.float64] | None], None] = lambda rings: None,
        load: Callable[[Campaign, str], None] = lambda campaign, label: None,
    ) -> None:
        self.panel = panel
        self.catalog = catalog  # the effects this session diagnoses and fits with
        self.current = current  # the Dataset the session shows now
        self.show = show  # show another Dataset (one with a new model or figure)
        self.propose = propose  # mark rings to measure on the map (None: none)
        self.load = load  # show a new campaign (the data with the rings the twin measured)
        self.proposed: NDArray[np.float64] | None = None  # the rings that would decide, not measured yet
        self.decision: Decision | None = None  # ... and why (the report shows it)
        self.diagnosis: diagnosis.Diagnosis | None = None
        self.steps: list[diagnosis.Step] = []
        # The study this session continues: as opened or last saved (`previous` of the next save),
        # the chain it reached, and the effects of the last refit since then (the next save's chain).
        self.study = study
        self.previous = study.current() if study is not None else None
        self.chain: list[Effect] = chain_of(self.previous, catalog) if study is not None else []
        self.refitted: list[Effect] | None = None
        self.revealed = False  # the browser asked what a teaching scenario hides: its report names it
        self.diagnosed = False  # a diagnosis since the study was opened or last saved: a run to save
        # The study applies while this session shows the campaign it belongs to (until new data).
        self.study_open = study is not None
        # An adaptive campaign the twin measures (planning.adaptive): the head, its last measured
        # scenario (the next rings come after its touches), the plan to measure next, each diagnosis's
        # (rings, minutes, check-ring MAE, floor); None while no adaptive campaign is shown.
        self.adaptive_twin: Scenario | None = None
        self.adaptive_last: Scenario | None = None
        self.next_plan: plans.Plan | None = None
        self.adaptive_points: list[tuple[int, float, float, float]] = []
        self._adaptive_loading = False

    def open_study(self) -> None:
        """Show the study: its line, and its steps as the start of the history."""
        if self.study is None:
            return
        self.steps = list(self.previous.steps) if self.previous is not None else []
        self.panel.show_history(self.steps)
        self._show_study_line()

    def _show_study_line(self) -> None:
        if self.study is None:
            return
        runs, verdict = (len(self.previous.runs), self.previous.verdict) if self.previous is not None else (0, None)
        chain = [effect_label(e) for e in self.chain]
        self.panel.show_study(self.study.name, runs, chain, verdict, applies=self.study_open)

    def clear(self) -> None:
        """New data: the diagnosis and history of the old data no longer apply, nor does the study."""
        self.diagnosis = None
        self.proposed, self.decision = None, None
        self.propose(None)
        self.steps = []
        self.panel.clear()
        # The study belongs to the served campaign only; reloading the page opens it again.
        self.study_open = False
        self.refitted = None
        self.revealed = False
        self._show_study_line()
        if not self._adaptive_loading:  # other data: an adaptive campaign shown before is over
            self.adaptive_twin = self.adaptive_last = self.next_plan = None
            self.adaptive_points = []
            self.panel.show_adaptive([], [], False)

    def diagnose(self) -> None:
        """Where the loaded baseline fails out of sample, and which effect is missing (none added)."""
        p, ds = self.panel, self.current()
        n_effects = len(self.catalog.candidates())
        seen: list[str] = []

        def progress(activity: str) -> None:
            seen.append(activity)
            p.show_progress(f"{activity}…", min(len(seen) / (n_effects + 2), 0.95))

        p.show_progress("out-of-sample residuals of the baseline (leave one orientation out)…", 0.02)
        # A study continues from the model it reached, as `diagnose --resume` does.
        start = list(self.chain) if self.study_open else []
        # An adaptive campaign's diagnosis offers the base model, as its plans read it (planning.adaptive).
        base = adaptive.base_model(self.catalog) if self.adaptive_twin is not None else []
        try:
            # The loaded model is the baseline, as in the command line; a claim's gain is tested on rings
            # left out of the choice (the nested cross-validation) before the verdict, and the worker
            # thread keeps the sliders live meanwhile.
            baseline = baseline_of({k: v for k, v in ds.models.items() if k in MODEL_TYPES})
            result = diagnosis.diagnose(
                ds.campaign, add=[], baseline=baseline, catalog=self.catalog, progress=progress, start=start, base=base
            )
        except InputError as error:
            p.done(f"**Cannot diagnose** — {error.line()}")
            return
        if ds.campaign is not self.current().campaign:
            return  # the data changed meanwhile: this diagnosis is about data no longer shown
        self.diagnosis = result
        # What rings can decide of what the verdict leaves open, said with the verdict (one to a few seconds).
        self.decision = rings_that_decide(ds.campaign, result, self.catalog, DECIDE_BUDGET) if result.leaves_open else None
        p.show_diagnosis(result, self.decision)
        if p.evidence_of.visible:
            p.evidence_of.value = p.evidence_of.options[0]
            self.show_evidence(p.evidence_of.value)
        # The diagnosis's per-ring figures join this browser's map (its out-of-sample error over the floor, each ring's verdict).
        self.show(ds.with_figures(diagnosis_figures(result, ds.campaign.orientations)))
        if not (self.study_open and self.steps):  # a study's history goes on; else it starts at the baseline
            self.steps = list(result.steps[: 1 + bool(base) + len(start)])
            self.refitted = None  # a new history: no refit of it yet
        p.show_history(self.steps)
        self.diagnosed = self.study_open
        continued = f", continuing the study from {' + '.join(effect_label(e) for e in start)}" if start else ""
        # The verdict says what was found and what to do next; the status line only what it continued from.
        p.done(f"Diagnosed{continued}." if continued else "")

    def decide(self) -> None:
        """The rings that would decide what the diagnosis leaves open (planning.deciding), on the map."""
        p, ds, result = self.panel, self.current(), self.diagnosis
        if result is None:
            p.decision.content = "_Diagnose first: the rings to measure answer what its verdict leaves open._"
            return
        p.decision.content = "_finding the rings that would decide…_"
        budget = int(p.budget.value)  # the rings the user would measure at most (the verdict says how many would do)
        decision = (
            self.decision
            if self.decision and self.decision.budget == budget
            else rings_that_decide(ds.campaign, result, self.catalog, budget)
        )
        if ds.campaign is not self.current().campaign:
            return
        self.decision = decision
        self.proposed = np.array([[r["A_deg"], r["B_deg"]] for r in decision.rings]).reshape(-1, 2)
        twin = twin_scenario(ds.campaign, self.catalog)
        p.show_decision(decision_words(decision, budget), twin is not None)
        if decision.rings and twin is None:
            p.decision.content += (
                "\n\n_Measure them on your CMM (**Download rings.csv** gives them to a CMM program), "
                "then `ph-explorer merge FILE.csv NEW.csv --out ALL.csv` and diagnose ALL.csv._"
            )
        self.propose(self.proposed if len(self.proposed) else None)

    def measure(self) -> None:
        """The twin measures the proposed rings after the campaign; the campaign with them is shown."""
        p, ds = self.panel, self.current()
        twin = twin_scenario(ds.campaign, self.catalog)
        if self.proposed is None or not len(self.proposed) or twin is None:
            p.decision.content = "_Nothing to measure: find the rings that would decide first (a teaching scenario's twin measures them)._"
            return
        p.decision.content = f"_the twin measures {len(self.proposed)} rings…_"
        new = simulate(twin.at_rings(self.proposed))
        if ds.campaign.times_s is None:
            new.times_s = None  # a design without touch times (a random head's no_times): merged as it is
        merged, _ = merged_campaign(ds.campaign, new)
        rings = ", ".join(orientation_label(a, b) for a, b in self.proposed)
        self.load(merged, f"{ds.label} + {len(self.proposed)} rings measured by the twin ({rings})")

    def start_adaptive(self) -> None:
        """The twin measures the first rings of the shown teaching scenario's head (planning.adaptive),
        shown as a campaign of their own, diagnosed, with the next plan."""
        p, ds = self.panel, self.current()
        twin = twin_scenario(ds.campaign, self.catalog)
        if twin is None:
            p.adaptive_status.content = "_Only a teaching scenario's twin can measure: load one (Data tab)._"
            return
        plan = adaptive.first_rings(geometry=twin.geometry, cadence=closed_loop.cadence_of(twin), catalog=self.catalog)
        p.adaptive_status.content = f"_the twin measures the first {len(plan.rings)} rings…_"
        last, campaign = closed_loop.measured_plan(twin, plan)
        self._adaptive_step(twin, last, campaign, f"{twin.name}: an adaptive campaign, its first {campaign.n_orientations} rings")

    def measure_next(self) -> None:
        """The twin measures the next plan's rings after the last; the merged campaign is diagnosed again."""
        p, ds, plan = self.panel, self.current(), self.next_plan
        if plan is None or self.adaptive_twin is None or self.adaptive_last is None:
            p.adaptive_status.content = "_Nothing to measure: Measure the first plan first._"
            return
        if plan.stop:  # the stop and its reason are shown already
            return
        p.adaptive_status.content = f"_the twin measures {len(plan.rings)} rings…_"
        last, new = closed_loop.measured_plan(self.adaptive_twin, plan, self.adaptive_last)
        merged, _ = merged_campaign(ds.campaign, new, replace=True)  # a ring measured badly is measured again
        name = self.adaptive_twin.name
        self._adaptive_step(self.adaptive_twin, last, merged, f"{name}: an adaptive campaign, {merged.n_orientations} rings")

    def _adaptive_step(self, twin: Scenario, last: Scenario, campaign: Campaign, label: str) -> None:
        """Show the campaign measured so far, diagnose it, and plan what comes next (or the stop)."""
        self._adaptive_loading = True
        try:
            self.load(campaign, label)
        finally:
            self._adaptive_loading = False
        self.adaptive_twin, self.adaptive_last = twin, last
        self.diagnose()
        result = self.diagnosis
        if result is None or self.current().campaign is not campaign:
            return
        last = self.next_plan
        asked, previous = (last.questions, last.answer) if last is not None else ((), None)
        plan = adaptive.next_rings(campaign, result, None, self.catalog, closed_loop.cadence_of(twin), asked, previous=previous)
        self.next_plan = plan
        final = result.steps[-1]
        self.adaptive_points.append((campaign.n_orientations, plan.spent_minutes, final.mae_um["mean"], final.noise_floor_um["mean"]))
        full = float(np.ptp(twin.times_s())) / 60.0  # the head's own full campaign, at its cadence
        head = (
            f"**{campaign.n_orientations} rings, {plan.spent_minutes:.0f} minutes at the machine** (the full campaign of "
            f"{len(twin.orientations)} rings: {full:.0f} min); check-ring MAE {final.mae_um['mean']:.3f} um, "
            f"{final.mae_um['mean'] / final.noise_floor_um['mean']:.2f}x its floor."
        )
        words = plan.lines()  # the stop in one line; else the plan's head, a line a ring, its time
        rings = [] if plan.stop else ["\n".join(" ".join(line.split()) for line in words[1:-1]), words[-1]]
        self.panel.show_adaptive([head, f"**{words[0]}**"], self.adaptive_points, not plan.stop, rings)
        self.panel.keep_in_view(f"{campaign.n_orientations} rings, ")

    def show_evidence(self, label: str) -> None:
        if self.diagnosis is not None:
            self.panel.show_evidence(label)

    def refit(self) -> None:
        """The hybrid with the ticked effects, fitted and measured on the check rings by diagnosis.add_effects."""
        p, ds = self.panel, self.current()
        ids = p.selected_effects()
        scanned = {c.effect: c for c in (self.diagnosis.candidates if self.diagnosis is not None else [])}
        shapes = {shape.id: shape.effect() for shape in (self.diagnosis.shapes if self.diagnosis is not None else ())}
        # At the settings the diagnosis found (e.g. 22 cycles per revolution), else the effect's own;
        # a shape at its knots.
        ticked = [shapes[i] if i in shapes else self.catalog[i](**scanned[i].settings) if i in scanned else self.catalog[i]() for i in ids]
        # The base model the diagnosis fitted (an adaptive campaign's) and a study's chain stay in the
        # model; a ticked effect already in it (same settings) is not added twice.
        base = list(self.diagnosis.chain[: len(self.diagnosis.base)]) if self.diagnosis is not None else []
        chain = base + (list(self.chain) if self.study_open else [])
        in_chain = {effect_label(e) for e in chain}
        effects = chain + [e for e in ticked if effect_label(e) not in in_chain]
        ids = [effect_label(e) for e in effects]
        if not ds.campaign.holdout_mask().any():
            p.done("**Cannot refit** — no held-out ring to measure the error on.", refit=True)
            return
        if not ids and (not self.steps or not self.steps[-1].added):
            # The baseline again: a step that adds nothing would repeat the history's last.
            p.done("**Nothing to refit** — tick an effect or a shape first (*Diagnose* ticks what it finds).", refit=True)
            return
        if not self.steps:
            p.show_progress("fitting the trilinear baseline…", 0.02, refit=True)
            self.steps = [diagnosis.add_effects(ds.campaign, [])[1]]
        label = ", ".join(ids) or "no effect"
        p.show_progress(f"refitting the hybrid with {label}…", 0.05, refit=True)
        hybrid, step = diagnosis.add_effects(
            ds.campaign,
            effects,
            progress=lambda stage, fraction: p.show_progress(f"{label}: {stage}", 0.05 + 0.9 * float(fraction), refit=True),
        )
        if ds.campaign is not self.current().campaign:
            return  # the data changed meanwhile
        self.refitted = effects  # the next save's chain, the report's model
        self.steps.append(step)
        p.show_history(self.steps)
        fitted = "; ".join(
            f"{e['effect']}: "
            + (
                self.catalog[e["effect"]].parameters_text(e["params"])
                if e["effect"] in self.catalog
                else f"its {len(e['params'])} values refitted"
            )
            for e in step.params
        )
        p.done(f"Refitted: {fitted or label}.", refit=True)  # its error: the fall line and the history under it
        p.keep_in_view("Check-ring MAE:")
        # No physical term ticked: the hybrid would be the baseline again; draw no separate curve.
        self.show(ds.with_model("hybrid", hybrid) if ids else ds.without_model("hybrid"))

    def save_study(self) -> None:
        """Write this run to the study: the last refit's effects (else the study's chain), the
        history, the last diagnosis's verdict; on top of the study as opened or last saved."""
        p, study = self.panel, self.study
        if study is None or not self.study_open:
            p.study_status.content = "**Cannot save** — no study of the data shown is open."
            return
        if self.diagnosis is None or not self.diagnosed:
            p.study_status.content = (
                "**Cannot save** — diagnose first: each saved run records one diagnosis (its verdict and uncertainties)."
            )
            return
        chain = self.refitted if self.refitted is not None else self.chain
        record = Study.of_run(self.diagnosis, chain, study.campaign, APP_DATA_PART, None, self.previous, steps=self.steps)
        try:
            study.save(record, self.previous)
        except InputError as error:
            p.study_status.content = f"**Cannot save** — {error.line()}"
            return
        except OSError as error:  # disk full, permissions: the study on disk stays whole (atomic write)
            p.study_status.content = f"**Cannot save** — {study.path}: {' '.join(str(error.strerror or error).split())}"
            return
        self.previous, self.chain, self.refitted, self.diagnosed = record, list(chain), None, False
        for box in p.effects.values():
            box.value = False  # what was ticked is in the study's chain now
        p.study_status.content = (
            f"Saved: run {len(record.runs)} to {study.name} (model: {' + '.join(effect_label(e) for e in chain) or 'the baseline alone'})."
        )
        self._show_study_line()

    def reveal(self) -> None:
        """What a teaching scenario hid in its data (the sidecar's hidden effects, with their true
        parameters) next to what this session found: the diagnosis's fit with its uncertainty, the last refit."""
        campaign = self.current().campaign
        scenario = campaign.scenario or {}
        hidden = [e for e in scenario.get("effects", []) if e.get("hidden")]
        if not teaching_scenario(campaign):
            self.panel.revealed.content = "_This campaign records no hidden effect (it is not a teaching scenario)._"
            return
        self.revealed = True
        found = {c.effect: c for c in reversed(self.diagnosis.candidates)} if self.diagnosis is not None else {}
        refitted = {p["effect"]: p["params"] for step in self.steps for p in step.params}
        lines = []
        for entry in hidden or [{"id": i} for i in scenario["hidden"]]:
            effect_id = str(entry["id"])
            cls = self.catalog.get(effect_id)
            truth = {k: float(v) for k, v in entry.items() if k not in ("id", "hidden")}
            text = cls.parameters_text if cls is not None else (lambda p, u=None: ", ".join(f"{k} {v:g}" for k, v in p.items()))
            # The truth, then what the diagnosis and the last refit found, flat under each hidden
            # effect's name (nested lists lose a line's width at 1440x900).
            lines.append(f"\n**Hidden: {cls.name if cls is not None else effect_id}** (`{effect_id}`)\n")
            lines.append(f"- truth: {text(truth) if truth else 'parameters not recorded'}")
            candidate = found.get(effect_id)
            if candidate is None:
                lines.append("- diagnosis: " + ("not diagnosed yet" if self.diagnosis is None else "not among the candidates"))
            else:
                verdict = "significant" if candidate.significant else "not significant"
                lines.append(f"- diagnosis ({verdict}, ± k = 2): {text(candidate.params, candidate.params_u)}")
            if effect_id in refitted:
                lines.append(f"- last refit: {text(refitted[effect_id])}")
            if cls is not None and (candidate is None or not candidate.significant):
                lines.append(f"- _{cls.teaching}_")  # else the verdict's "More" already teaches it
        self.panel.revealed.content = "\n".join(lines)
        # From the first effect's name to the last line's own words ("last refit:", "truth:", ...).
        last = next((line[2:].split(":")[0] + ":" for line in reversed(lines) if line.startswith("- ") and ":" in line), None)
        self.panel.keep_in_view("Hidden:", last)
