"""A browser without a browser: a websocket client speaking viser's protocol (tests and benchmarks).

The one fake browser of the project. It connects like the viser web client (viser registers a
client when it receives the client's first camera message, so one is sent), drains and counts
what the server sends, learns its GUI elements by label from the server's messages, and sends
what a user's browser sends: a slider move (`move_slider("A (deg)", 43.0)`) or a file upload; it
keeps the files the server sends it to download (`download("report.html")`).

    browser, session = open_session(app)   # connect; returns with the Session the server made
    browser.move_slider("A (deg)", 60.0)   # as the user's browser would
    browser.close()

viser's wire format is internal to viser (`viser._messages`): this module is the only place
outside viser that speaks it. Runs in the tests' process or in a benchmark's own process
(benchmarks/browsers.py imports it as `tests.fake_browser` from the repository root).
"""

from __future__ import annotations

import threading
import time
import uuid
from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any

import msgspec
import viser
import zstandard
from viser import _messages
from websockets.exceptions import ConnectionClosedOK
from websockets.sync.client import connect

if TYPE_CHECKING:
    from ph_explorer.app.server import ExplorerApp
    from ph_explorer.app.session import Session

CONNECT_TIMEOUT_S = 30.0


def encode(message: _messages.Message) -> bytes:
    return msgspec.msgpack.encode(message.as_serializable_dict())


def decode_frame(raw: bytes) -> list[dict[str, Any]]:
    """The messages of one server frame: [8 B inner size][8 B compressed size][zstd msgpack]."""
    inner = int.from_bytes(raw[0:8], "little")
    size = int.from_bytes(raw[8:16], "little")
    payload = zstandard.ZstdDecompressor().decompress(raw[16 : 16 + size], max_output_size=inner)
    return list(msgspec.msgpack.decode(payload).get("messages", ()))


def camera_message(
    width: int = 800, height: int = 600, position: tuple[float, float, float] = (100.0, -100.0, 0.0)
) -> _messages.ViewerCameraMessage:
    """The camera a browser reports on connecting (viser registers the client on it), on an orbit
    (another position) and when its canvas changes shape (another width and height, px)."""
    return _messages.ViewerCameraMessage(
        wxyz=(1.0, 0.0, 0.0, 0.0),
        position=position,
        fov=1.0,
        near=1.0,
        far=5000.0,
        image_height=height,
        image_width=width,
        look_at=(0.0, 0.0, -60.0),
        up_direction=(0.0, 0.0, 1.0),
    )


