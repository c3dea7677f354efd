"""`ph-explorer serve`: the viser server, one Session per browser, heavy work on a worker thread.

Each browser (viser client) gets its own Session: its own sliders, scene objects and panels,
and its own data once it uploads a file or picks a scenario. A slider move renders in the
callback's thread; moves that arrive while a render is running are coalesced so the latest value
wins. Refits, scenario simulations, uploads and slow figures run on one worker thread and never
hold a lock that a slider update needs.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np
import viser

from ph_explorer.app.dataset import (
    Dataset,
    dataset_for,
    default_dataset,
    list_scenarios,
    optional,
    read_uploaded_campaign,
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
    parse_orientation_label,
)
from ph_explorer.app.scene import ErrorField, HeadScene, RingScene
from ph_explorer.errors import InputError
from ph_explorer.geometry import stylus_direction

INITIAL_ORIENTATION = PAPER_PRESETS["A15 B-20"]
# Initial camera: the ring of the first orientation in front, the head above it, mm.
HEAD_VIEW = {"position": (40.0, -75.0, -150.0), "look_at": (4.0, 10.0, -60.0)}


def _effect_names() -> dict[str, str]:
    """id -> name of the effects in the catalog, when it is in this build."""
    effects = optional("ph_explorer.effects")
    catalog = getattr(effects, "CATALOG", None) if effects is not None else None
    if not catalog:
        return {}
    diagnosis = optional("ph_explorer.diagnosis")
    skip = getattr(diagnosis, "NOT_CANDIDATES", set()) if diagnosis is not None else set()
    return {effect_id: getattr(cls, "name", effect_id) for effect_id, cls in catalog.items() if effect_id not in skip}


class Session:
    """One browser: its sliders, its view, its data, its hybrid model and history."""

    def __init__(self, app: "ExplorerApp", client: Any, dataset: Dataset) -> None:
        self.app = app
        self.client = client
        self.dataset = dataset
        self.history: list[tuple[str, float]] = []
        self.diagnosis: Any = None
        self.jobs: list[Future] = []
        self.render_count = 0
        self._render_lock = threading.Lock()
        self._dirty = False
        self._rendering = False
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
            self.tables = TablesPanel(gui)
            self.charts = ChartsPanel(gui, dataset.view(a0, b0), self.controls.shown())
            self.field_panel = FieldPanel(gui, dataset.figure_names())
            diagnosis = optional("ph_explorer.diagnosis")
            self.diagnosis_available = diagnosis is not None and hasattr(diagnosis, "diagnose") and hasattr(diagnosis, "HybridModel")
            self.physics = PhysicsPanel(gui, self.diagnosis_available, _effect_names())
            self.data_panel = DataPanel(gui, list_scenarios())
        self._wire()
        self.set_dataset(dataset)

    # -- wiring: GUI events -> calls of the core, nothing else ------------------------------------
    def _wire(self) -> None:
        c = self.controls
        for handle in (c.a, c.b, c.magnification, c.repetitions, c.band, *c.show.values()):
            handle.on_update(lambda _event: self.request_render())

        @c.presets.on_click
        def _(event: Any) -> None:
            self.go_to(*PAPER_PRESETS[event.target.value])

        @c.worst.on_update
        def _(event: Any) -> None:
            target = parse_orientation_label(c.worst.value)
            if target is not None:
                self.go_to(*target)

        @c.view_head.on_click
        def _(event: Any) -> None:
            self.client.camera.position = HEAD_VIEW["position"]
            self.client.camera.look_at = HEAD_VIEW["look_at"]

        @c.view_ring.on_click
        def _(event: Any) -> None:
            a, b = float(c.a.value), float(c.b.value)
            s = stylus_direction(a, b)
            centre = self.dataset.campaign.geometry.axial_distance_mm * s
            side = np.cross(s, [0.0, 0.0, 1.0]) if abs(s[2]) < 0.99 else np.array([0.0, 1.0, 0.0])
            self.client.camera.look_at = centre
            self.client.camera.position = centre + 75.0 * s + 6.0 * side

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

    # -- orientation ---------------------------------------------------------------------------
    @property
    def orientation(self) -> tuple[float, float]:
        return float(self.controls.a.value), float(self.controls.b.value)

    def go_to(self, a_deg: float, b_deg: float) -> None:
        """Move both sliders (a preset, a marker click), then render once."""
        self._moving = True
        try:
            self.controls.a.value = float(np.clip(a_deg, 0.0, 115.0))
            self.controls.b.value = float(((b_deg + 180.0) % 360.0) - 180.0 if b_deg != 180.0 else 180.0)
        finally:
            self._moving = False
        self.request_render()

    def request_render(self) -> None:
        """Render now, or, when a render is running, make it run once more with the latest values."""
        if self._moving:
            return
        with self._render_lock:
            self._dirty = True
            if self._rendering:
                return
            self._rendering = True
        try:
            while True:
                with self._render_lock:
                    if not self._dirty:
                        self._rendering = False
                        return
                    self._dirty = False
                self._render()
        except BaseException:
            with self._render_lock:
                self._rendering = False
            raise

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
        self.view = view
        self.render_count += 1
        self.app.render_times.append(time.perf_counter() - start)

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
        self.request_render()

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
        future = self.app.worker.submit(self._guarded, job, *args)
        self.jobs.append(future)
        return future

    def _guarded(self, job: Callable[..., None], *args: Any) -> None:
        try:
            job(*args)
        except Exception as error:  # the browser shows one line; the server log keeps the rest
            self.data_panel.show_info(f"**Error** — {type(error).__name__}: {error}")
            raise

    def wait(self, timeout: float = 60.0) -> None:
        """Wait for this session's worker jobs (tests)."""
        deadline = time.monotonic() + timeout
        while self.jobs:
            self.jobs.pop(0).result(timeout=max(0.1, deadline - time.monotonic()))

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
        self.history = []
        self.physics.show_history([], None)
        self.set_dataset(dataset_for(campaign, f"uploaded {campaign.source}", None))

    def _load_scenario(self, name: str) -> None:
        self.data_panel.show_info(f"Simulating scenario **{name}**…")
        try:
            campaign = simulated_scenario(name)
        except InputError as error:
            self.data_panel.show_error(error.line())
            return
        self.data_panel.show_info(f"Scenario **{name}** simulated by the twin.")
        self.history = []
        self.physics.show_history([], None)
        self.set_dataset(dataset_for(campaign, f"scenario {name} (simulated by the twin)", None))

    # -- physics (ph_explorer.diagnosis) -----------------------------------------------------------
    def _progress(self, text: str, fraction: float | None = None) -> None:
        p = self.physics
        p.progress.visible = True
        p.progress.animated = fraction is None
        if fraction is not None:
            p.progress.value = float(np.clip(100.0 * fraction, 0.0, 100.0))
        p.status.content = f"_{text}_"

    def _diagnose(self) -> None:
        """Where the trilinear baseline fails out of sample, and which effect is missing (no effect added)."""
        diagnosis = optional("ph_explorer.diagnosis")
        if diagnosis is None:
            return
        p, ds = self.physics, self.dataset
        self._progress("diagnosing: out-of-sample residuals, then every catalog effect against them…")
        try:
            result = diagnosis.diagnose(ds.campaign, add=[], progress=lambda text: self._progress(str(text)))
        except InputError as error:
            p.progress.visible = False
            p.status.content = f"**Cannot diagnose** — {error.line()}"
            return
        self.diagnosis = result
        p.progress.visible = False
        floor, base = result.noise_floor_um, result.baseline_mae_um
        lines = [
            f"Check rings: {result.baseline_model} MAE **{base['mean']:.3f} um** vs mean "
            f"(floor {floor['mean']:.3f}), **{base['single']:.3f} um** vs single (floor {floor['single']:.3f}).",
            "",
            "| effect | explains | noise explains | parameters |",
            "|---|---|---|---|",
        ]
        for cand in result.candidates:
            params = ", ".join(f"{k} = {v:.3g}" for k, v in dict(cand.params).items())
            mark = " **(significant)**" if cand.significant else ""
            lines.append(
                f"| {cand.name or cand.effect}{mark} | {100.0 * cand.explained_fraction:.1f} % | "
                f"{100.0 * cand.noise_fraction:.1f} % | {params} |"
            )
        verdict = "an effect is missing" if result.verdict == "missing" else "no effect is missing"
        lines += ["", f"**Verdict:** {verdict}."]
        best = result.candidates[0] if result.candidates else None
        if best is not None and best.significant:
            lines += ["", f"**{best.name or best.effect}** — _{best.teaching}_", "", "Tick it below and refit."]
        p.result.content = "\n".join(lines)
        for cand in result.candidates:
            box = p.effects.get(cand.effect)
            if box is not None:
                box.label = f"{box.label.split(' — ')[0]} — {100.0 * cand.explained_fraction:.1f} %"
        # The diagnosis' per-orientation out-of-sample error becomes a field figure.
        ds.add_figure(
            "diagnosis: out-of-sample MAE / its floor",
            result.out_of_sample_mae_um["mean"] / result.out_of_sample_floor_um["mean"],
            "x the floor of each ring; training rings by leave-one-out, check rings by the baseline (ph_explorer.diagnosis)",
        )
        self.field_panel.set_names(ds.figure_names())
        self.history = [(result.baseline_model, float(base["mean"]))]
        p.show_history(self.history, float(floor["mean"]))
        p.status.content = "Diagnosed."

    def _refit(self) -> None:
        """The hybrid with the ticked effects, refitted on the training rings and measured on the check rings."""
        diagnosis = optional("ph_explorer.diagnosis")
        effects_module = optional("ph_explorer.effects")
        if diagnosis is None or effects_module is None:
            return
        p, ds = self.physics, self.dataset
        campaign = ds.campaign
        held_out = campaign.holdout_mask()
        train = ~held_out
        if not held_out.any():
            p.status.content = "**Cannot refit** — no held-out ring to measure the error on."
            return
        ids = p.selected_effects()
        scanned = {c.effect: c for c in (self.diagnosis.candidates if self.diagnosis is not None else [])}
        effects = [effects_module.CATALOG[i]() for i in ids]
        structural = [dict(scanned[i].structural) if i in scanned and scanned[i].structural else e.structural_values() for i, e in zip(ids, effects)]
        if not self.history:
            self._progress("fitting the trilinear baseline…", 0.05)
            baseline = diagnosis.HybridModel([], "trilinear").fit(campaign, train)
            self.history = [("trilinear", diagnosis.check_mae(baseline, campaign, held_out)["mean"])]
        self._progress(f"refitting the hybrid with {', '.join(ids) or 'no effect'}…", 0.1)
        hybrid = diagnosis.HybridModel(
            effects, "trilinear", structural, progress=lambda text, fraction: self._progress(str(text), 0.1 + 0.8 * float(fraction))
        ).fit(campaign, train)
        mae = diagnosis.check_mae(hybrid, campaign, held_out)
        p.progress.value, p.progress.visible = 100.0, False
        self.history.append(("+" + "+".join(ids) if ids else "no effect", float(mae["mean"])))
        p.show_history(self.history, ds.noise_floor_um.get("mean"))
        fitted = "; ".join(
            f"{e['effect']}: " + ", ".join(f"{k} = {v:.3g}" for k, v in e["params"].items()) for e in hybrid.effect_parameters()
        )
        p.status.content = (
            f"Hybrid ({', '.join(ids) or 'no effect'}): check-ring MAE **{mae['mean']:.3f} um** vs mean, "
            f"{mae['single']:.3f} um vs single. {fitted}"
        )
        self.set_dataset(ds.with_model("hybrid", hybrid))

    def _reveal(self) -> None:
        hidden = self.dataset.campaign.scenario.get("hidden") if self.dataset.campaign.scenario else None
        if not hidden:
            self.physics.revealed.content = "_This campaign records no hidden effect (it is not a teaching scenario)._"
            return
        names = _effect_names()
        effects = optional("ph_explorer.effects")
        catalog = getattr(effects, "CATALOG", {}) if effects is not None else {}
        lines = []
        for effect_id in hidden:
            teaching = getattr(catalog.get(effect_id), "teaching", "")
            lines.append(f"- **{names.get(effect_id, effect_id)}** ({effect_id}): {teaching}")
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
        self.render_times: deque[float] = deque(maxlen=10_000)
        self.worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix="ph-explorer-worker")
        self._sessions_lock = threading.Lock()
        # Warm the caches the first browser needs (the default view and field).
        dataset.view(*INITIAL_ORIENTATION)
        dataset.figure(dataset.figure_names()[0])
        self.server = viser.ViserServer(host=host, port=port, label="ph-explorer", verbose=verbose)
        self.server.gui.configure_theme(control_width="large", show_share_button=False, show_logo=False)
        self.server.scene.set_up_direction("+z")
        camera = self.server.initial_camera
        camera.position = HEAD_VIEW["position"]
        camera.look_at = HEAD_VIEW["look_at"]
        camera.near = 1.0
        camera.far = 5000.0
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)

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
            self.sessions.pop(client.client_id, None)

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
        self.server.stop()
        self.worker.shutdown(wait=False, cancel_futures=True)


def build_server(
    scenario: str | None = None,
    data: Path | None = None,
    model: Path | None = None,
    host: str = "127.0.0.1",
    port: int = 8080,
    geometry: Mapping[str, float] | None = None,
    verbose: bool = False,
) -> ExplorerApp:
    """Load the data and models, then start the server (port 0 picks a free port)."""
    dataset = default_dataset(scenario=scenario, data=data, model=model, geometry=geometry)
    return ExplorerApp(dataset, host=host, port=port, geometry_overrides=geometry, verbose=verbose)


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
    start = time.perf_counter()
    app = build_server(scenario=scenario, data=data, model=model, host=host, port=port, geometry=geometry)
    shown_host = "127.0.0.1" if app.host in ("0.0.0.0", "") else app.host
    print(f"ph-explorer: {app.dataset.label}; models: {', '.join(app.dataset.model_names) or 'none'}")
    for note in app.dataset.notes:
        print(f"  - {note}")
    print(f"ph-explorer: serving at http://{shown_host}:{app.port}  (ready in {time.perf_counter() - start:.1f} s; Ctrl-C stops)", flush=True)
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        print("ph-explorer: stopped")
    finally:
        app.stop()
    return 0
