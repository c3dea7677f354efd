"""Robustness (issue 7): whatever file a user brings, the command line answers with one line and
the explorer keeps serving every browser.

tests/test_io_properties.py proves the reader's contract (any bytes end in a Campaign or an
InputError); here the same generated files go through the command line a user runs
(`ph-explorer inspect FILE`), and bad uploads go through viser's websocket protocol into a
running server with several browsers connected.
"""

from __future__ import annotations

import time
import uuid
from pathlib import Path

import msgspec
import numpy as np
from viser.transforms import SO3
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from ph_explorer.cli import app as cli_app
from test_io_properties import VALID, csvish, mutated  # the reader's own generators, reused

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
RUNNER = CliRunner()


def _inspect(tmp_path: Path, data: bytes) -> None:
    """`ph-explorer inspect` exits 0, or 2 with exactly one line on stderr; never a traceback."""
    path = tmp_path / "campaign.csv"
    path.write_bytes(data)
    result = RUNNER.invoke(cli_app, ["inspect", str(path)])
    assert result.exit_code in (0, 2), f"exit {result.exit_code}: {result.exception!r}"
    assert "Traceback" not in result.stdout + result.stderr
    if result.exit_code == 2:
        message = result.stderr.rstrip("\n")
        assert message and "\n" not in message, repr(result.stderr)
        assert str(path) in message
    else:
        assert result.stderr == "" and "orientations" in result.stdout.lower()


def test_the_valid_file_inspects(tmp_path: Path) -> None:
    result = RUNNER.invoke(cli_app, ["inspect", str(tmp_path / "missing.csv")])
    assert result.exit_code == 2 and result.stderr.count("\n") == 1
    _inspect(tmp_path, VALID)


@given(data=st.one_of(st.binary(max_size=300), csvish, mutated()))
@example(data=b"")
@example(data=b"\xff\xfe\x00A")
@example(data=VALID.replace(b"0.5\n", b"nan\n", 1))
@SETTINGS
def test_any_file_through_the_cli_ends_in_one_line(tmp_path: Path, data: bytes) -> None:
    _inspect(tmp_path, data)


# -- the server: a bad upload in one browser, every browser keeps being served ---------------------
viser = pytest.importorskip("viser")
from viser import _messages  # noqa: E402
from websockets.sync.client import connect  # noqa: E402


class Browser:
    """A minimal viser websocket client that drains what the server sends."""

    def __init__(self, port: int) -> None:
        import threading

        self.ws = connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None)
        self.send(
            _messages.ViewerCameraMessage(
                wxyz=(1.0, 0.0, 0.0, 0.0), position=(100.0, -100.0, 0.0), fov=1.0, near=1.0, far=5000.0,
                image_height=600, image_width=800, look_at=(0.0, 0.0, -60.0), up_direction=(0.0, 0.0, 1.0),
            )
        )
        threading.Thread(target=self._drain, daemon=True).start()

    def send(self, message: _messages.Message) -> None:
        self.ws.send(msgspec.msgpack.encode(message.as_serializable_dict()))

    def upload(self, button_uuid: str, name: str, content: bytes) -> None:
        """What the browser's upload button sends: a transfer start, then the file in one part."""
        transfer = str(uuid.uuid4())
        self.send(_messages.FileTransferStartUpload(button_uuid, transfer, name, "text/csv", 1, len(content)))
        self.send(_messages.FileTransferPart(button_uuid, transfer, 0, content))

    def _drain(self) -> None:
        try:
            while True:
                self.ws.recv()
        except Exception:
            pass

    def close(self) -> None:
        self.ws.close()


def _wait(condition, timeout: float = 20.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.02)
    return condition()


@pytest.fixture(scope="module")
def explorer():
    from ph_explorer.app.dataset import dataset_for
    from ph_explorer.app.server import ExplorerApp
    from ph_explorer.models.synthetic import lobing_campaign

    campaign = lobing_campaign(seed=5, extra_orientations=((43.0, 90.0),))
    app = ExplorerApp(dataset_for(campaign, "synthetic robustness campaign", None), host="127.0.0.1", port=0)
    yield app
    app.stop()


BAD_FILES = {
    "text.csv": b"A_deg,B_deg,rep,point,dev_um\n0,0,0,0,abc\n",
    "binary.csv": bytes(range(256)) * 4,
    "empty.csv": b"",
    "truncated.csv": VALID[: len(VALID) // 2],
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_a_bad_upload_leaves_every_browser_served(explorer, name: str) -> None:
    from ph_explorer.geometry import head_rotation

    before = set(explorer.sessions)
    browsers = [Browser(explorer.port) for _ in range(3)]
    try:
        assert _wait(lambda: len(set(explorer.sessions) - before) == 3), "a browser got no session"
        ids = sorted(set(explorer.sessions) - before)
        sessions = [explorer.sessions[i] for i in ids]
        for s in sessions:
            s.wait()
        # Client ids are given in connection order: browsers[k] owns sessions[k].
        datasets = [s.dataset for s in sessions]
        uploader = sessions[0]
        browsers[0].upload(uploader.data_panel.upload._impl.uuid, name, BAD_FILES[name])
        assert _wait(lambda: name in uploader.data_panel.message.content), uploader.data_panel.message.content
        uploader.wait()
        assert "keeps its current data" in uploader.data_panel.message.content
        assert [s.dataset for s in sessions] == datasets
        # Every browser, the uploader included, still moves its own head.
        for k, (browser, s) in enumerate(zip(browsers, sessions)):
            browser.send(_messages.GuiUpdateMessage(s.controls.a._impl.uuid, {"value": 20.0 + 10.0 * k}))
        for k, s in enumerate(sessions):
            assert _wait(lambda: s.orientation[0] == 20.0 + 10.0 * k and s.view.a_deg == 20.0 + 10.0 * k)
            r = _rotation(s.head.b_frame.wxyz) @ _rotation(s.head.a_frame.wxyz)
            np.testing.assert_allclose(r, head_rotation(*s.orientation), atol=1e-9)
    finally:
        for b in browsers:
            b.close()


def _rotation(wxyz: np.ndarray) -> np.ndarray:
    """The rotation matrix of a viser frame's (w, x, y, z) quaternion."""
    return SO3(np.asarray(wxyz, dtype=float)).as_matrix()
