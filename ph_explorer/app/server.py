"""`ph-explorer serve`: the viser server, one Session per browser, heavy work on worker threads.

Each browser (viser client) gets its own Session: its own sliders, scene objects and panels,
and its own data once it uploads a file or picks a scenario. A slider move from a browser only
notes that its session is dirty (and since when); ONE render thread per app draws the dirty
sessions in the order they became dirty (oldest request first, a session re-queued at the back
when it moved again meanwhile), each render with that session's latest values: moves that arrive
before their session's turn are coalesced, the latest value wins. One renderer because renders are
Python under the interpreter lock: thirty renders at once in viser's callback threads each took
thirty times as long. Values set by the server itself (`go_to`, tests, scripts) render in the
caller's thread and `go_to` returns once its orientation is drawn. Diagnoses, refits, scenario
simulations, uploads and slow figures run on worker threads (in order within a session, at most
HEAVY_JOBS at once over all sessions) and never hold a lock that a slider update needs.

For benchmarks and scripts (stable names)::

    from ph_explorer.app.server import build_server
    from ph_explorer.app.headless import open_session

    app = build_server(port=0)          # the default data, in-process, a free port
    app.startup_s                       # seconds from the call to a ready server
    browser, session = open_session(app)  # a simulated browser and its Session
    session.go_to(43.0, 90.0)           # move that browser's sliders (renders once)
    session.controls.a.value = 50.0     # or one slider, as a user would
    app.render_times                    # server seconds per render, every session (a deque)
    app.latency_times                   # seconds from a slider event to the end of its render
    session.render_times                # the same for one session (also session.latency_times)
    session.wait_rendered()             # until that browser's latest values are drawn
    browser.close(); app.stop()
"""

from __future__ import annotations

import os
import threading
import time
import traceback
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import viser

from ph_explorer import diagnosis
from ph_explorer.app.dataset import (
    Dataset,
    dataset_for,
    default_dataset,
    read_uploaded_campaign,
    scenario_descriptions,
    simulated_scenario,
)
from ph_explorer.app.panels import (
    NO_CHOICE,
    PAPER_PRESETS,
    ChartsPanel,
    ControlsPanel,
    DataPanel,
    FieldPanel,
    PhysicsPanel,
    TablesPanel,
    orientation_label,
    parameters_text,
    parse_orientation_label,
)
from ph_explorer.app.scene import ErrorField, HeadScene, RingScene, axis_camera, ring_camera
from ph_explorer.effects import CATALOG
from ph_explorer.errors import InputError

INITIAL_ORIENTATION = PAPER_PRESETS["A15 B-20"]
# The whole error field (dome of stylus directions, radius 300 mm) seen from outside, mm.
FIELD_VIEW = {"position": (560.0, -700.0, 360.0), "look_at": (0.0, 0.0, -60.0)}


# Diagnoses and refits running at once over all browsers (the machine's cores; the rest queue).
HEAVY_JOBS = 2
# The longest a synchronous render (go_to) waits for the render thread to finish this session's render.
RENDER_WAIT_S = 30.0


def effect_names() -> dict[str, str]:
    """id -> name of the catalog effects a hybrid can take (not the pure noise)."""
    return {effect_id: cls.name for effect_id, cls in CATALOG.items() if effect_id not in diagnosis.NOT_CANDIDATES}


def effect_units() -> dict[str, dict[str, str]]:
    """id -> parameter name -> unit, from the catalog's Parameter lists."""
    return {effect_id: {p.name: p.unit for p in cls.parameters} for effect_id, cls in CATALOG.items()}


