"""Simulated browsers (tests/fake_browser.py) moving the explorer's sliders at a fixed rate.

Run as a separate process from the repository root (`python -m benchmarks.browsers PORT N RATE_HZ
SECONDS`) so that the clients' own work does not run under the server's interpreter lock. Each
browser connects, sends a camera message (viser registers a client on it), reads the server's
messages until it has seen its own A and B sliders; once every browser has (or has failed to), all
move their sliders at RATE_HZ (one slider update per tick, A and B in turn) for SECONDS and each
ends on a final orientation of its own. When every browser has sent its final orientation the
process prints `FINALS [[A, B], ...]` and waits (at most RELEASE_TIMEOUT_S) for a line on stdin, so
that the server can check its sessions while the browsers are still connected; then it closes them
and prints one JSON line:
{"browsers": [{"final": [A, B], "sent": n, "received": n, "errors": [...]}, ...]}.
Bounded: every wait has a timeout and the run stops by itself.
"""

from __future__ import annotations

import json
import math
import sys
import threading
import time
from typing import Any

from tests.fake_browser import CONNECT_TIMEOUT_S, FakeBrowser

RELEASE_TIMEOUT_S = 60.0
A_LABEL, B_LABEL = "A (deg)", "B (deg)"


def final_orientation(k: int) -> tuple[float, float]:
    """A distinct last orientation per browser, so the server's final state can be checked."""
    return float(10 + (k * 7) % 100), float(-170 + (k * 13) % 340)


def start_together(ready: threading.Barrier) -> None:
    """This browser is connected (or has failed to): wait for the others, at most CONNECT_TIMEOUT_S."""
    try:
        ready.wait(CONNECT_TIMEOUT_S)
    except threading.BrokenBarrierError:
        pass  # one of them is late: the others start without it


def browser(
    k: int,
    port: int,
    rate_hz: float,
    seconds: float,
    ready: threading.Barrier,
    out: dict[str, Any],
    done: threading.Event,
    release: threading.Event,
) -> None:
    """One browser's run, reported in `out`; every failure goes to out["errors"], never raised."""
    try:
        client = FakeBrowser(port, labels=(A_LABEL, B_LABEL))
    except Exception as error:  # noqa: BLE001
        out["errors"].append(f"connect: {type(error).__name__}: {error}")
        start_together(ready)
        done.set()
        return
    try:
        try:
            for label in (A_LABEL, B_LABEL):  # wait until the server has sent both sliders
                client.uuid(label, timeout=CONNECT_TIMEOUT_S)
        finally:
            start_together(ready)  # everyone starts together; each browser has its own phase
        period, t0, tick = 1.0 / rate_hz, time.monotonic(), 0
        while time.monotonic() - t0 < seconds:
            t = time.monotonic() - t0
            if tick % 2 == 0:
                client.move_slider(A_LABEL, round(45.0 + 40.0 * math.sin(0.7 * t + k), 1))
            else:
                client.move_slider(B_LABEL, round(170.0 * math.sin(0.4 * t + 2 * k), 1))
            out["sent"] += 1
            tick += 1
            time.sleep(max(0.0, t0 + tick * period - time.monotonic()))
        a, b = final_orientation(k)
        client.move_slider(A_LABEL, a)
        client.move_slider(B_LABEL, b)
        out["sent"] += 2
        out["final"] = [a, b]
        done.set()
        release.wait(RELEASE_TIMEOUT_S)
    except Exception as error:  # noqa: BLE001
        out["errors"].append(f"{type(error).__name__}: {error}")
    finally:
        done.set()
        client.close()
        out["received"] = client.received
        out["errors"] += client.errors


def run(port: int, n: int, rate_hz: float, seconds: float) -> dict[str, Any]:
    ready = threading.Barrier(n)  # every browser connected (or failed to): all start together
    results: list[dict[str, Any]] = [{"final": None, "sent": 0, "received": 0, "errors": []} for _ in range(n)]
    done = [threading.Event() for _ in range(n)]
    release = threading.Event()
    threads = [
        threading.Thread(target=browser, args=(k, port, rate_hz, seconds, ready, results[k], done[k], release), daemon=True)
        for k in range(n)
    ]
    for thread in threads:
        thread.start()
    deadline = time.monotonic() + seconds + 2 * CONNECT_TIMEOUT_S + 30
    for event in done:
        event.wait(max(0.0, deadline - time.monotonic()))
    print("FINALS " + json.dumps([r["final"] for r in results]), flush=True)
    # Until the server says it has checked its sessions (a line on stdin), or at most RELEASE_TIMEOUT_S.
    reader = threading.Thread(target=sys.stdin.readline, daemon=True)
    reader.start()
    reader.join(RELEASE_TIMEOUT_S)
    release.set()
    for thread in threads:
        thread.join(RELEASE_TIMEOUT_S + 30)
    return {"browsers": results}


def main(argv: list[str]) -> int:
    port, n, rate_hz, seconds = int(argv[0]), int(argv[1]), float(argv[2]), float(argv[3])
    print(json.dumps(run(port, n, rate_hz, seconds)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
