"""`ph-explorer diagnose` on a fleet (issue 33): many campaigns on Dask, each diagnosed on a worker
exactly as the single command diagnoses it alone, one row each; a file that fails is its row."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from command_line import run_cli

from ph_explorer.errors import InputError
from ph_explorer.io import campaign_files, write_campaign
from ph_explorer.twin.random_heads import random_campaign

SEEDS = (11, 12, 13)
# The single command in a fresh interpreter: its JSON, and whether it loaded Dask (it must not).
ALONE = """
import json, sys
from typer.testing import CliRunner
from ph_explorer.cli import app
result = CliRunner().invoke(app, ["diagnose", "--data", sys.argv[1], "--json"])
print(json.dumps({"status": result.exit_code, "report": json.loads(result.stdout),
                  "dask": sorted({m.split(".")[0] for m in sys.modules} & {"dask", "distributed"})}))
"""


@pytest.fixture(scope="module")
def heads(tmp_path_factory) -> Path:
    """Three small random heads (the coarse design) and a file no program could read as a campaign."""
    folder = tmp_path_factory.mktemp("heads")
    for seed in SEEDS:
        write_campaign(random_campaign(seed, "coarse"), folder / f"head_{seed}.csv")
    (folder / "broken.csv").write_text("A_deg,B_deg,point\n15,-20,oops\n")
    return folder


def test_files_patterns_and_folders_name_the_campaigns_once_each(heads: Path) -> None:
    first = heads / "head_11.csv"
    assert campaign_files([heads]) == sorted(heads.glob("*.csv"))
    assert campaign_files([first, str(heads / "head_1*.csv")]) == [first, heads / "head_12.csv", heads / "head_13.csv"]
    with pytest.raises(InputError, match="no file matches"):
        campaign_files([str(heads / "nothing_*.csv")])
    (heads / "empty").mkdir()
    with pytest.raises(InputError, match="holds no .csv file"):
        campaign_files([heads / "empty"])


def test_each_campaign_of_a_fleet_is_diagnosed_as_alone_and_a_broken_file_is_its_row(heads: Path) -> None:
    done = run_cli("diagnose", "--data", heads, "--json")
    assert done.returncode == 2, done.stderr  # one file failed: exit 2, after all the others
    fleet = json.loads(done.stdout)
    rows = {Path(r["campaign"]).name: r for r in fleet["campaigns"]}
    assert list(rows) == ["broken.csv", *(f"head_{s}.csv" for s in SEEDS)] and fleet["failed"] == 1
    assert "error" in rows["broken.csv"] and len(rows["broken.csv"]["error"].splitlines()) == 1
    assert "diagnosis" not in rows["broken.csv"]
    for seed in SEEDS:
        path = heads / f"head_{seed}.csv"
        alone = json.loads(subprocess.run([sys.executable, "-c", ALONE, str(path)], capture_output=True, text=True, check=True).stdout)
        assert alone["status"] == 0 and alone["dask"] == []  # one campaign never loads Dask
        row = rows[path.name]
        assert row["diagnosis"] == alone["report"]  # the same result, to the last digit
        assert row["verdict"] == alone["report"]["verdict"] and len(row["sha256"]) == 64 and row["seconds"] > 0
    # Progress on stderr: done/total, elapsed, the slowest.
    assert "4/4 diagnosed" in done.stderr and "slowest" in done.stderr


def test_the_fleet_table_names_each_campaign_its_verdict_and_its_error(heads: Path) -> None:
    done = run_cli("diagnose", "--data", heads / "head_11.csv", "--data", heads / "broken.csv")
    assert done.returncode == 2
    assert "head_11.csv" in done.stdout and "broken.csv" in done.stdout and "error" in done.stdout
    assert "2 campaigns in" in done.stdout and "1 failed" in done.stdout


@pytest.mark.parametrize(
    "args, words",
    [
        (["--data", "{heads}/nothing_*.csv"], "no file matches"),
        (["--data", "{heads}", "--save", "{heads}/study.json"], "option --save: a study is of one campaign"),
        (["--data", "{heads}", "--add", "gremlins"], "--add"),
        (["--data", "{heads}", "--data-part", "oracle"], "--data-part"),
    ],
)
def test_a_bad_fleet_option_is_one_line_and_no_worker_starts(heads: Path, args: list[str], words: str) -> None:
    done = run_cli("diagnose", *[a.format(heads=heads) for a in args])
    assert done.returncode == 2 and words in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not (heads / "study.json").exists()