class Session:
    """One browser: its sliders, its view, its data, its hybrid model and history."""

    def __init__(self, app: "ExplorerApp", client: Any, dataset: Dataset) -> None:
        self.app = app
        self.client = client
        self.dataset = dataset
        self.steps: list[diagnosis.Step] = []  # the error history: baseline, + effects, ...
        self.diagnosis: diagnosis.Diagnosis | None = None
        self.jobs: list[Future] = []
        self.render_count = 0
        self.render_times: deque[float] = deque(maxlen=10_000)  # server seconds per render
        # Seconds from the oldest slider event a render drew to the end of that render (wall clock).
        self.latency_times: deque[float] = deque(maxlen=10_000)
        self.view: Any = None
        # This browser's heavy jobs run in order on its own thread; app.heavy bounds them overall.
        self._jobs = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"ph-explorer-{client.client_id}")
        # Guards _dirty/_rendering/_pending_since; notified when a render of this session ends.
        self._render_state = threading.Condition()
        self._dirty = False  # values changed since the last render took them
        self._rendering = False  # a thread (the app's render thread or a caller) is rendering this session
        self._pending_since: float | None = None  # time.time() of the oldest event not yet drawn
        self._closed = False
        self._moving = False  # sliders being set together (a preset): render once at the end
        self._field_token = 0

        scene, gui = client.scene, client.gui
        geometry = dataset.campaign.geometry
        a0, b0 = INITIAL_ORIENTATION
        with client.atomic():
            self.head = HeadScene(scene, geometry)
            self.ring = RingScene(scene, geometry)
            self.field = ErrorField(scene)
            self.field.on_pick(self.go_to)
            self.controls = ControlsPanel(gui, a0, b0)
            tabs = gui.add_tab_group()
            with tabs.add_tab("Tables 1-3", icon=viser.Icon.TABLE):
                self.tables = TablesPanel(gui)
            with tabs.add_tab("Charts", icon=viser.Icon.CHART_LINE):
                self.charts = ChartsPanel(gui, dataset.view(a0, b0), self.controls.shown())
            with tabs.add_tab("Physics", icon=viser.Icon.FLASK):
                self.physics = PhysicsPanel(gui, effect_names())
            with tabs.add_tab("Field", icon=viser.Icon.WORLD):
                self.field_panel = FieldPanel(gui, dataset.figure_names())
            with tabs.add_tab("Data", icon=viser.Icon.DATABASE):
                self.data_panel = DataPanel(gui, app.scenarios)
        self._camera_at: tuple[float, float] | None = None
        self._camera_view = "ring + head"
        self._wire()
        self.set_dataset(dataset)

    # -- wiring: GUI events -> calls of the core, nothing else ------------------------------------
    def _wire(self) -> None:
        c = self.controls
        for handle in (c.a, c.b, c.magnification, c.repetitions, c.band, *c.show.values()):
            handle.on_update(self._control_changed)

        @c.presets.on_click
        def _(event: Any) -> None:
            self.go_to(*PAPER_PRESETS[event.target.value])

        @c.worst.on_update
        def _(event: Any) -> None:
            target = parse_orientation_label(c.worst.value)
            if target is not None:
                self.go_to(*target)

        @c.view_ring.on_click
        def _(event: Any) -> None:
            self.look(event.target.value)

        @c.follow.on_update
        def _(event: Any) -> None:
            if c.follow.value:
                self.look("ring + head" if self._camera_view == "whole field" else self._camera_view)

        @self.field_panel.figure.on_update
        def _(event: Any) -> None:
            self.refresh_field()

        @self.field_panel.show.on_update
        def _(event: Any) -> None:
            self.field.set_visible(bool(self.field_panel.show.value))

        @self.data_panel.upload.on_upload
        def _(event: Any) -> None:
            uploaded = self.data_panel.upload.value
            self.submit(self._load_upload, uploaded.name, uploaded.content)

        @self.data_panel.scenario.on_update
        def _(event: Any) -> None:
            name = self.data_panel.scenario.value
            if name != NO_CHOICE and not name.startswith("("):
                self.submit(self._load_scenario, name)

        p = self.physics
        p.diagnose.on_click(lambda _event: self.submit(self._diagnose))
        p.refit.on_click(lambda _event: self.submit(self._refit))
        p.reveal.on_click(lambda _event: self._reveal())

        @p.evidence_of.on_update
        def _(event: Any) -> None:
            self._show_evidence(p.evidence_of.value)

    # -- orientation ---------------------------------------------------------------------------
    @property
    def orientation(self) -> tuple[float, float]:
        return float(self.controls.a.value), float(self.controls.b.value)

    def go_to(self, a_deg: float, b_deg: float) -> None:
        """Move both sliders (a preset, a marker click), then render once; returns once it is drawn."""
        self._moving = True
        try:
            self.controls.a.value = float(np.clip(a_deg, 0.0, 115.0))
            self.controls.b.value = float(((b_deg + 180.0) % 360.0) - 180.0 if b_deg != 180.0 else 180.0)
        finally:
            self._moving = False
        self.render_now(wait=True)

    def look(self, view: str) -> None:
        """Point this browser's camera: 'ring + head', 'along the axis' or 'whole field'."""
        a, b = self.orientation
        axial = self.dataset.campaign.geometry.axial_distance_mm
        if view == "along the axis":
            position, look_at = axis_camera(a, b, axial)
        elif view == "whole field":
            position, look_at = np.array(FIELD_VIEW["position"]), np.array(FIELD_VIEW["look_at"])
        else:
            position, look_at = ring_camera(a, b, axial)
        with self.client.atomic():  # position first: viser moves look_at along with it
            self.client.camera.position = position
            self.client.camera.look_at = look_at
        self._camera_at = (a, b)
        self._camera_view = view  # the view a following camera keeps

    def _control_changed(self, event: Any) -> None:
        if event.client is not None:
            # A browser's message: viser stamped the value when its event loop applied it.
            stamp = getattr(getattr(event.target, "_impl", None), "update_timestamp", None)
            self.request_render(since=stamp)
        elif not self._moving:  # set by the server (a test, a script): draw it in this thread
            self.render_now(wait=False)

    def _mark_dirty(self, since: float | None) -> None:
        """Under _render_state: the values changed at `since` (time.time()); keep the oldest pending."""
        since = time.time() if since is None else float(since)
        self._dirty = True
        if self._pending_since is None or since < self._pending_since:
            self._pending_since = since

    def _take(self) -> float:
        """Under _render_state: start a render of the latest values; return since when they were pending."""
        since = self._pending_since if self._pending_since is not None else time.time()
        self._dirty, self._pending_since, self._rendering = False, None, True
        return since

    def request_render(self, since: float | None = None) -> None:
        """Note that this session's values changed; the app's render thread draws the latest ones.

        Never blocks on a render: a browser's slider callback returns at once. A session being
        rendered is not queued now: its renderer re-queues it (at the back) or renders again.
        """
        with self._render_state:
            self._mark_dirty(since)
            queue = not self._rendering
        if queue:
            self.app.schedule_render(self)

    def render_now(self, wait: bool = True) -> None:
        """Render in this thread, looping until this session's latest values are drawn.

        When another thread is rendering this session: with wait, wait for that render to end and
        then draw what is still pending (so the caller returns with its values drawn); without wait,
        leave the new values to that thread (it renders once more, or re-queues the session).
        """
        if self._moving:
            return
        deadline = time.monotonic() + RENDER_WAIT_S
        with self._render_state:
            self._mark_dirty(None)
            while self._rendering:
                remaining = deadline - time.monotonic()
                if not wait or remaining <= 0:
                    return
                self._render_state.wait(remaining)
            if not self._dirty:
                return  # drawn meanwhile by the render thread
            since = self._take()
        try:
            while True:
                self._timed_render(since)
                with self._render_state:
                    if not self._dirty:
                        self._rendering = False
                        self._render_state.notify_all()
                        return
                    since = self._take()
        except BaseException:
            with self._render_state:
                self._rendering = False
                self._render_state.notify_all()
            raise

    def render_queued(self) -> None:
        """The app's render thread: draw this session's latest values once (re-queued if it moved again)."""
        with self._render_state:
            if self._rendering or not self._dirty or self._closed:
                return  # another thread is drawing it, or it is clean, or gone
            since = self._take()
        try:
            self._timed_render(since)
        finally:
            with self._render_state:
                self._rendering = False
                again = self._dirty and not self._closed
                self._render_state.notify_all()
            if again:
                self.app.schedule_render(self)

    def _timed_render(self, since: float) -> None:
        self._render()
        latency = max(0.0, time.time() - since)
        self.latency_times.append(latency)
        self.app.latency_times.append(latency)

    @property
    def render_idle(self) -> bool:
        """No render running or pending: the latest values are drawn."""
        with self._render_state:
            return not (self._dirty or self._rendering)

    def wait_rendered(self, timeout: float = 10.0) -> bool:
        """Wait until this session's latest values are drawn; False on timeout."""
        deadline = time.monotonic() + timeout
        with self._render_state:
            while self._dirty or self._rendering:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                # The render thread notifies at the end of each render; a re-queued session waits its turn.
                self._render_state.wait(min(remaining, 0.05))
            return True

    def _render(self) -> None:
        start = time.perf_counter()
        a, b = self.orientation
        ds = self.dataset
        view = ds.view(a, b)
        shown = self.controls.shown()
        band_model = self.controls.band.value
        band = None
        if band_model in ds.models:
            low, high = ds.monte_carlo_band(band_model, a, b)
            band = (band_model, low, high)
        if view.measured:
            state = "held-out check ring" if view.held_out else "training ring"
            title = f"{orientation_label(a, b)} measured ({state})"
        else:
            title = f"{orientation_label(a, b)} — prediction (not measured)"
        with self.client.atomic():
            self.head.update(a, b)
            self.ring.place(a, b)
            self.ring.update(
                view.curves,
                shown,
                float(self.controls.magnification.value),
                view.repetitions,
                bool(self.controls.repetitions.value),
                band,
                title,
            )
            self.field.highlight(a, b, ds.campaign.geometry.pivot_to_ball_mm)
            self.tables.update(view, ds)
            self.charts.update(view, shown)
            self.controls.status.content = f"**{title}**"
            if self.controls.follow.value and self._camera_at != (a, b) and self._camera_view != "whole field":
                self.look(self._camera_view)
        self.view = view
        self.render_count += 1
        elapsed = time.perf_counter() - start
        self.render_times.append(elapsed)
        self.app.render_times.append(elapsed)

    # -- data ----------------------------------------------------------------------------------
    def set_dataset(self, dataset: Dataset) -> None:
        """Show another campaign (or the same with a new model) in this browser."""
        geometry_changed = dataset.campaign.geometry != self.dataset.campaign.geometry
        self.dataset = dataset
        if geometry_changed:
            with self.client.atomic():
                self.ring.frame.remove()
                self.head.root.remove()
                self.head = HeadScene(self.client.scene, dataset.campaign.geometry)
                self.ring = RingScene(self.client.scene, dataset.campaign.geometry)
        self.controls.set_models(dataset.model_names)
        self.field_panel.set_names(dataset.figure_names())
        self.data_panel.set_source(dataset)
        self.refresh_field()
        self.render_now(wait=True)

    def refresh_field(self) -> None:
        """Recolour the error field; slow figures (leave-one-out refits) are computed on the worker."""
        self._field_token += 1
        token, dataset, name = self._field_token, self.dataset, self.field_panel.figure.value
        if name not in dataset.figure_names():
            return
        if dataset.has_figure(name):
            self._apply_field(dataset, name)
            return
        self.field_panel.set_scale(0.0, 0.0, "", computing=True)

        def compute() -> None:
            dataset.figure(name)
            if token == self._field_token:
                self._apply_field(dataset, name)

        self.submit(compute)

    def _apply_field(self, dataset: Dataset, name: str) -> None:
        values, note = dataset.figure(name)
        held_out = ~np.asarray(dataset.train_mask, dtype=bool)
        with self.client.atomic():
            self.field.set_values(dataset.campaign.orientations, values, held_out)
            self.field.set_visible(bool(self.field_panel.show.value))
            self.field_panel.set_scale(*self.field.range, note)
            self.controls.set_worst(dataset.worst_orientations(name), name)
        a, b = self.orientation
        self.field.highlight(a, b, dataset.campaign.geometry.pivot_to_ball_mm)

    def submit(self, job: Callable[..., None], *args: Any) -> Future:
        """Run heavy work off the callback thread: after this session's earlier jobs, a few at once overall."""
        future = self._jobs.submit(self._guarded, job, *args)
        self.jobs.append(future)
        return future

    def _guarded(self, job: Callable[..., None], *args: Any) -> None:
        with self.app.heavy:
            try:
                job(*args)
            except Exception as error:  # the browser shows one line; the server log keeps the rest
                line = f"**Error** — {type(error).__name__}: {' '.join(str(error).split())}"
                self.data_panel.show_info(line)
                self.physics.done(line)
                self.physics.done(line, refit=True)
                raise

    def close(self) -> None:
        with self._render_state:
            self._closed = True
        self._jobs.shutdown(wait=False, cancel_futures=True)

    def wait(self, timeout: float = 60.0) -> None:
        """Wait for this session's worker jobs, then for its latest values to be drawn (tests)."""
        deadline = time.monotonic() + timeout
        while self.jobs:
            self.jobs.pop(0).result(timeout=max(0.1, deadline - time.monotonic()))
        if not self.wait_rendered(timeout=max(0.1, deadline - time.monotonic())):
            raise TimeoutError("the session's latest values were not drawn in time")

    def _load_upload(self, name: str, content: bytes) -> None:
        try:
            campaign = read_uploaded_campaign(name, content, self.app.geometry_overrides)
        except InputError as error:
            self.data_panel.show_error(error.line())
            return
        except ValueError as error:  # a campaign the core refuses (e.g. inconsistent shapes)
            self.data_panel.show_error(f"{name}: {' '.join(str(error).split())}")
            return
        self.data_panel.show_info(f"Loaded **{campaign.source}**.")
        self._new_data(dataset_for(campaign, f"uploaded {campaign.source}", None))

    def _load_scenario(self, name: str) -> None:
        self.data_panel.show_info(f"Simulating scenario **{name}**…")
        try:
            campaign = simulated_scenario(name)
        except InputError as error:
            self.data_panel.show_error(error.line())
            return
        self.data_panel.show_info(f"Scenario **{name}** simulated by the twin. {self.app.scenario_notes.get(name, '')}")
        self._new_data(dataset_for(campaign, f"scenario {name} (simulated by the twin)", None))

    def _new_data(self, dataset: Dataset) -> None:
        self.diagnosis = None
        self.steps = []
        self.physics.clear()
        self.set_dataset(dataset)

    # -- physics: each callback is one call of ph_explorer.diagnosis -----------------------------
    def _diagnose(self) -> None:
        """Where the trilinear baseline fails out of sample, and which effect is missing (none added)."""
        p, ds = self.physics, self.dataset
        names = list(effect_names())
        seen: list[str] = []

        def progress(effect_id: str) -> None:
            seen.append(str(effect_id))
            p.show_progress(f"scanning {effect_id} against the out-of-sample residual…", len(seen) / (len(names) + 1))

        p.show_progress("out-of-sample residuals of the baseline (leave one orientation out)…", 0.02)
        try:
            result = diagnosis.diagnose(ds.campaign, add=[], progress=progress)
        except InputError as error:
            p.done(f"**Cannot diagnose** — {error.line()}")
            return
        if ds.campaign is not self.dataset.campaign:
            return  # the data changed meanwhile: this diagnosis is about data no longer shown
        self.diagnosis = result
        units = effect_units()
        p.show_diagnosis(result, units)
        if p.evidence_of.visible:
            p.evidence_of.value = p.evidence_of.options[0]
            self._show_evidence(p.evidence_of.value)
        # The diagnosis' per-orientation out-of-sample error becomes a field figure.
        ds.add_figure(
            "diagnosis: out-of-sample MAE / its floor",
            result.out_of_sample_mae_um["mean"] / result.out_of_sample_floor_um["mean"],
            "x the floor of each ring; training rings by leave-one-out, check rings by the baseline (ph_explorer.diagnosis)",
        )
        self.field_panel.set_names(ds.figure_names())
        self.steps = [result.steps[0]]
        p.show_history(self.steps, result.baseline_model)
        p.done(f"Diagnosed: {len(result.candidates)} candidate effects scanned.")

    def _show_evidence(self, effect_id: str) -> None:
        if self.diagnosis is None:
            return
        for candidate in self.diagnosis.candidates:
            if candidate.effect == effect_id:
                self.physics.show_evidence(candidate, effect_units().get(effect_id, {}))

    def _refit(self) -> None:
        """The hybrid with the ticked effects, fitted and measured on the check rings by diagnosis.add_effects."""
        p, ds = self.physics, self.dataset
        ids = p.selected_effects()
        scanned = {c.effect: c for c in (self.diagnosis.candidates if self.diagnosis is not None else [])}
        effects = [CATALOG[i]() for i in ids]
        # The structural values the diagnosis found (e.g. 22 cycles per revolution), else the effect's own.
        structural = [dict(scanned[i].structural) if i in scanned else e.structural_values() for i, e in zip(ids, effects)]
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
            structural,
            progress=lambda stage, fraction: p.show_progress(f"{label}: {stage}", 0.05 + 0.9 * float(fraction), refit=True),
        )
        if ds.campaign is not self.dataset.campaign:
            return  # the data changed meanwhile
        self.steps.append(step)
        p.show_history(self.steps, "trilinear")
        units = effect_units()
        fitted = "; ".join(f"{e['effect']}: {parameters_text(e['params'], units.get(e['effect'], {}))}" for e in step.params)
        p.done(
            f"Hybrid ({label}): check-ring MAE **{step.mae_um['mean']:.3f} um** vs mean, "
            f"{step.mae_um['single']:.3f} um vs single. {fitted}",
            refit=True,
        )
        # No physical term ticked: the hybrid would be the baseline again; draw no separate curve.
        self.set_dataset(ds.with_model("hybrid", hybrid) if ids else ds.without_model("hybrid"))

    def _reveal(self) -> None:
        scenario = self.dataset.campaign.scenario or {}
        hidden = scenario.get("hidden")
        if not hidden:
            self.physics.revealed.content = "_This campaign records no hidden effect (it is not a teaching scenario)._"
            return
        lines = []
        for effect_id in hidden:
            cls = CATALOG.get(effect_id)
            name, teaching = (cls.name, cls.teaching) if cls is not None else (effect_id, "")
            lines.append(f"- **{name}** (`{effect_id}`): {teaching}")
        self.physics.revealed.content = "Hidden in this scenario:\n" + "\n".join(lines)


