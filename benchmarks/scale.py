"""The explorer under load: N simulated browsers (tests/fake_browser.py, in a separate process:
benchmarks/browsers.py) moving sliders at a fixed rate, against the server running in this
process (so its render times and memory are measured where they happen).

Two server-side figures per render: `server_update_ms`, the time of the render itself, and
`latency_ms`, from the oldest slider event the render drew (when viser applied it) to the end of
that render, so queueing behind other browsers' renders is counted. Slider moves that arrive
before their session's turn are coalesced: `renders` is at most `slider_updates_sent`. A render draws
what the eye follows (head, curves, polar plot, map marker); what follows (tables, charts, a following
camera) is drawn by a catch-up render of its own, at most every FOLLOW_INTERVAL_S, at the last
orientation drawn, after the renders the eye follows (up to LATER_MAX_WAIT_S behind them): its
render times and how long it lagged (`following_catch_up_ms`, `following_lag_ms`) are its own.
The browsers start once the app's dataset is prepared (`lattice`: each model's curves on a dense
lattice, so that a slider move predicts nothing); `server_cpu_ms_per_update` is the server
process' CPU per slider update, every thread included.
"""

from __future__ import annotations

import gc
import json
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.peak import resident_mib
from ph_explorer.app.render_queue import LATER_MAX_WAIT_S
from ph_explorer.app.server import ExplorerApp
from ph_explorer.app.session import FOLLOW_INTERVAL_S
from ph_explorer.models.lattice import TOLERANCE_UM

REPOSITORY = Path(__file__).resolve().parent.parent


def percentile_ms(values: list[float], q: float) -> float | None:
    return round(1000.0 * float(np.percentile(values, q)), 3) if values else None


def lattice_figures(app: ExplorerApp, timeout: float = 120.0) -> dict[str, Any]:
    """Wait until the app's dataset is prepared (its models' lattices: a slider move then predicts
    nothing); what was built, its size and tolerance (ph_explorer.models.lattice)."""
    dataset = app.dataset
    start = time.perf_counter()
    ready = dataset.prepared.wait(timeout)
    return {
        "ready": ready,
        "waited_s": round(time.perf_counter() - start, 2),
        "models": {name: round(lattice.nbytes / 2**20, 1) for name, lattice in dataset.lattices.items()},  # MiB each
        "step_deg": {name: lattice.step_deg for name, lattice in dataset.lattices.items()},
        "tolerance_um": TOLERANCE_UM,
        "on_demand": [name for name in dataset.model_names if name not in dataset.lattices],
    }


