"""`ph-explorer uncertainty` (issue 17): the JSON of every band, and one-line errors with exit 2."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from synthetic import lobing_campaign
from typer.testing import CliRunner

from ph_explorer.cli import app
from ph_explorer.cli.train_command import train_command
from ph_explorer.io import write_campaign
from ph_explorer.models.network import NetworkConfig
from ph_explorer.uncertainty.model_error import FILE_NAME, load_errors

QUICK = NetworkConfig(max_epochs=8, early_stopping_patience=8)
N_POINTS = 16  # the bands' Monte Carlo costs in proportion to the points: the JSON and text need no more
BAND_KEYS = {
    "A_deg",
    "B_deg",
    "model",
    "touch_lower_um",
    "touch_upper_um",
    "mean_lower_um",
    "mean_upper_um",
    "mean_of_repetitions",
    "budget_um",
    "ront_um",
}


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    base = tmp_path_factory.mktemp("uncertainty")
    data = write_campaign(lobing_campaign(seed=3, n_repetitions=6, n_points=N_POINTS, check_orientations=[(43.0, 91.0)]), base / "c.csv")
    out = base / "model"
    assert train_command(data, out, network_config=QUICK, quiet=True) == 0
    return out


def invoke(*args: str):
    return CliRunner().invoke(app, ["uncertainty", *args])


def test_json_has_a_band_per_orientation_and_model(folder: Path) -> None:
    errors, repetitions = load_errors(folder)
    assert set(errors) == {"network", "trilinear"} and repetitions == 6
    result = invoke("--model", str(folder), "--orientations", "15:-20, 43:90", "--level", "0.9", "--json", "--seed", "1")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["level"] == 0.9
    bands = report["bands"]
    assert [(b["A_deg"], b["B_deg"], b["model"]) for b in bands] == [
        (15.0, -20.0, "network"),
        (15.0, -20.0, "trilinear"),
        (43.0, 90.0, "network"),
        (43.0, 90.0, "trilinear"),
    ]
    for band in bands:
        assert set(band) == BAND_KEYS
        lo_t, hi_t = np.array(band["touch_lower_um"]), np.array(band["touch_upper_um"])
        lo_m, hi_m = np.array(band["mean_lower_um"]), np.array(band["mean_upper_um"])
        assert lo_t.shape == hi_t.shape == lo_m.shape == hi_m.shape == (N_POINTS,)
        assert np.all(lo_t < lo_m) and np.all(lo_m < hi_m) and np.all(hi_m < hi_t)
        assert band["mean_of_repetitions"] == 6
        budget = band["budget_um"]
        assert set(budget) == {"repeatability", "repeatability_mean", "model", "parameters", "combined_touch", "combined_mean"}
        assert budget["model"] > 0 and budget["combined_touch"] > budget["repeatability"]
        assert set(band["ront_um"]) == {"value", "U"} and band["ront_um"]["value"] > 0 and band["ront_um"]["U"] > 0
    # A wider level gives a wider band (about 1.1 against 0.7 um here: one digit of its Monte Carlo
    # tells them apart; the default digits are the call's above).
    wide = invoke("--model", str(folder), "--orientations", "15:-20", "--level", "0.99", "--json", "--seed", "1", "--digits", "1")
    wide = json.loads(wide.stdout)
    narrow = bands[1]
    assert np.mean(np.subtract(wide["bands"][1]["touch_upper_um"], wide["bands"][1]["touch_lower_um"])) > np.mean(
        np.subtract(narrow["touch_upper_um"], narrow["touch_lower_um"])
    )


def test_text_output_names_the_budget(folder: Path) -> None:
    result = invoke("--model", str(folder), "--orientations", "30:0", "--seed", "2", "--digits", "1")  # a quick look
    assert result.exit_code == 0, result.output
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 2 and all("budget um" in line and "RONt" in line for line in lines)


@pytest.mark.parametrize(
    "args, option",
    [
        (["--orientations", "15"], "--orientations"),
        (["--orientations", "15:-20:3"], "--orientations"),
        (["--orientations", "a:b"], "--orientations"),
        (["--orientations", ","], "--orientations"),
        (["--orientations", "150:0"], "--orientations"),
        (["--orientations", "15:-20", "--level", "1.5"], "--level"),
        (["--orientations", "15:-20", "--level", "0"], "--level"),
        (["--orientations", "15:-20", "--digits", "5"], "--digits"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(folder: Path, args: list[str], option: str) -> None:
    result = invoke("--model", str(folder), *args, "--json")
    assert result.exit_code == 2
    assert result.stdout == ""  # nothing half-written
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and f"option {option}" in lines[0]


def test_missing_folder_and_folder_without_errors(folder: Path, tmp_path: Path) -> None:
    missing = invoke("--model", str(tmp_path / "nope"), "--orientations", "15:-20", "--json")
    assert missing.exit_code == 2 and missing.stdout == ""
    assert (
        len(missing.stderr.strip().splitlines()) == 1 and "model folder not found" in missing.stderr and "option --model" in missing.stderr
    )
    old = tmp_path / "old"
    shutil.copytree(folder, old)
    (old / FILE_NAME).unlink()
    result = invoke("--model", str(old), "--orientations", "15:-20", "--json")
    assert result.exit_code == 2 and result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1 and FILE_NAME in result.stderr