class ExplorerApp:
    """The viser server and its sessions (one per browser)."""

    def __init__(
        self,
        dataset: Dataset,
        host: str = "127.0.0.1",
        port: int = 8080,
        geometry_overrides: Mapping[str, float] | None = None,
        verbose: bool = False,
    ) -> None:
        self.dataset = dataset
        self.geometry_overrides = dict(geometry_overrides or {})
        self.sessions: dict[int, Session] = {}
        self.render_times: deque[float] = deque(maxlen=10_000)  # server seconds per render, all sessions
        self.latency_times: deque[float] = deque(maxlen=10_000)  # slider event -> end of its render, s
        self.heavy = threading.BoundedSemaphore(HEAVY_JOBS)
        # The render thread's queue: dirty sessions, oldest request first, each at most once.
        self._render_queue: deque[Session] = deque()
        self._queued: set[int] = set()  # id() of the sessions in the queue
        self._render_ready = threading.Condition()
        self._stopping = False
        self.startup_s = float("nan")  # set by build_server: from the call to a ready server
        described = scenario_descriptions()
        self.scenarios = list(described)
        self.scenario_notes = described
        self._sessions_lock = threading.Lock()
        # Warm the caches the first browser needs (the default view and field).
        dataset.view(*INITIAL_ORIENTATION)
        dataset.figure(dataset.figure_names()[0])
        self.server = viser.ViserServer(host=host, port=port, label="ph-explorer", verbose=verbose)
        self.server.gui.configure_theme(control_width="large", show_share_button=False, show_logo=False)
        self.server.scene.set_up_direction("+z")
        camera = self.server.initial_camera
        position, look_at = ring_camera(*INITIAL_ORIENTATION, dataset.campaign.geometry.axial_distance_mm)
        camera.position = tuple(position)
        camera.look_at = tuple(look_at)
        camera.near = 1.0
        camera.far = 5000.0
        self._renderer = threading.Thread(target=self._render_loop, name="ph-explorer-render", daemon=True)
        self._renderer.start()
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)

    def schedule_render(self, session: Session) -> None:
        """Queue a dirty session for the render thread (at the back, unless it is queued already)."""
        with self._render_ready:
            if id(session) not in self._queued:
                self._queued.add(id(session))
                self._render_queue.append(session)
                self._render_ready.notify()

    def _render_loop(self) -> None:
        """The one render thread: sessions in turn, each with its latest values."""
        while True:
            with self._render_ready:
                while not self._render_queue and not self._stopping:
                    self._render_ready.wait()
                if self._stopping:
                    return
                session = self._render_queue.popleft()
                self._queued.discard(id(session))
            try:
                session.render_queued()
            except Exception:  # one browser's failed render must not stop the others'
                traceback.print_exc()

    @property
    def host(self) -> str:
        return self.server.get_host()

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def _connect(self, client: Any) -> None:
        session = Session(self, client, self.dataset)
        with self._sessions_lock:
            self.sessions[client.client_id] = session

    def _disconnect(self, client: Any) -> None:
        with self._sessions_lock:
            session = self.sessions.pop(client.client_id, None)
        if session is not None:
            session.close()

    def session(self, client_id: int | None = None, timeout: float = 10.0) -> Session:
        """A connected browser's session (the first one by default), waiting for it to connect."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._sessions_lock:
                if client_id is None and self.sessions:
                    return self.sessions[min(self.sessions)]
                if client_id in self.sessions:
                    return self.sessions[client_id]
            time.sleep(0.02)
        raise TimeoutError("no browser session connected")

    def stop(self) -> None:
        """Stop the server, the render thread and every session's jobs."""
        with self._render_ready:
            self._stopping = True
            self._render_ready.notify_all()
        self._renderer.join(timeout=10)
        self.server.stop()
        with self._sessions_lock:
            sessions = list(self.sessions.values())
        for session in sessions:
            session.close()


