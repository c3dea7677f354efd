"""A browser without a browser: a websocket client speaking viser's protocol.

For tests and benchmarks: `open_session(app)` connects one simulated browser to a running
ExplorerApp and returns it with the Session the server made for it; set that session's GUI values
(`session.controls.a.value = 43.0`, `session.go_to(43, 90)`) and read its scene handles and panels.
viser registers a client when it receives the client's first camera message, so one is sent.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

import msgspec
import viser
from viser import _messages
from websockets.sync.client import connect

if TYPE_CHECKING:
    from ph_explorer.app.server import ExplorerApp, Session


class SimulatedBrowser:
    """A websocket client that announces a camera and drains everything the server sends."""

    def __init__(self, port: int, host: str = "127.0.0.1") -> None:
        self.ws = connect(f"ws://{host}:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None)
        self.received = 0
        self.send(
            _messages.ViewerCameraMessage(
                wxyz=(1.0, 0.0, 0.0, 0.0),
                position=(100.0, -100.0, 0.0),
                fov=1.0,
                near=1.0,
                far=5000.0,
                image_height=600,
                image_width=800,
                look_at=(0.0, 0.0, -60.0),
                up_direction=(0.0, 0.0, 1.0),
            )
        )
        threading.Thread(target=self._drain, daemon=True).start()

    def send(self, message: _messages.Message) -> None:
        self.ws.send(msgspec.msgpack.encode(message.as_serializable_dict()))

    def move_slider(self, handle: object, value: float) -> None:
        """What the browser sends when the user moves a slider (the server's callbacks then run)."""
        self.send(_messages.GuiUpdateMessage(handle._impl.uuid, {"value": float(value)}))  # type: ignore[attr-defined]

    def _drain(self) -> None:
        try:
            while True:
                self.ws.recv()
                self.received += 1
        except Exception:  # closed by either side: nothing more to read
            pass

    def close(self) -> None:
        self.ws.close()


def open_session(app: "ExplorerApp", timeout: float = 20.0) -> tuple[SimulatedBrowser, "Session"]:
    """Connect a simulated browser; return it and its Session once the session has rendered."""
    before = set(app.sessions)
    browser = SimulatedBrowser(app.port)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        new = set(app.sessions) - before
        if new:
            session = app.sessions[min(new)]
            session.wait(timeout=max(0.1, deadline - time.monotonic()))
            return browser, session
        time.sleep(0.02)
    browser.close()
    raise TimeoutError("the simulated browser got no session")
