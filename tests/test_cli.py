"""The command line as a user meets it: run in a subprocess."""

from __future__ import annotations

import json
import os
import re
import shutil
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
    assert s["near_pole"] == []  # A0 = 0 is on the pole, A43 far from it
    assert 0 < s["unreachable_touches"] < 6 * 32 and s["unreachable_touches"] % 6 == 0
    assert s["scenario"] == {"name": "test", "seed": 1, "hidden_effects": 0}


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


def test_inspect_names_the_rings_near_the_pole(tmp_path: Path) -> None:
    """A ring between A0 = 0 and the lattice's next A (A9: B turns 92 deg while A swings) is where
    the interpolation between rings is poorest; inspect names it, in text and JSON."""
    rng = np.random.default_rng(3)
    orientations = np.array([(a, b) for a in (0.0, 15.0, 30.0) for b in (-120.0, 0.0, 120.0)] + [(9.0, 45.0), (40.0, 45.0)])
    path = write_campaign(Campaign(orientations, rng.normal(0.0, 0.2, (11, 3, 64))), tmp_path / "pole.csv")
    assert json.loads(run("inspect", str(path), "--json").stdout)["near_pole"] == [[9.0, 45.0]]
    line = next(line for line in run("inspect", str(path)).stdout.splitlines() if line.startswith("rings near the pole"))
    assert "A9 B45 (B turns over a quarter turn" in line and "A40" not in line


def test_inspect_without_a_file_is_a_usage_error() -> None:
    result = run("inspect")
    assert result.returncode == 2 and "Traceback" not in result.stderr


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (("serve", "--port", "abc"), "option --port: 'abc' is not a valid int (ph-explorer serve --help"),
        (("diagnose", "--modle", "x"), "No such option: --modle"),
        (("diagnose",), "Missing option '--data'"),
        (("frobnicate",), "No such command 'frobnicate'"),
    ],
)
def test_a_command_line_that_cannot_be_parsed_is_one_line(args: tuple[str, ...], words: str) -> None:
    result = run(*args)
    assert result.returncode == 2 and result.stdout == ""
    assert len(result.stderr.splitlines()) == 1 and words in result.stderr, result.stderr


# -- the command layer: imports, import errors, option errors --------------------------------------

# Runs the console script's main() with torch unimportable, as on a machine without it.
WITHOUT_TORCH = """
import sys

class NoTorch:
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None

sys.meta_path.insert(0, NoTorch())
from ph_explorer.cli import main

sys.argv[0] = "ph-explorer"
main()
"""


def run_without_torch(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, COLUMNS="120")
    return subprocess.run([sys.executable, "-c", WITHOUT_TORCH, *args], capture_output=True, text=True, env=env, timeout=120)


def test_without_torch_train_reports_the_import_error_and_inspect_works(tmp_path: Path) -> None:
    path = _campaign(tmp_path)
    out = tmp_path / "model"
    train = run_without_torch("train", "--data", str(path), "--out", str(out))
    assert train.returncode == 1, (train.stdout, train.stderr)
    assert train.stderr.strip().splitlines() == ["ph-explorer train: ModuleNotFoundError: No module named 'torch'"]
    assert not out.exists() and "not implemented" not in train.stderr
    inspect = run_without_torch("inspect", str(path), "--json")
    assert inspect.returncode == 0, inspect.stderr
    assert json.loads(inspect.stdout)["orientations"] == 11
    listed = run_without_torch("simulate", "--list")  # the twin needs no torch either
    assert listed.returncode == 0 and listed.stdout.startswith("head_2")
    # Nor the diagnosis on the trilinear baseline (issue 28: no torch unless the network is asked for).
    diagnosed = run_without_torch("diagnose", "--data", str(path), "--json")
    assert diagnosed.returncode == 0, diagnosed.stderr
    assert json.loads(diagnosed.stdout)["baseline"]["model"] == "trilinear"


