"""Simulated browsers: websocket clients on 127.0.0.1 speaking viser's protocol.

Run as a separate process (`python -m benchmarks.browsers PORT N RATE_HZ SECONDS`) so that the
clients' own work does not run under the server's interpreter lock. Each browser connects, sends
a camera message (viser registers a client on it), reads the server's messages until it has seen
its own A and B sliders, then moves them at RATE_HZ (one slider update per tick, A and B in turn)
for SECONDS and ends on a final orientation of its own. When every browser has sent its final
orientation the process prints `FINALS [[A, B], ...]` and waits (at most RELEASE_TIMEOUT_S) for a
line on stdin, so that the server can check its sessions while the browsers are still connected;
then it closes them and prints one JSON line:
{"browsers": [{"final": [A, B], "sent": n, "received": n, "errors": [...]}, ...]}.
Bounded: every wait has a timeout and the run stops by itself.
"""

from __future__ import annotations

import asyncio
import json
import math
import sys
import time
from typing import Any

import msgspec
import viser
import zstandard
from viser import _messages
from websockets.asyncio.client import connect

CONNECT_TIMEOUT_S = 30.0
RELEASE_TIMEOUT_S = 60.0
SLIDER_LABELS = {"A (deg)": "a", "B (deg)": "b"}


def encode(message: _messages.Message) -> bytes:
    return msgspec.msgpack.encode(message.as_serializable_dict())


def decode_window(raw: bytes) -> list[dict[str, Any]]:
    """The messages of one server frame: [8 B inner size][8 B compressed size][zstd msgpack]..."""
    inner = int.from_bytes(raw[0:8], "little")
    size = int.from_bytes(raw[8:16], "little")
    payload = zstandard.ZstdDecompressor().decompress(raw[16 : 16 + size], max_output_size=inner)
    return list(msgspec.msgpack.decode(payload).get("messages", ()))


def final_orientation(k: int) -> tuple[float, float]:
    """A distinct last orientation per browser, so the server's final state can be checked."""
    return float(10 + (k * 7) % 100), float(-170 + (k * 13) % 340)


async def browser(
    k: int, port: int, rate_hz: float, seconds: float, start_at: float, done: asyncio.Future, release: asyncio.Event
) -> dict[str, Any]:
    out: dict[str, Any] = {"final": None, "sent": 0, "received": 0, "errors": []}
    uuids: dict[str, str] = {}
    found = asyncio.Event()
    try:
        ws = await asyncio.wait_for(
            connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None),
            CONNECT_TIMEOUT_S,
        )
    except Exception as error:  # noqa: BLE001 - reported, not raised
        out["errors"].append(f"connect: {type(error).__name__}: {error}")
        done.set_result(None)
        return out

    async def reader() -> None:
        try:
            async for raw in ws:
                out["received"] += 1
                if found.is_set() or not isinstance(raw, bytes):
                    continue
                for m in decode_window(raw):
                    if m.get("type") == "GuiSliderMessage":
                        label = (m.get("props") or {}).get("label")
                        if label in SLIDER_LABELS:
                            uuids[SLIDER_LABELS[label]] = m["uuid"]
                if len(uuids) == 2:
                    found.set()
        except Exception as error:  # noqa: BLE001
            if not out.get("closing"):
                out["errors"].append(f"receive: {type(error).__name__}: {error}")

    read_task = asyncio.create_task(reader())
    try:
        camera = _messages.ViewerCameraMessage(
            wxyz=(1.0, 0.0, 0.0, 0.0), position=(100.0, -100.0, 0.0), fov=1.0, near=1.0, far=5000.0,
            image_height=600, image_width=800, look_at=(0.0, 0.0, -60.0), up_direction=(0.0, 0.0, 1.0),
        )
        await ws.send(encode(camera))
        await asyncio.wait_for(found.wait(), CONNECT_TIMEOUT_S)
        # Everyone starts together; each browser has its own phase.
        await asyncio.sleep(max(0.0, start_at - time.monotonic()))
        period, t0, tick = 1.0 / rate_hz, time.monotonic(), 0
        while time.monotonic() - t0 < seconds:
            t = time.monotonic() - t0
            if tick % 2 == 0:
                value = round(45.0 + 40.0 * math.sin(0.7 * t + k), 1)
                message = _messages.GuiUpdateMessage(uuids["a"], {"value": value})
            else:
                value = round(170.0 * math.sin(0.4 * t + 2 * k), 1)
                message = _messages.GuiUpdateMessage(uuids["b"], {"value": value})
            await ws.send(encode(message))
            out["sent"] += 1
            tick += 1
            await asyncio.sleep(max(0.0, t0 + tick * period - time.monotonic()))
        a, b = final_orientation(k)
        await ws.send(encode(_messages.GuiUpdateMessage(uuids["a"], {"value": a})))
        await ws.send(encode(_messages.GuiUpdateMessage(uuids["b"], {"value": b})))
        out["sent"] += 2
        out["final"] = [a, b]
        done.set_result(out["final"])
        await asyncio.wait_for(release.wait(), RELEASE_TIMEOUT_S)
    except Exception as error:  # noqa: BLE001
        out["errors"].append(f"{type(error).__name__}: {error}")
    finally:
        if not done.done():
            done.set_result(None)
        out["closing"] = True
        await ws.close()
        read_task.cancel()
        try:
            await read_task
        except (asyncio.CancelledError, Exception):
            pass
        out.pop("closing", None)
    return out


async def run(port: int, n: int, rate_hz: float, seconds: float) -> dict[str, Any]:
    start_at = time.monotonic() + 2.0 + 0.1 * n  # time for every browser to connect first
    loop = asyncio.get_running_loop()
    done = [loop.create_future() for _ in range(n)]
    release = asyncio.Event()
    tasks = [asyncio.create_task(browser(k, port, rate_hz, seconds, start_at, done[k], release)) for k in range(n)]
    finals = await asyncio.wait_for(asyncio.gather(*done), seconds + 2 * CONNECT_TIMEOUT_S + 30)
    print("FINALS " + json.dumps(finals), flush=True)
    try:
        await asyncio.wait_for(loop.run_in_executor(None, sys.stdin.readline), RELEASE_TIMEOUT_S)
    except asyncio.TimeoutError:
        pass
    release.set()
    results = await asyncio.wait_for(asyncio.gather(*tasks), RELEASE_TIMEOUT_S + 30)
    return {"browsers": results}


def main(argv: list[str]) -> int:
    port, n, rate_hz, seconds = int(argv[0]), int(argv[1]), float(argv[2]), float(argv[3])
    print(json.dumps(asyncio.run(run(port, n, rate_hz, seconds))), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
