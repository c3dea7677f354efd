"""The command line as a user meets it: run in a subprocess."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ph_explorer.campaign import Campaign
from ph_explorer.io import write_campaign

SUBCOMMANDS = ("serve", "simulate", "train", "evaluate", "diagnose", "inspect")


def run(*args: str, module: str = "ph_explorer") -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, COLUMNS="120")
    return subprocess.run([sys.executable, "-m", module, *args], capture_output=True, text=True, env=env, timeout=120)


@pytest.mark.parametrize("module", ["ph_explorer", "ph_explorer.cli"])
def test_help_lists_the_six_subcommands(module: str) -> None:
    result = run("--help", module=module)
    assert result.returncode == 0, result.stderr
    for name in SUBCOMMANDS:
        assert name in result.stdout


def test_console_script_is_installed() -> None:
    script = Path(sys.executable).parent / "ph-explorer"
    if not script.exists():
        pytest.skip("no console script next to this interpreter")
    result = subprocess.run([str(script), "--help"], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0 and all(name in result.stdout for name in SUBCOMMANDS)


def _campaign(tmp_path: Path) -> Path:
    rng = np.random.default_rng(2)
    grid = [(a, b) for a in (0.0, 45.0, 90.0) for b in (-120.0, 0.0, 120.0)]
    orientations = np.array(grid + [(43.0, 90.0), (112.0, 0.0)])
    deviations = rng.normal(0.0, 0.25, (len(orientations), 6, 32))
    c = Campaign(orientations, deviations, check_orientations=[[43.0, 90.0]], scenario={"name": "test", "seed": 1})
    return write_campaign(c, tmp_path / "c.csv")


def test_inspect_json(tmp_path: Path) -> None:
    path = _campaign(tmp_path)
    result = run("inspect", str(path), "--json")
    assert result.returncode == 0, result.stderr
    s = json.loads(result.stdout)
    assert s["orientations"] == 11 and s["repetitions"] == 6 and s["points"] == 32 and s["touches"] == 11 * 6 * 32
    assert s["grid"] == {"A_deg": [0.0, 45.0, 90.0], "B_deg": [-120.0, 0.0, 120.0]}
    assert sorted(s["off_grid"]) == [[43.0, 90.0], [112.0, 0.0]]
    assert s["check_orientations"] == [[43.0, 90.0]]
    assert s["noise_sigma_um"] == pytest.approx(0.25, rel=0.05)  # 2,112 touches, 5 dof each
    assert s["has_times"] is False
    assert s["geometry"]["points_per_circle"] == 32 and s["geometry"]["pivot_to_ball_mm"] == 80.0
    # A0 = 112 tilts the stylus to 118.5 deg at some touches: beyond the PH20's 115 deg.
    assert s["unreachable_orientations"] == [[112.0, 0.0]]
    assert 0 < s["unreachable_touches"] < 6 * 32 and s["unreachable_touches"] % 6 == 0
    assert s["scenario"] == {"name": "test", "seed": 1}


def test_inspect_text_and_geometry_options(tmp_path: Path) -> None:
    path = _campaign(tmp_path)
    result = run("inspect", str(path), "--bore-diameter-mm", "30")
    assert result.returncode == 0, result.stderr
    assert "bore 30 mm" in result.stdout and "orientations" in result.stdout
    lines = result.stdout.splitlines()
    assert len(lines) > 10
    # Aligned: every value starts in the same column, after the longest label and two spaces.
    starts = {re.match(r"^\S.*?\S {2,}(?=\S)", line).end() for line in lines}
    assert len(starts) == 1
    bad = run("inspect", str(path), "--bore-diameter-mm", "1")
    assert bad.returncode == 2 and "Traceback" not in bad.stderr
    assert bad.stderr.strip().splitlines() == [bad.stderr.strip()] and "bore_diameter_mm = 1" in bad.stderr


def test_inspect_without_a_file_is_a_usage_error() -> None:
    result = run("inspect")
    assert result.returncode == 2 and "Traceback" not in result.stderr
