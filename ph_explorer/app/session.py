"""One browser of `ph-explorer serve`: its sliders, view, data, physics loop and render bookkeeping.

The callbacks only translate GUI events into calls: a slider move asks for a render, a button
submits a job of the physics loop or a data load to this session's worker thread. Renders follow
render_queue.py: a browser's move only marks the session dirty and the app's one render thread
draws it; values set by the server itself (`go_to`, tests, scripts) are drawn in the caller's
thread, and `go_to` returns once its orientation is drawn.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field

import numpy as np
import viser

from ph_explorer.app.accessibility import name_inputs
from ph_explorer.app.background import FOREGROUND
from ph_explorer.app.camera import ViewCamera
from ph_explorer.app.dataset import Dataset, dataset_for, read_uploaded_campaign, simulated_scenario
from ph_explorer.app.field import ErrorField
from ph_explorer.app.map_panel import MapPanel
from ph_explorer.app.orientation_view import OrientationView
from ph_explorer.app.panels import PAPER_PRESETS, ChartsPanel, ControlsPanel, DataPanel, FiguresPanel, TablesPanel, wrap_b
from ph_explorer.app.physics import PhysicsLoop, teaching_scenario
from ph_explorer.app.physics_panel import PhysicsPanel
from ph_explorer.app.render_queue import Following, RenderQueue, RenderState, RenderStats, WhenResting
from ph_explorer.app.report_panel import ReportPanel
from ph_explorer.app.ring import RingScene
from ph_explorer.app.scene import HeadScene
from ph_explorer.app.study_file import StudyFile
from ph_explorer.campaign import Campaign, orientation_label
from ph_explorer.effects import Catalog
from ph_explorer.errors import InputError
from ph_explorer.figures.polar import polar_scale
from ph_explorer.twin import Scenario

INITIAL_ORIENTATION = PAPER_PRESETS["A15 B-20"]
RENDER_WAIT_S = 30.0  # how long a render by the server itself (go_to) waits for the render thread to end this session's


@dataclass(frozen=True)
class Shared:
    """What the sessions of one app share."""

    renders: RenderQueue  # the one render thread
    heavy: threading.BoundedSemaphore  # diagnoses, refits and loads running at once over all sessions
    catalog: Catalog  # the effects a session diagnoses and fits with
    scenarios: Mapping[str, Scenario]  # the shipped scenarios by name
    geometry_overrides: Mapping[str, float] = field(default_factory=dict)  # applied to uploaded files
    stats: RenderStats = field(default_factory=RenderStats)
    following_stats: RenderStats = field(default_factory=RenderStats)  # the renders that catch up what follows
    study: StudyFile | None = None  # the operator's study (serve --study), continued by every browser


TASK_SETTLE_S = 0.5  # the sliders at rest this long: compute the task's RONt (a second or so per model)
# A browser's slider move draws the head, the curves, the polar plot and the map's marker; what follows
# (Tables 1-3, the charts, a following camera) at most this often, and at the last orientation drawn.
FOLLOW_INTERVAL_S = 0.25


class Session:
    """One browser: its sliders, its view, its data, its hybrid model and history."""

    def __init__(self, shared: Shared, client: viser.ClientHandle, dataset: Dataset) -> None:
        self.shared = shared
        self.catalog = shared.catalog
        self.client = client
        self.dataset = dataset
        self.jobs: list[Future[None]] = []
        self.view = dataset.view(*INITIAL_ORIENTATION)  # the last view drawn
        self.render_state = RenderState(self._render, on_timed=shared.stats.rendered)
        # This browser's heavy jobs run in order on its own thread; shared.heavy bounds them overall.
        self._jobs = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"ph-explorer-{client.client_id}")
        self._moving = False  # sliders being set together (go_to): render once at the end
        self._field_token = 0  # the latest field request; older computations do not draw
        self._closed = False  # the browser left (close)
        self.uploaded: tuple[str, bytes] | None = None  # the CSV uploaded last, while it is the data: its sidecar joins it
        self.camera = ViewCamera(client, lambda: (self.head, self.ring))
        self.following = Following(self._draw_following, shared.renders, FOLLOW_INTERVAL_S, shared.following_stats.rendered)
        # The task's RONt, once the sliders rest, on its own thread (a diagnosis does not hold it back).
        self._task = WhenResting(self._compute_task, TASK_SETTLE_S, name=f"ph-explorer-task-{client.client_id}")

        scene, gui = client.scene, client.gui
        geometry = dataset.campaign.geometry
        a0, b0 = INITIAL_ORIENTATION
        with client.atomic():
            self.head = HeadScene(scene, geometry)
            self.ring = RingScene(scene, geometry)
            self.field = ErrorField(scene)
            self.field.on_pick(self.go_to)
            self.controls = ControlsPanel(gui, a0, b0, dataset.a_range)
            # The flat polar plot and the error map in their own panel, always in view beside the
            # controls (issue 15: a teacher reads both at every step of the loop, nothing scrolled).
            self.figures = FiguresPanel(gui)
            self.polar = self.figures.polar
            tabs = gui.add_tab_group()
            with tabs.add_tab("Physics"):
                self.physics = PhysicsPanel(gui, self.catalog, study=shared.study is not None)
            with tabs.add_tab("Map"):
                self.map_panel = MapPanel(gui, dataset.figure_names(), self.go_to, self.figures.map_plot)
            with tabs.add_tab("Tables 1-3"):
                self.tables = TablesPanel(gui)
            with tabs.add_tab("Charts"):
                self.charts = ChartsPanel(gui, self.view, self.controls.shown())
            with tabs.add_tab("Data"):
                self.data_panel = DataPanel(gui, {name: s.purpose for name, s in shared.scenarios.items()})
                self.report_panel = ReportPanel(gui, self)  # Export report, Open study
        name_inputs(client)  # sliders reachable by their labels (a screen reader, a test's get_by_label)
        self.loop = PhysicsLoop(
            self.physics, self.catalog, lambda: self.dataset, self.set_dataset, shared.study, self.map_panel.propose, self._new_data
        )
        self._wire()
        self.set_dataset(dataset)
        self.loop.open_study()

    # -- wiring: GUI events -> calls, nothing else ---------------------------------------------------
    def _wire(self) -> None:
        c, p, data = self.controls, self.physics, self.data_panel
        for handle in (c.a, c.b, c.magnification, c.repetitions, c.band, c.band_of, c.band_model_error, self.tables.task, *c.show.values()):
            handle.on_update(self._control_changed)
        c.presets.on_click(lambda event: self.go_to(*PAPER_PRESETS[event.target.value]))
        c.view_ring.on_click(lambda event: self.look(event.target.value))
        # The browser reports its camera on every orbit and resize: a followed View fits its canvas.
        self.client.camera.on_update(lambda _: self.camera.reframe() if c.follow.value else None)
        self.map_panel.figure.on_update(lambda _: self.refresh_field())
        self.map_panel.show.on_update(lambda _: self.field.set_visible(bool(self.map_panel.show.value)))
        data.upload.on_upload(lambda _: self.submit(self.load_upload, data.upload.value.name, data.upload.value.content))
        data.sidecar.on_upload(lambda _: self.submit(self.load_sidecar, data.sidecar.value.name, data.sidecar.value.content))
        p.diagnose.on_click(lambda _: self.submit(self.loop.diagnose))
        p.refit.on_click(lambda _: self.submit(self.loop.refit))
        p.save_study.on_click(lambda _: self.submit(self.loop.save_study))
        p.reveal.on_click(lambda _: self.report_panel.reveal_hidden())
        p.decide.on_click(lambda _: self.submit(self.loop.decide))
        p.measure.on_click(lambda _: self.submit(self.loop.measure))
        p.adaptive_start.on_click(lambda _: self.submit(self.loop.start_adaptive))
        p.adaptive_next.on_click(lambda _: self.submit(self.loop.measure_next))
        p.download_rings.on_click(lambda _: self.report_panel.send_rings())
        p.evidence_of.on_update(lambda _: self.loop.show_evidence(p.evidence_of.value))

        @c.worst.on_update
        def _(_: viser.GuiEvent) -> None:
            if c.worst.value in c.worst_targets:
                self.go_to(*c.worst_targets[c.worst.value])

        @c.follow.on_update
        def _(_: viser.GuiEvent) -> None:
            if c.follow.value:  # back to following: the ring's view, even after "whole field"
                self.camera.follow(*self.orientation, resume=True)

        @data.scenario.on_update
        def _(_: viser.GuiEvent) -> None:
            name = data.chosen()
            if name in self.shared.scenarios:
                self.submit(self.load_scenario, name)

    def _control_changed(self, event: viser.GuiEvent) -> None:
        if event.client is not None:
            # A browser's message: viser stamped the value when its event loop applied it.
            self.shared.renders.request(self.render_state, since=event.target.update_timestamp)
        elif not self._moving:  # set by the server (a test, a script): drawn when this returns, here
            self._draw_here()

    # -- orientation and camera ------------------------------------------------------------------------
    @property
    def orientation(self) -> tuple[float, float]:
        return float(self.controls.a.value), float(self.controls.b.value)

    def go_to(self, a_deg: float, b_deg: float) -> None:
        """Move both sliders (a preset, a marker click), then render once; returns once it is drawn."""
        self._moving = True
        try:
            self.controls.a.value = float(np.clip(a_deg, self.controls.a.min, self.controls.a.max))
            self.controls.b.value = wrap_b(b_deg)
        finally:
            self._moving = False
        self._draw_here()

    def look(self, view: str) -> None:
        """Point this browser's camera: 'ring + head', 'along the axis' or 'whole field'."""
        self.camera.look(view, *self.orientation)

    # -- rendering ---------------------------------------------------------------------------------
    @property
    def render_count(self) -> int:
        return self.render_state.render_count

    def wait_rendered(self, timeout: float = 10.0) -> bool:
        """Wait until this session's latest values are drawn, and what follows them; False on timeout."""
        deadline = time.monotonic() + timeout
        return self.render_state.wait_rendered(timeout) and self.following.wait_caught_up(max(0.0, deadline - time.monotonic()))

    def _draw_here(self) -> None:
        """Values set by the server (go_to, a script, a test): drawn when this returns, what follows them too."""
        if self.render_state.render_now(wait=True, timeout=RENDER_WAIT_S):  # False inside its own render
            self.following.wait_caught_up(RENDER_WAIT_S)

    def _render(self) -> None:
        try:
            self._draw()
        except Exception as error:  # counted for the benchmarks, then reported by the render queue
            self.shared.stats.failed(error)
            raise

    def _draw(self) -> None:
        """Draw this session's latest values: head, ring and curves, field marker, tables, charts."""
        a, b = self.orientation
        ds = self.dataset
        view = ds.view(a, b)
        shown = self.controls.shown()
        band_model = self.controls.band.value
        kind = self.controls.band_kind()
        band = (
            (band_model, *ds.band(band_model, a, b, bool(self.controls.band_model_error.value), kind)) if band_model in ds.models else None
        )
        if view.measured:
            title = f"{orientation_label(a, b)} measured ({'held-out check ring' if view.held_out else 'training ring'})"
        else:
            title = f"{orientation_label(a, b)} — prediction (not measured)"
        c = self.controls
        # The chart's base radius keeps the campaign's touches (but its rarest), this ring's own and
        # the curves drawn here off the centre (ph_explorer.figures.polar), repetitions shown or not.
        own = () if view.repetitions is None else (view.repetitions,)
        drawn = [ds.campaign_bounds_um, *own, *view.curves.values(), *(band[1:] if band is not None else ())]
        scale = polar_scale(float(c.magnification.value), drawn, self.ring.bore_radius)
        show_repetitions = bool(c.repetitions.value)
        with self.client.atomic():
            self.head.update(a, b)
            self.ring.place(a, b)
            self.ring.update(view.curves, shown, scale, view.repetitions, show_repetitions, band, title)
            self.polar.update(scale, view, shown, show_repetitions, band, title)
            self.field.highlight(a, b, ds.campaign.geometry.pivot_to_ball_mm)
            self.map_panel.draw(a, b)
            if self.following.due():
                self._draw_following(view, shown)
        self.view = view
        self._want_task(a, b)

    def _draw_following(self, view: OrientationView | None = None, shown: Mapping[str, bool] | None = None) -> None:
        """What follows the sliders (FOLLOW_INTERVAL_S), by default at the orientation drawn last."""
        view = self.view if view is None else view
        with self.client.atomic():
            self.tables.update(view, self.dataset)
            self.charts.update(view, self.controls.shown() if shown is None else shown)
            if self.controls.follow.value:
                self.camera.follow(view.a_deg, view.b_deg)

    # -- the task's RONt, once the sliders rest ------------------------------------------------------------
    def _want_task(self, a: float, b: float) -> None:
        """Ask for the task's RONt here unless it is known; computed when A and B have rested TASK_SETTLE_S."""
        ds = self.dataset
        if self.tables.task.value and any(ds.cached_task(m, a, b) is None for m in ds.model_names):
            self._task.want(a, b)

    def _compute_task(self, a: float, b: float) -> None:
        if self._closed or self.orientation != (a, b):
            return  # gone elsewhere (that orientation asks for itself), or the browser left
        ds = self.dataset
        try:
            for model in ds.model_names:
                FOREGROUND.wait_idle()  # a clicked job first, alone; then a model at a time
                with self.shared.heavy:  # asked again once its turn comes: other browsers' jobs go first
                    if self._closed or self.orientation != (a, b):
                        return
                    ds.task(model, a, b)
        except Exception as error:  # the tables say it; the server log keeps the rest
            self.data_panel.show_info(f"**Error** — RONt of one measurement: {type(error).__name__}: {' '.join(str(error).split())}")
            raise
        self.shared.renders.request(self.render_state)

    # -- data ----------------------------------------------------------------------------------------
    def set_dataset(self, dataset: Dataset) -> None:
        """Show another campaign (or the same with a new model or figure) in this browser."""
        geometry_changed = dataset.campaign.geometry != self.dataset.campaign.geometry
        self.dataset = dataset
        dataset.prepare_in_background()
        if geometry_changed:
            with self.client.atomic():
                self.ring.frame.remove()
                self.head.root.remove()
                self.head = HeadScene(self.client.scene, dataset.campaign.geometry)
                self.ring = RingScene(self.client.scene, dataset.campaign.geometry)
        self._moving = True  # a value clipped into the new A range is drawn below, once
        try:
            self.controls.set_a_range(*dataset.a_range)
        finally:
            self._moving = False
        self.controls.set_models(dataset.model_names)
        self.map_panel.set_names(dataset.figure_names())
        self.data_panel.set_source(dataset)
        # Teaching-only controls for a teaching scenario only: a lab's campaign hides nothing to reveal.
        teaching = teaching_scenario(dataset.campaign)
        self.physics.reveal.visible = self.report_panel.reveal.visible = self.physics.adaptive_folder.visible = teaching
        self.show_failing()
        self.refresh_field()
        self._draw_here()

    def refresh_field(self) -> None:
        """Redraw the error map and recolour the 3D field; slow figures are computed on the worker."""
        self._field_token += 1
        token, dataset, name = self._field_token, self.dataset, self.map_panel.figure.value
        if name not in dataset.figure_names():
            return
        if dataset.has_figure(name):
            self._apply_field(dataset, name)
            return
        self.map_panel.computing()

        def compute() -> None:
            dataset.figure(name)
            if token == self._field_token:
                self._apply_field(dataset, name)

        self.submit(compute)

    def _apply_field(self, dataset: Dataset, name: str) -> None:
        figure = dataset.figure(name)
        held_out = dataset.held_out_mask
        a, b = self.orientation
        with self.client.atomic():
            self.field.set_values(dataset.campaign.orientations, figure.values, held_out)
            self.field.set_visible(bool(self.map_panel.show.value))
            self.map_panel.set_figure(name, figure, dataset.campaign.orientations, held_out)
            self.map_panel.draw(a, b)
            self.controls.set_worst(dataset.worst_orientations(name), figure, name)
        self.field.highlight(a, b, dataset.campaign.geometry.pivot_to_ball_mm)

    def show_failing(self) -> None:
        """The rings the last diagnosis finds beyond their noise, worst first (none before a diagnosis)."""
        result = self.loop.diagnosis
        tested = result is None or result.within_noise["baseline"] is not None
        self.map_panel.set_failing(None if result is None else result.failing_rings(), tested, result.baseline_model if result else "")

    def load_upload(self, name: str, content: bytes, sidecar: tuple[str, bytes] | None = None) -> None:
        """A CSV from the browser (and its sidecar TOML) read as the command line reads them; a bad file keeps the data."""
        self.controls.working(f"Reading {name}…", 0.05)
        try:
            campaign = read_uploaded_campaign(name, content, self.shared.geometry_overrides, sidecar)
        except (InputError, ValueError) as error:  # its line, or a campaign the core refuses (e.g. inconsistent shapes)
            self.data_panel.show_error(error.line() if isinstance(error, InputError) else f"{name}: {' '.join(str(error).split())}")
            return
        finally:
            self.controls.idle()
        self.data_panel.show_loaded(campaign, None if sidecar is None else sidecar[0])
        self._new_data(campaign, f"uploaded {campaign.source}")
        self.uploaded = (name, content)

    def load_sidecar(self, name: str, content: bytes) -> None:
        """The uploaded CSV read again beside this sidecar TOML (its check rings, its geometry)."""
        if self.uploaded is not None:
            return self.load_upload(*self.uploaded, sidecar=(name, content))
        self.data_panel.show_error(f"{name}: upload the campaign CSV first; its sidecar is read beside it")

    def load_scenario(self, name: str) -> None:
        """A shipped scenario, simulated by the twin."""
        self.data_panel.show_info(f"Simulating scenario **{name}**…")
        self.controls.working(f"Scenario {name}: simulating the campaign…", 0.05)
        try:
            campaign = simulated_scenario(name)
        except InputError as error:
            self.controls.idle()
            self.data_panel.show_error(error.line())
            return
        self.data_panel.show_info(
            f"Scenario **{name}** simulated by the twin. {self.shared.scenarios[name].description if name in self.shared.scenarios else ''}"
        )
        self._new_data(campaign, f"scenario {name} (simulated by the twin)", name)

    def _new_data(self, campaign: Campaign, label: str, what: str | None = None) -> None:
        """Fit the models to new data and show it, the progress above the fold (a few seconds)."""
        what = what or campaign.source or label
        self.uploaded = None  # a sidecar uploaded next joins an uploaded CSV only (load_upload sets it again)
        try:
            self.controls.working(f"{what}: fitting the models (leave one orientation out)…", 0.3)
            dataset = dataset_for(campaign, label, None)
            dataset.figure(dataset.figure_names()[0])  # the map's first figure (leave-one-out fits), drawn with the data
            self.controls.working(f"{what}: drawing the field and the rings…", 0.8)
            self.loop.clear()
            self.set_dataset(dataset)
            self.data_panel.forget(keep=what)  # nothing of the old data stays: its scenario, its report's line
            self.report_panel.status.content = ""
        finally:
            self.controls.idle()

    # -- worker jobs ---------------------------------------------------------------------------------
    def submit(self, job: Callable[..., None], *args: object) -> Future[None]:
        """Run heavy work off the callback thread: after this session's earlier jobs, a few at once overall."""
        future = self._jobs.submit(self._guarded, job, *args)
        self.jobs.append(future)
        return future

    def _guarded(self, job: Callable[..., None], *args: object) -> None:
        with self.shared.heavy, FOREGROUND.running():
            try:
                job(*args)
            except Exception as error:  # the browser shows one line; the server log keeps the rest
                line = f"**Error** — {type(error).__name__}: {' '.join(str(error).split())}"
                self.data_panel.show_info(line)
                self.physics.done(line)
                self.physics.done(line, refit=True)
                raise

    def wait(self, timeout: float = 60.0) -> None:
        """Wait for this session's worker jobs, then for its latest values to be drawn (tests, scripts)."""
        deadline = time.monotonic() + timeout
        while self.jobs:
            self.jobs.pop(0).result(timeout=max(0.1, deadline - time.monotonic()))
        if not self.wait_rendered(timeout=max(0.1, deadline - time.monotonic())):
            raise TimeoutError("the session's latest values were not drawn in time")

    def close(self) -> None:
        self._closed = True  # a RONt under way stops after its model: nobody will see the rest
        self.following.close()
        self._task.close()
        self.render_state.close()
        self._jobs.shutdown(wait=False, cancel_futures=True)
