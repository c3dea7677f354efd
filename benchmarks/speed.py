"""Speed figures: simulate, training, refit, diagnosis, prediction, Monte Carlo, serve start-up."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Callable
from typing import Any

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis import add_effects, diagnose
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.twin import load_scenario, simulate


def best_of(repeat: int, func: Callable[[], Any]) -> float:
    """The shortest of `repeat` wall-clock runs (s): the least disturbed by other processes."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        func()
        times.append(time.perf_counter() - start)
    return min(times)


def simulate_speed(repeat: int = 5) -> dict[str, Any]:
    scenario = load_scenario("paper")
    campaign = simulate(scenario, scenario.seed)
    seconds = best_of(repeat, lambda: simulate(scenario, scenario.seed))
    return {"touches": campaign.n_touches, "seconds": round(seconds, 4), "touches_per_s": round(campaign.n_touches / seconds)}


def refit_speed(campaign: Campaign) -> tuple[dict[str, Any], DeviationModel]:
    """The hybrid refit after ticking effects: add_effects on the paper campaign (fit + check MAE)."""
    effects = [DEFAULT_CATALOG["lobing"](), DEFAULT_CATALOG["b_axis_cyclic"](cycles_per_rev=2)]
    start = time.perf_counter()
    hybrid, step = add_effects(campaign, effects)
    seconds = time.perf_counter() - start
    figures = {
        "effects": ["lobing", "b_axis_cyclic (2/rev)"],
        "seconds": round(seconds, 3),
        "check_mae_um": {k: round(v, 5) for k, v in step.mae_um.items()},
    }
    return figures, hybrid


SERVE_ANSWER_TARGET_S = 1.5  # issue 16: `serve` answers its URL within 1.5 s (median)
DIAGNOSIS_TARGET_S = 30.0  # issue 13: a paper-size campaign diagnosed in under 30 s on 2 cores


def diagnosis_speed(repeat: int = 3) -> dict[str, Any]:
    """Seconds of one diagnose(campaign) alone on the machine (simulation excluded), median of
    `repeat`: the paper campaign (nothing found) and head_3 (an effect found, so the nested
    cross-validation of the choice runs too: the longest path of a paper-size diagnosis)."""
    out: dict[str, Any] = {"target_s": DIAGNOSIS_TARGET_S, "note": "one diagnosis at a time, nothing else running in the benchmark"}
    for name in ("paper", "head_3"):
        scenario = load_scenario(name)
        campaign = simulate(scenario, scenario.seed)
        times, verdicts = [], set()
        for _ in range(repeat):
            start = time.perf_counter()
            result = diagnose(campaign)
            times.append(time.perf_counter() - start)
            verdicts.add(result.verdict)
        out[name] = {
            "seconds_median": round(float(np.median(times)), 2),
            "seconds": [round(t, 2) for t in times],
            "verdict": "/".join(sorted(verdicts)),
            "nested": result.nested is not None,
            "touches": campaign.n_touches,
        }
    out["holds"] = all(out[name]["seconds_median"] < DIAGNOSIS_TARGET_S for name in ("paper", "head_3"))
    return out


def prediction_speed(models: dict[str, DeviationModel], repeat: int = 200) -> dict[str, float]:
    """Median time (us) of predicting one orientation's curve (64 points), per model."""
    out = {}
    for name, model in models.items():
        model.predict([[43.0, 90.0]])  # warm-up
        times = []
        for k in range(repeat):
            o = [[10.0 + (k * 7) % 90, -170.0 + (k * 13) % 340]]
            start = time.perf_counter()
            model.predict(o)
            times.append(time.perf_counter() - start)
        out[name] = round(1e6 * float(np.median(times)), 1)
    return out


def monte_carlo_speed(
    models: dict[str, DeviationModel], orientations: np.ndarray, n_repetitions: int = 10, repeat: int = 3
) -> dict[str, Any]:
    """Simulated touches per second of model.simulate over a campaign's orientations."""
    rng = np.random.default_rng(0)
    touches = len(orientations) * n_repetitions * 64
    out: dict[str, Any] = {"touches_per_call": touches}
    for name, model in models.items():
        seconds = best_of(repeat, lambda: model.simulate(orientations, n_repetitions, rng))
        out[name] = round(touches / seconds)
    return out


def serve_startup(launches: int = 5, timeout: float = 120.0) -> dict[str, Any]:
    """`python -m ph_explorer serve` in fresh processes: seconds until its URL answers, and until it is ready.

    Each launch gets a free port and the URL is polled from the launch on (every 20 ms, HTTP GET of
    the page), so "answers" is what a user's browser meets, interpreter and imports included.
    "Ready" is when the command prints "serving at": the campaign, the models and the first view
    loaded. Before the page-first start (the previous design) the URL answered only then, so the
    ready time is also that design's answer time. Medians over `launches`.
    """
    answers, ready, reported = [], [], []
    for _ in range(launches):
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        start = time.perf_counter()
        process = subprocess.Popen(
            [sys.executable, "-m", "ph_explorer", "serve", "--port", str(port)],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
            # The Ctrl-C below as in a terminal: a run in a shell's background has SIGINT ignored (inherited).
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
        )
        timer = threading.Timer(timeout, process.kill)
        timer.start()
        answered: list[float] = []

        def poll() -> None:
            while process.poll() is None and time.perf_counter() - start < timeout:
                try:
                    with urllib.request.urlopen(f"http://127.0.0.1:{port}/", timeout=1) as page:
                        if page.status == 200:
                            answered.append(time.perf_counter() - start)
                            return
                except OSError:
                    pass
                time.sleep(0.02)

        poller = threading.Thread(target=poll, daemon=True)
        poller.start()
        try:
            for line in process.stdout:
                # "(ready 3.4 s after the command started; ...)" or "(ready in 0.9 s; ...)"
                match = re.search(r"serving at (\S+)\s+\(ready (?:in )?([0-9.]+) s", line)
                if match:
                    ready.append(time.perf_counter() - start)
                    reported.append(float(match.group(2)))
                    break
            poller.join(timeout)
        finally:
            timer.cancel()
            if process.poll() is None:
                process.send_signal(signal.SIGINT)
                try:
                    process.wait(timeout=20)
                except subprocess.TimeoutExpired:
                    process.kill()
                    process.wait()
        answers.extend(answered[:1])
    answer = float(np.median(answers)) if len(answers) == launches else None
    return {
        "seconds_from_launch": None if answer is None else round(answer, 2),
        "seconds_from_launch_each": [round(x, 2) for x in answers],
        "seconds_to_ready": None if len(ready) < launches else round(float(np.median(ready)), 2),
        "seconds_to_ready_each": [round(x, 2) for x in ready],
        "seconds_reported": None if not reported else round(float(np.median(reported)), 2),
        "launches": launches,
        "target_s": SERVE_ANSWER_TARGET_S,
        "holds": answer is not None and answer <= SERVE_ANSWER_TARGET_S,
    }
