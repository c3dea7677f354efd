"""One browser's physics loop: diagnose -> tick effects -> refit -> the error history; reveal.

Each step is one call of ph_explorer.diagnosis, run on the session's worker thread (never on a
callback thread); the Physics tab (physics_panel.py) shows its progress and results. The loop
reads the session's data through `current()` and hands a changed Dataset back through `show()`,
so it never holds the session itself.
"""

from __future__ import annotations

from typing import Callable

from ph_explorer import diagnosis
from ph_explorer.app.dataset import Dataset
from ph_explorer.app.physics_panel import PhysicsPanel
from ph_explorer.effects import Catalog
from ph_explorer.errors import InputError
from ph_explorer.models.folder import MODEL_TYPES, baseline_of

DIAGNOSIS_FIGURE = "diagnosis: out-of-sample MAE / its floor"


class PhysicsLoop:
    """The diagnosis, the error history (baseline, + effects, ...) and the hybrid of one session."""

    def __init__(self, panel: PhysicsPanel, catalog: Catalog, current: Callable[[], Dataset], show: Callable[[Dataset], None]) -> None:
        self.panel = panel
        self.catalog = catalog  # the effects this session diagnoses and fits with
        self.current = current  # the Dataset the session shows now
        self.show = show  # show another Dataset (one with a new model or figure)
        self.diagnosis: diagnosis.Diagnosis | None = None
        self.steps: list[diagnosis.Step] = []

    def clear(self) -> None:
        """New data: the diagnosis and history of the old data no longer apply."""
        self.diagnosis = None
        self.steps = []
        self.panel.clear()

    def diagnose(self) -> None:
        """Where the loaded baseline fails out of sample, and which effect is missing (none added)."""
        p, ds = self.panel, self.current()
        n_effects = len(self.catalog.candidates())
        seen: list[str] = []

        def progress(effect_id: str) -> None:
            seen.append(str(effect_id))
            p.show_progress(f"scanning {effect_id} against the out-of-sample residual…", len(seen) / (n_effects + 1))

        p.show_progress("out-of-sample residuals of the baseline (leave one orientation out)…", 0.02)
        try:
            # The loaded model is the baseline, as in the command line.
            baseline = baseline_of({k: v for k, v in ds.models.items() if k in MODEL_TYPES})
            result = diagnosis.diagnose(ds.campaign, add=[], baseline=baseline, catalog=self.catalog, progress=progress)
        except InputError as error:
            p.done(f"**Cannot diagnose** — {error.line()}")
            return
        if ds.campaign is not self.current().campaign:
            return  # the data changed meanwhile: this diagnosis is about data no longer shown
        self.diagnosis = result
        p.show_diagnosis(result)
        if p.evidence_of.visible:
            p.evidence_of.value = p.evidence_of.options[0]
            self.show_evidence(p.evidence_of.value)
        # The diagnosis' per-orientation out-of-sample error becomes a field figure.
        ds.add_figure(
            DIAGNOSIS_FIGURE,
            result.out_of_sample_mae_um["mean"] / result.out_of_sample_floor_um["mean"],
            "x the floor of each ring; training rings by leave-one-out, check rings by the baseline (ph_explorer.diagnosis)",
        )
        self.show(ds)
        self.steps = [result.steps[0]]
        p.show_history(self.steps)
        p.done(f"Diagnosed: {len(result.candidates)} candidate effects scanned.")

    def show_evidence(self, label: str) -> None:
        if self.diagnosis is not None:
            self.panel.show_evidence(label)

    def refit(self) -> None:
        """The hybrid with the ticked effects, fitted and measured on the check rings by diagnosis.add_effects."""
        p, ds = self.panel, self.current()
        ids = p.selected_effects()
        scanned = {c.effect: c for c in (self.diagnosis.candidates if self.diagnosis is not None else [])}
        # At the settings the diagnosis found (e.g. 22 cycles per revolution), else the effect's own.
        effects = [self.catalog[i](**scanned[i].settings) if i in scanned else self.catalog[i]() for i in ids]
        if not ds.campaign.holdout_mask().any():
            p.done("**Cannot refit** — no held-out ring to measure the error on.", refit=True)
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
        self.steps.append(step)
        p.show_history(self.steps)
        fitted = "; ".join(f"{e['effect']}: {self.catalog[e['effect']].parameters_text(e['params'])}" for e in step.params)
        p.done(
            f"Hybrid ({label}): check-ring MAE **{step.mae_um['mean']:.3f} um** vs mean, "
            f"{step.mae_um['single']:.3f} um vs single. {fitted}",
            refit=True,
        )
        # No physical term ticked: the hybrid would be the baseline again; draw no separate curve.
        self.show(ds.with_model("hybrid", hybrid) if ids else ds.without_model("hybrid"))

    def reveal(self) -> None:
        """What a teaching scenario hid in its data (from the campaign's sidecar)."""
        hidden = (self.current().campaign.scenario or {}).get("hidden")
        if not hidden:
            self.panel.revealed.content = "_This campaign records no hidden effect (it is not a teaching scenario)._"
            return
        lines = []
        for effect_id in hidden:
            cls = self.catalog.get(effect_id)
            name, teaching = (cls.name, cls.teaching) if cls is not None else (effect_id, "")
            lines.append(f"- **{name}** (`{effect_id}`): {teaching}")
        self.panel.revealed.content = "Hidden in this scenario:\n" + "\n".join(lines)