def test_importing_the_cli_imports_neither_torch_nor_viser() -> None:
    probe = (
        "import json, sys\n"
        "import ph_explorer.cli\n"
        "print(json.dumps({m: m in sys.modules for m in ('torch', 'viser', 'ph_explorer.cli.train_command', 'ph_explorer.cli.serve_command')}))\n"
    )
    result = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    loaded = json.loads(result.stdout)
    assert loaded["ph_explorer.cli.train_command"] and loaded["ph_explorer.cli.serve_command"]  # the command modules are loaded ...
    assert not loaded["torch"] and not loaded["viser"]  # ... without what they need only when they run


@pytest.mark.parametrize(
    "value,words",
    [("", "names no effect"), (" , ", "names no effect"), ("wobble", "unknown effect 'wobble'"), ("noise", "cannot be added")],
)
def test_a_bad_add_option_is_one_line_naming_the_option(tmp_path: Path, value: str, words: str) -> None:
    path = _campaign(tmp_path)
    result = run("diagnose", "--data", str(path), "--add", value)
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith("option --add: ") and words in lines[0], lines[0]


def test_other_option_errors_name_the_option(tmp_path: Path) -> None:
    path = _campaign(tmp_path)
    part = run("diagnose", "--data", str(path), "--data-part", "forest")
    assert part.returncode == 2 and part.stderr.strip() == (
        "option --data-part: unknown data-driven part 'forest' (trilinear, network, gp)"
    )
    missing = run("simulate", "--out", str(tmp_path / "x.csv"))
    assert missing.returncode == 2 and missing.stderr.strip().startswith("option --scenario: ")
    holdout = run("train", "--data", str(path), "--out", str(tmp_path / "m"), "--holdout", "1:2")
    assert holdout.returncode == 2 and holdout.stderr.strip() == f"{path}, option --holdout: orientation(s) 1:2 not in the campaign"


@pytest.mark.parametrize("command", ["simulate", "report"])
def test_an_unknown_scenario_names_the_option_and_a_missing_folder_makes_none(tmp_path: Path, command: str) -> None:
    out = tmp_path / ("x.csv" if command == "simulate" else "x.html")
    unknown = run(command, "--scenario", "head_99", "--out", str(out))
    assert unknown.returncode == 2 and unknown.stderr.strip().startswith("option --scenario: unknown scenario 'head_99' (shipped: ")
    # An output in a folder that does not exist is refused before any work, as by every command.
    missing = run(command, "--scenario", "head_3", "--out", str(tmp_path / "no_such" / out.name))
    assert missing.returncode == 2 and missing.stderr.strip() == f"{tmp_path / 'no_such'}, option --out: no such folder for the " + (
        "campaign" if command == "simulate" else "report"
    )
    assert not (tmp_path / "no_such").exists() and not out.exists()


@pytest.mark.parametrize(
    "args",
    [
        ("train", "--data", "{csv}", "--out", "{missing}/model"),
        ("merge", "{csv}", "{csv2}", "--out", "{missing}/all.csv"),
        ("design", "--start", "--out", "{missing}/plan.csv"),
        ("design", "--data", "{csv}", "--decide", "--out", "{missing}/rings.csv"),
        ("diagnose", "--data", "{csv}", "--save", "{missing}/study.json"),
    ],
)
def test_every_output_in_a_missing_folder_is_refused_before_any_work(tmp_path: Path, args: tuple[str, ...]) -> None:
    csv = _campaign(tmp_path)
    values = {"csv": csv, "csv2": csv.with_name("copy.csv"), "missing": tmp_path / "no_such"}
    shutil.copy(csv, values["csv2"])
    result = run(*(arg.format(**values) for arg in args))
    assert result.returncode == 2 and result.stderr.strip().startswith(f"{tmp_path / 'no_such'}, option --")
    assert "no such folder" in result.stderr and not (tmp_path / "no_such").exists()