def build_server(
    scenario: str | None = None,
    data: Path | None = None,
    model: Path | None = None,
    host: str = "127.0.0.1",
    port: int = 8080,
    geometry: Mapping[str, float] | None = None,
    verbose: bool = False,
) -> ExplorerApp:
    """Load the data and models, then start the server (port 0 picks a free port).

    With no data options: the shipped paper campaign with model/paper (measured mean, network,
    trilinear). The returned app's `startup_s` is the time this call took.
    """
    start = time.perf_counter()
    dataset = default_dataset(scenario=scenario, data=data, model=model, geometry=geometry)
    app = ExplorerApp(dataset, host=host, port=port, geometry_overrides=geometry, verbose=verbose)
    app.startup_s = time.perf_counter() - start
    return app


def seconds_since_process_start() -> float | None:
    """Wall-clock seconds since this process started (imports included), where /proc says; else None."""
    try:
        fields = Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()
        start_ticks = int(fields[19])  # field 22 of stat: start time in clock ticks after boot
        uptime = float(Path("/proc/uptime").read_text().split()[0])
        return max(0.0, uptime - start_ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError):
        return None


def serve_command(
    scenario: str | None = None,
    data: Path | None = None,
    model: Path | None = None,
    host: str = "127.0.0.1",
    port: int = 8080,
    geometry: Mapping[str, float] | None = None,
) -> int:
    """The `serve` subcommand: start the explorer, print its URL, serve until interrupted."""
    if scenario is not None and data is not None:
        raise InputError("give --scenario or --data, not both")
    app = build_server(scenario=scenario, data=data, model=model, host=host, port=port, geometry=geometry)
    shown_host = "127.0.0.1" if app.host in ("0.0.0.0", "") else app.host
    print(f"ph-explorer: {app.dataset.label}; models: {', '.join(app.dataset.model_names) or 'none'}")
    for note in app.dataset.notes:
        print(f"  - {note}")
    since_start = seconds_since_process_start()
    ready = f"ready {since_start:.1f} s after the command started" if since_start is not None else f"ready in {app.startup_s:.1f} s"
    print(f"ph-explorer: serving at http://{shown_host}:{app.port}  ({ready}; Ctrl-C stops)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("ph-explorer: stopped")
    finally:
        app.stop()
    return 0