def drive(app: ExplorerApp, n_browsers: int, rate_hz: float, seconds: float) -> dict[str, Any]:
    """Run the browsers process against the app; return server-side and client-side figures."""
    lattice = lattice_figures(app)
    app.stats.render_times.clear()
    app.stats.latency_times.clear()
    before_sessions = set(app.sessions)
    gc.collect()
    rss_before = resident_mib()
    start, cpu_start = time.perf_counter(), time.process_time()
    missed: int | None = None
    connected = 0
    sessions: list[Any] = []
    stats = app.stats  # every render of every session, failed ones included
    renders_before, errors_before = stats.render_count + stats.error_count, stats.error_count
    following = app.shared.following_stats  # the renders that catch up what follows the sliders (Session.following)
    following.render_times.clear()
    following.latency_times.clear()
    following_before = following.render_count
    process = subprocess.Popen(
        [sys.executable, "-m", "benchmarks.browsers", str(app.port), str(n_browsers), str(rate_hz), str(seconds)],
        cwd=REPOSITORY,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    timer = threading.Timer(seconds + 300, process.kill)  # bounded, whatever happens
    timer.start()
    try:
        finals: list[Any] = []
        for line in process.stdout:
            if line.startswith("FINALS "):
                finals = [tuple(f) for f in json.loads(line[7:]) if f is not None]
                break
        # Every browser is still connected: let the sessions render their last update, then
        # check that each ended on its own browser's last orientation (latest value wins).
        sessions = [app.sessions[c] for c in set(app.sessions) - before_sessions if c in app.sessions]
        connected = len(sessions)
        for session in sessions:
            session_wait(session)
        time.sleep(0.3)
        for session in sessions:
            session_wait(session)
        seen = [session.orientation for session in sessions]
        missed = sum(1 for f in finals if f not in seen) if finals else None
        process.stdin.write("release\n")
        process.stdin.flush()
        out, err = process.communicate(timeout=120)
    finally:
        timer.cancel()
    cpu_s = time.process_time() - cpu_start  # the server's every thread: renders, viser's event loop, callbacks
    renders = stats.render_count + stats.error_count - renders_before
    render_errors = stats.error_count - errors_before
    wall = time.perf_counter() - start
    browsers: list[dict[str, Any]] = []
    client_errors: list[str] = []
    lines = [line for line in (out or "").splitlines() if line.startswith("{")]
    if process.returncode != 0 or not lines:
        client_errors.append(f"browsers process exit {process.returncode}: {(err or '').strip()[-500:]}")
    else:
        browsers = json.loads(lines[-1])["browsers"]
        client_errors = [e for b in browsers for e in b["errors"]]
    times = list(app.stats.render_times)
    latencies = list(app.stats.latency_times)
    per_session = [session.render_count for session in sessions] if connected else []
    time.sleep(0.5)
    gc.collect()
    rss_after = resident_mib()
    completed = sum(1 for b in browsers if b["final"] is not None)
    sent = int(sum(b["sent"] for b in browsers))
    return {
        "browsers": n_browsers,
        "rate_hz": rate_hz,
        "seconds": seconds,
        "wall_s": round(wall, 2),
        "sessions_connected": connected,
        "browsers_completed": completed,
        "slider_updates_sent": sent,
        "renders": renders,
        # Renders per slider update sent: below 1 when moves were coalesced (the latest value drawn).
        "renders_per_update": round(renders / sent, 3) if sent else None,
        "renders_per_session": {"min": min(per_session), "median": float(np.median(per_session)), "max": max(per_session)}
        if per_session
        else None,
        "renders_in_percentiles": len(times),  # app.stats.render_times keeps the last 10 000
        # Tables 1-3, the charts and a following camera: drawn by a catch-up render of their own at most
        # every FOLLOW_INTERVAL_S (counted here, not in `renders`), after the renders the eye follows.
        "follow_interval_s": FOLLOW_INTERVAL_S,
        "later_max_wait_s": LATER_MAX_WAIT_S,
        "following_catch_up_renders": following.render_count - following_before,
        "following_catch_up_ms": {
            "p50": percentile_ms(list(following.render_times), 50),
            "p95": percentile_ms(list(following.render_times), 95),
        },
        # From a render asking for what follows to the end of the catch-up render that drew it: how
        # far behind the sliders the tables, charts and a following camera were.
        "following_lag_ms": {
            "p50": percentile_ms(list(following.latency_times), 50),
            "p95": percentile_ms(list(following.latency_times), 95),
        },
        "frames_received": int(sum(b["received"] for b in browsers)),
        "server_update_ms": {"p50": percentile_ms(times, 50), "p95": percentile_ms(times, 95), "max": percentile_ms(times, 100)},
        "latency_ms": {"p50": percentile_ms(latencies, 50), "p95": percentile_ms(latencies, 95), "max": percentile_ms(latencies, 100)},
        # The server process' CPU per slider update sent, every thread (renders, viser's event loop, callbacks).
        "server_cpu_ms_per_update": round(1000.0 * cpu_s / sent, 3) if sent else None,
        "lattice": lattice,
        "client_errors": client_errors[:20],
        "render_errors": render_errors,
        "last_render_error": stats.last_error if render_errors else None,
        "sessions_not_on_their_last_orientation": missed,
        "sessions_left_open": len(set(app.sessions) - before_sessions),
        "errors": len(client_errors) + render_errors + (missed if missed is not None else n_browsers) + (n_browsers - completed),
        "rss_mb": {
            "before": round(rss_before, 1),
            "after": round(rss_after, 1),
            "growth": round(rss_after - rss_before, 1),
            "peak": round(resident_mib("VmHWM"), 1),
        },
    }


def session_wait(session: Any, timeout: float = 10.0) -> None:
    """Wait until a session's latest slider values are drawn (none pending on the render thread)."""
    session.wait_rendered(timeout)