class FakeBrowser:
    """A websocket client that announces a camera, drains what the server sends and sends GUI updates.

    `labels`: stop reading the server's messages once these GUI labels are known (a benchmark's
    browser saves its CPU for the run); by default every message is read, so every label and
    property update (e.g. a slider's new range) is known.
    """

    def __init__(self, port: int, host: str = "127.0.0.1", labels: Iterable[str] | None = None) -> None:
        self.received = 0  # frames received
        self.errors: list[str] = []  # how the connection failed, if it did before close()
        self.widgets: dict[str, dict[str, Any]] = {}  # label -> {"uuid", "type", "props", "value"}
        self.last: dict[str, dict[str, Any]] = {}  # message type -> the last message of that type received
        self._by_uuid: dict[str, dict[str, Any]] = {}
        self._wanted = None if labels is None else set(labels)
        self._downloads: dict[str, dict[str, Any]] = {}  # transfer id -> {"filename", "part_count", "parts"}
        self._known = threading.Condition()
        self.closed = False
        self._closing = False
        self.ws = connect(
            f"ws://{host}:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None, open_timeout=CONNECT_TIMEOUT_S
        )
        self.send(camera_message())
        threading.Thread(target=self._drain, name="fake-browser", daemon=True).start()

    # -- what the browser sends ----------------------------------------------------------------------
    def send(self, message: _messages.Message) -> None:
        self.ws.send(encode(message))

    def uuid(self, label: str, timeout: float = CONNECT_TIMEOUT_S) -> str:
        """The id of this browser's GUI element with that label (waits for the server to send it)."""
        with self._known:
            if not self._known.wait_for(lambda: label in self.widgets or self.closed, timeout):
                raise TimeoutError(f"no GUI element {label!r} received")
            if label not in self.widgets:
                raise ConnectionError("the fake browser is closed")
            return self.widgets[label]["uuid"]

    def move_slider(self, label: str, value: float) -> None:
        """What the browser sends when the user moves a slider (the server's callbacks then run)."""
        self.send(_messages.GuiUpdateMessage(self.uuid(label), {"value": float(value)}))

    def click(self, label: str, choice: str | None = None) -> None:
        """What the browser sends when the user clicks a button, or the button `choice` of a button group."""
        self.send(_messages.GuiUpdateMessage(self.uuid(label), {"value": True if choice is None else choice}))

    def upload(self, label: str, name: str, content: bytes) -> None:
        """What an upload button sends: a transfer start, then the file in one part."""
        button, transfer = self.uuid(label), str(uuid.uuid4())
        self.send(_messages.FileTransferStartUpload(button, transfer, name, "text/csv", 1, len(content)))
        self.send(_messages.FileTransferPart(button, transfer, 0, content))

    def download(self, filename: str, timeout: float = CONNECT_TIMEOUT_S) -> bytes:
        """The bytes of the latest file of that name the server sent this browser to download
        (send_file_download), once whole: never an earlier one while the latest is still arriving."""

        def whole() -> bytes | None:
            latest = [t for t in self._downloads.values() if t["filename"] == filename][-1:]
            for transfer in latest:
                if len(transfer["parts"]) == transfer["part_count"]:
                    return b"".join(transfer["parts"][k] for k in range(transfer["part_count"]))
            return None

        with self._known:
            if not self._known.wait_for(lambda: whole() is not None or self.closed, timeout):
                raise TimeoutError(f"no download {filename!r} received")
            content = whole()
        if content is None:
            raise ConnectionError("the fake browser is closed")
        return content

    def downloaded(self) -> list[str]:
        """The names of the files the server has started sending this browser to download."""
        with self._known:
            return [transfer["filename"] for transfer in self._downloads.values()]

    def props(self, label: str) -> dict[str, Any]:
        """The properties this browser was last told for a GUI element (label, min, max, ...)."""
        self.uuid(label)
        with self._known:
            return dict(self.widgets[label]["props"])

    # -- what the browser receives ---------------------------------------------------------------------
    def _drain(self) -> None:
        try:
            while True:
                raw = self.ws.recv()
                self.received += 1
                if isinstance(raw, bytes) and (self._wanted is None or not self._wanted <= set(self.widgets)):
                    self._read(decode_frame(raw))
        except ConnectionClosedOK:
            pass
        except Exception as error:  # noqa: BLE001 - reported, not raised: the drain thread has no caller
            if not self._closing:
                self.errors.append(f"receive: {type(error).__name__}: {error}")
        finally:
            with self._known:
                self.closed = True
                self._known.notify_all()

    def _read(self, messages: list[dict[str, Any]]) -> None:
        with self._known:
            for m in messages:
                kind = m.get("type", "")
                self.last[kind] = m
                if kind == "FileTransferStartDownload":
                    self._downloads[m["transfer_uuid"]] = {"filename": m["filename"], "part_count": m["part_count"], "parts": {}}
                elif kind == "FileTransferPart" and m.get("transfer_uuid") in self._downloads:
                    self._downloads[m["transfer_uuid"]]["parts"][int(m["part_index"])] = bytes(m["content"])
                elif kind == "GuiUpdateMessage" and m.get("uuid") in self._by_uuid:
                    widget = self._by_uuid[m["uuid"]]
                    updates = m.get("updates") or {}
                    widget["value"] = updates.get("value", widget["value"])
                    widget["props"].update({k: v for k, v in updates.items() if k != "value"})
                elif kind.startswith("Gui") and isinstance(m.get("props"), dict) and "label" in m["props"]:
                    widget = {"uuid": m["uuid"], "type": kind, "props": dict(m["props"]), "value": m.get("value")}
                    self._by_uuid[m["uuid"]] = widget
                    self.widgets.setdefault(m["props"]["label"], widget)  # a label names the first element that has it
            self._known.notify_all()

    def close(self) -> None:
        self._closing = True
        self.ws.close()


def wait_for(condition: Callable[[], bool], timeout: float = 20.0) -> bool:
    """Poll until condition() holds (the server applies a browser's messages in its own threads)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.02)
    return bool(condition())


def open_session(app: ExplorerApp, timeout: float = 20.0) -> tuple[FakeBrowser, Session]:
    """Connect a fake browser; return it and its Session once the session has rendered."""
    before = set(app.sessions)
    browser = FakeBrowser(app.port)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        new = set(app.sessions) - before
        if new:
            session = app.sessions[min(new)]
            session.wait(timeout=max(0.1, deadline - time.monotonic()))
            return browser, session
        time.sleep(0.02)
    browser.close()
    raise TimeoutError("the fake browser got no session")
