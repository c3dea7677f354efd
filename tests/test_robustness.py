"""Robustness (issue 7): whatever file a user brings, the command line answers with one line and
the explorer keeps serving every browser.

tests/test_io_properties.py proves the reader's contract (any bytes end in a Campaign or an
InputError); here the same generated files go through the command line a user runs
(`ph-explorer inspect FILE`), and bad uploads go through viser's websocket protocol into a
running server with several browsers connected.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings, strategies as st
from test_io_properties import VALID, csvish, mutated  # the reader's own generators, reused
from typer.testing import CliRunner
from viser.transforms import SO3

from ph_explorer.cli import app as cli_app

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


def _off_any_lattice() -> bytes:
    """A valid campaign whose rings lie on no lattice: two share an A0, two a B0, none at their node."""
    rings = [(30.0, 10.0), (30.0, 50.0), (60.0, 90.0), (45.0, 90.0), (75.0, -120.0), (15.0, 160.0)]
    rng = np.random.default_rng(3)
    rows = [f"{a:g},{b:g},{rep},{k},{rng.normal(0.0, 0.2):.5f}" for a, b in rings for rep in range(2) for k in range(8)]
    return ("A_deg,B_deg,rep,point,dev_um\n" + "\n".join(rows) + "\n").encode()


OFF_ANY_LATTICE = _off_any_lattice()


@pytest.mark.parametrize("sidecar", [False, True], ids=["off-grid rings held out", "a sidecar's check ring"])
@pytest.mark.parametrize("command", [["diagnose", "--save", "study.json"], ["report", "--out", "report.html"], ["design", "--decide"]])
def test_rings_on_no_lattice_are_one_line_naming_the_file_and_nothing_is_written(tmp_path: Path, command: list[str], sidecar: bool) -> None:
    """The trilinear model, every command's baseline, predicts a ring from the lattice rings around
    it: rings on none are said in one line (before, with a sidecar's check ring: a ValueError
    traceback from the suspect-ring smoother)."""
    path = tmp_path / "scattered.csv"
    path.write_bytes(OFF_ANY_LATTICE)
    if sidecar:
        (tmp_path / "scattered.toml").write_text("[scenario]\ncheck_orientations = [[15.0, 160.0]]\n")
    files = sorted(p.name for p in tmp_path.iterdir())
    assert RUNNER.invoke(cli_app, ["inspect", str(path)]).exit_code == 0  # a valid file
    args = [command[0], "--data", str(path), *[str(tmp_path / a) if "." in a else a for a in command[1:]]]
    result = RUNNER.invoke(cli_app, args)
    assert result.exit_code == 2, f"exit {result.exit_code}: {result.exception!r}"
    message = result.stderr.rstrip("\n")
    assert "\n" not in message and str(path) in message and "lattice" in message, message
    assert sorted(p.name for p in tmp_path.iterdir()) == files


# -- the server: a bad upload in one browser, every browser keeps being served ---------------------
viser = pytest.importorskip("viser")
from fake_browser import open_session, wait_for  # noqa: E402


@pytest.fixture(scope="module")
def explorer():
    from synthetic import lobing_campaign

    from ph_explorer.app.dataset import dataset_for
    from ph_explorer.app.server import ExplorerApp

    campaign = lobing_campaign(seed=5, extra_orientations=((43.0, 90.0),))
    app = ExplorerApp(dataset_for(campaign, "synthetic robustness campaign", None), host="127.0.0.1", port=0)
    yield app
    app.stop()


BAD_FILES = {
    "text.csv": b"A_deg,B_deg,rep,point,dev_um\n0,0,0,0,abc\n",
    "binary.csv": bytes(range(256)) * 4,
    "empty.csv": b"",
    "truncated.csv": VALID[: len(VALID) // 2],
    "scattered.csv": OFF_ANY_LATTICE,
}


@pytest.mark.parametrize("name", sorted(BAD_FILES))
def test_a_bad_upload_leaves_every_browser_served(explorer, name: str) -> None:
    from ph_explorer.geometry import head_rotation

    opened = [open_session(explorer) for _ in range(3)]
    browsers, sessions = [b for b, _ in opened], [s for _, s in opened]
    try:
        datasets = [s.dataset for s in sessions]
        uploader = sessions[0]
        browsers[0].upload("Upload a campaign CSV", name, BAD_FILES[name])
        assert wait_for(lambda: name in uploader.data_panel.message.content), uploader.data_panel.message.content
        uploader.wait()
        assert "keeps its current data" in uploader.data_panel.message.content
        assert [s.dataset for s in sessions] == datasets
        # Every browser, the uploader included, still moves its own head.
        for k, browser in enumerate(browsers):
            browser.move_slider("A (deg)", 20.0 + 10.0 * k)
        for k, s in enumerate(sessions):
            assert wait_for(lambda: s.orientation[0] == 20.0 + 10.0 * k and s.view.a_deg == 20.0 + 10.0 * k)
            r = _rotation(s.head.b_frame.wxyz) @ _rotation(s.head.a_frame.wxyz)
            np.testing.assert_allclose(r, head_rotation(*s.orientation), atol=1e-9)
    finally:
        for b in browsers:
            b.close()


def _rotation(wxyz: np.ndarray) -> np.ndarray:
    """The rotation matrix of a viser frame's (w, x, y, z) quaternion."""
    return SO3(np.asarray(wxyz, dtype=float)).as_matrix()
