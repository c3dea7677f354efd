"""The explorer's viser server: one Session per browser, one render thread, a bound on heavy jobs.

Each browser gets its own Session (session.py); slider moves from every browser are drawn by ONE
render thread (render_queue.py); diagnoses, refits, simulations, uploads and slow figures run on
each session's worker thread, at most HEAVY_JOBS at once, never holding a lock a render needs.
`build_server(port=0)` starts one in-process for benchmarks and scripts (`ph-explorer serve` is
ph_explorer/cli/serve_command.py; tests/fake_browser.py connects simulated browsers).

Method: docs/methods/explorer_server.md.
"""

from __future__ import annotations

import gc
import threading
import time
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import viser

from ph_explorer import paths
from ph_explorer.app.dataset import Dataset, default_dataset, shipped_scenarios
from ph_explorer.app.loading import LoadingNotice, open_server
from ph_explorer.app.render_queue import RenderQueue, RenderStats
from ph_explorer.app.scene import CAMERA_FOV_DEG, ring_camera
from ph_explorer.app.session import INITIAL_ORIENTATION, Session, Shared
from ph_explorer.app.study_file import StudyFile, open_study
from ph_explorer.effects import DEFAULT_CATALOG, Catalog
from ph_explorer.errors import InputError

# Diagnoses and refits running at once over all browsers (the machine's cores; the rest queue).
HEAVY_JOBS = 2
# The garbage collector's thresholds while an app serves (build_server), and Python's defaults.
GC_THRESHOLDS = (10_000, 20, 20)
DEFAULT_GC_THRESHOLDS = (700, 10, 10)


class ExplorerApp:
    """The viser server and its sessions (one per browser)."""

    def __init__(
        self,
        dataset: Dataset,
        host: str = "127.0.0.1",
        port: int = 8080,
        geometry_overrides: Mapping[str, float] | None = None,
        verbose: bool = False,
        catalog: Catalog = DEFAULT_CATALOG,
        study: StudyFile | None = None,
        server: viser.ViserServer | None = None,
    ) -> None:
        """server: one already answering (open_server, as `serve` does before loading); else one is opened."""
        self.dataset = dataset
        self.study = study
        self.sessions: dict[int, Session] = {}
        self.startup_s = float("nan")  # set by build_server: from the call to a ready server
        self.stats = RenderStats()
        self.renders = RenderQueue()
        self.shared = Shared(
            renders=self.renders,
            heavy=threading.BoundedSemaphore(HEAVY_JOBS),
            catalog=catalog,
            scenarios=shipped_scenarios(),
            geometry_overrides=dict(geometry_overrides or {}),
            stats=self.stats,
            study=study,
        )
        self._sessions_lock = threading.Lock()
        # Warm the caches the first browser needs (the default view and field).
        dataset.view(*INITIAL_ORIENTATION)
        dataset.figure(dataset.figure_names()[0])
        dataset.prepare_in_background()  # the lattices: slider moves stop predicting a few seconds later
        self.server = server if server is not None else open_server(host=host, port=port, verbose=verbose)
        camera = self.server.initial_camera
        position, look_at = ring_camera(*INITIAL_ORIENTATION, dataset.campaign.geometry)
        camera.fov = float(np.radians(CAMERA_FOV_DEG))
        camera.position = tuple(position)
        camera.look_at = tuple(look_at)
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

    def _connect(self, client: viser.ClientHandle) -> None:
        session = Session(self.shared, client, self.dataset)
        with self._sessions_lock:
            self.sessions[client.client_id] = session

    def _disconnect(self, client: viser.ClientHandle) -> None:
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
        """Stop the render thread, the server and every session's jobs."""
        self.renders.stop()
        self.server.stop()
        with self._sessions_lock:
            sessions = list(self.sessions.values())
        for session in sessions:
            session.close()
        gc.unfreeze()  # build_server's frozen objects may be garbage now (tests start many apps)
        gc.set_threshold(*DEFAULT_GC_THRESHOLDS)


def build_server(
    scenario: str | None = None,
    data: Path | None = None,
    model: Path | None = None,
    host: str = "127.0.0.1",
    port: int = 8080,
    geometry: Mapping[str, float] | None = None,
    verbose: bool = False,
    study: Path | None = None,
    effects: Path | None = None,
    server: viser.ViserServer | None = None,
    notice: LoadingNotice | None = None,
) -> ExplorerApp:
    """Load the data and models, then start the server (port 0 picks a free port).

    With no data options: the shipped paper campaign with assets/models/paper (measured mean, network,
    trilinear). The returned app's `startup_s` is the time this call took.
    study: the operator's study file, of the served campaign's file (--data, or the shipped
    paper.csv); checked here, before the server starts (InputError), and the only file the app writes.
    effects: the operator's Python file of effects (`Catalog.with_file`), imported here, before the
    server starts; every browser diagnoses and refits with them. Browsers upload campaign CSVs only.
    server, notice: a server already answering and its browsers' loading note (`serve` opens both
    first, so that the URL answers while this loads); the explorer takes the waiting browsers over.
    """
    start = time.perf_counter()
    if study is not None and scenario is not None:
        # A scenario is simulated anew in memory: there are no campaign bytes to tie a study to.
        raise InputError(
            "a study belongs to a campaign file: simulate the scenario to a CSV (simulate --out) and serve it with --data", option="--study"
        )
    catalog = DEFAULT_CATALOG.with_file(effects) if effects is not None else DEFAULT_CATALOG
    dataset = default_dataset(scenario=scenario, data=data, model=model, geometry=geometry)
    opened = None
    if study is not None:
        data_file = Path(data) if data is not None else paths.assets_dir() / "data" / "paper.csv"
        opened = open_study(Path(study), data_file, dataset.campaign, catalog)
    if notice is not None:
        notice.say("the first view")
        # Ready before the explorer registers its sessions, which then take over the waiting browsers.
        dataset.view(*INITIAL_ORIENTATION)
        notice.finish()
    app = ExplorerApp(
        dataset, host=host, port=port, geometry_overrides=geometry, verbose=verbose, catalog=catalog, study=opened, server=server
    )
    # What is loaded now (torch, the models, the campaign: ~250 000 objects) lives as long as the
    # app: out of the garbage collector's sight, a full collection (all threads stopped) scans only
    # what the sessions made (60 ms, not 300 ms, with 30 browsers). A room's renders make short-lived
    # objects by the million: collected 14 times less often, most die young, uncounted (a fifth of the time).
    gc.freeze()
    gc.set_threshold(*GC_THRESHOLDS)
    app.startup_s = time.perf_counter() - start
    return app
