"""`ph-explorer diagnose` on a fleet (issue 33): many campaigns on Dask, each diagnosed on a worker
exactly as the single command diagnoses it alone, one row each; a file that fails is its row."""

from __future__ import annotations

import html
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from command_line import run_cli

from ph_explorer.errors import InputError
from ph_explorer.figures.fleet_page import report_names
from ph_explorer.io import campaign_files, write_campaign
from ph_explorer.twin.random_heads import random_campaign

SEEDS = (11, 12, 13, 14)
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
    """Four small random heads (the coarse design) and a file no program could read as a campaign."""
    folder = tmp_path_factory.mktemp("heads")
    for seed in SEEDS:
        write_campaign(random_campaign(seed, "coarse"), folder / f"head_{seed}.csv")
    (folder / "broken.csv").write_text("A_deg,B_deg,point\n15,-20,oops\n")
    return folder


@pytest.fixture(scope="module")
def alone(heads: Path) -> dict[str, dict]:
    """Each head diagnosed by the single command in a fresh interpreter: its --json report."""
    reports = {}
    for seed in SEEDS:
        path = heads / f"head_{seed}.csv"
        done = json.loads(subprocess.run([sys.executable, "-c", ALONE, str(path)], capture_output=True, text=True, check=True).stdout)
        assert done["status"] == 0 and done["dask"] == []  # one campaign never loads Dask
        reports[path.name] = done["report"]
    return reports


def same_as_alone(fleet: dict, alone: dict[str, dict]) -> None:
    """Every head's row holds exactly what the single command printed for it alone."""
    rows = {Path(r["campaign"]).name: r for r in fleet["campaigns"]}
    for name, report in alone.items():
        assert rows[name]["diagnosis"] == report, name  # the same result, to the last digit
        assert rows[name]["verdict"] == report["verdict"] and len(rows[name]["sha256"]) == 64 and rows[name]["seconds"] > 0


def test_files_patterns_and_folders_name_the_campaigns_once_each(heads: Path) -> None:
    first = heads / "head_11.csv"
    assert campaign_files([heads]) == sorted(heads.glob("*.csv"))
    assert campaign_files([first, str(heads / "head_1*.csv")]) == [first, *(heads / f"head_{s}.csv" for s in SEEDS[1:])]
    with pytest.raises(InputError, match="no file matches"):
        campaign_files([str(heads / "nothing_*.csv")])
    (heads / "empty").mkdir()
    with pytest.raises(InputError, match="holds no .csv file"):
        campaign_files([heads / "empty"])


def test_each_campaign_of_a_fleet_is_diagnosed_as_alone_and_a_broken_file_is_its_row(heads: Path, alone: dict[str, dict]) -> None:
    done = run_cli("diagnose", "--data", heads, "--json")
    assert done.returncode == 2, done.stderr  # one file failed: exit 2, after all the others
    fleet = json.loads(done.stdout)
    rows = {Path(r["campaign"]).name: r for r in fleet["campaigns"]}
    assert list(rows) == ["broken.csv", *(f"head_{s}.csv" for s in SEEDS)] and fleet["failed"] == 1
    assert "error" in rows["broken.csv"] and len(rows["broken.csv"]["error"].splitlines()) == 1
    assert "diagnosis" not in rows["broken.csv"]
    same_as_alone(fleet, alone)
    assert fleet["workers"] == (os.cpu_count() or 1) and fleet["workers_lost"] == 0  # a LocalCluster of the cores
    # Progress on stderr: done/total, elapsed, the slowest.
    assert f"{len(SEEDS) + 1}/{len(SEEDS) + 1} diagnosed" in done.stderr and "slowest" in done.stderr


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
        (["--data", "{heads}", "--model", "{heads}/no_model"], "model folder not found"),
        (["--data", "{heads}", "--report", "{heads}"], "option --report: is a folder"),
        (["--data", "{heads}", "--report", "{heads}/no_folder/fleet.html"], "no such folder for the fleet's page"),
    ],
)
def test_a_bad_fleet_option_is_one_line_and_no_worker_starts(heads: Path, args: list[str], words: str) -> None:
    done = run_cli("diagnose", *[a.format(heads=heads) for a in args])
    assert done.returncode == 2 and words in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
    assert not (heads / "study.json").exists()


# A report's own dates (its making, the study's run): all that differs between two makings of it.
DATES = re.compile(r"\d{4}-\d\d-\d\d[T ]\d\d:\d\d(:\d\d)?( UTC)?")


def test_the_fleet_page_links_each_campaign_to_its_own_report_as_the_report_command_writes_it(heads: Path, tmp_path: Path) -> None:
    page = tmp_path / "fleet.html"
    done = run_cli("diagnose", "--data", heads / "head_11.csv", "--data", heads / "broken.csv", "--report", page, "--json")
    assert done.returncode == 2, done.stderr
    rows = {Path(r["campaign"]).name: r for r in json.loads(done.stdout)["campaigns"]}
    assert rows["head_11.csv"]["report"] == "head_11.html" and "report" not in rows["broken.csv"]
    text = page.read_text()
    assert '<a href="head_11.html">' in text and html.escape(rows["broken.csv"]["error"]) in text
    assert (
        "2 campaigns in" in text
        and "1 failed" in text
        and f"Verdicts: {rows['head_11.csv']['verdict']} 1, error 1." in text
        and sorted(p.name for p in tmp_path.iterdir()) == ["fleet.html", "head_11.html"]
    )
    alone = tmp_path / "alone" / "head_11.html"
    alone.parent.mkdir()
    assert run_cli("report", "--data", heads / "head_11.csv", "--out", alone).returncode == 0
    written = (tmp_path / "head_11.html").read_text()
    assert DATES.sub("DATE", written) == DATES.sub("DATE", alone.read_text()) and DATES.search(written)


def test_reports_of_campaigns_that_share_a_name_do_not_overwrite_each_other() -> None:
    paths = [Path("a/head.csv"), Path("b/head.csv"), Path("c/fleet.csv"), Path("d/other.csv")]
    assert report_names(paths, Path("out/fleet.html")) == ["head-1.html", "head-2.html", "fleet-3.html", "other.html"]


DASK = str(Path(sys.executable).with_name("dask"))


@pytest.fixture
def cluster(tmp_path: Path):
    """A Dask scheduler and two workers, each its own process on the loopback, the scheduler's port
    chosen free by the system (its address read from its scheduler file): (address, workers)."""
    from dask.distributed import Client

    file = tmp_path / "scheduler.json"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL, "start_new_session": True}
    command = [DASK, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard", "--scheduler-file", str(file)]
    processes = [subprocess.Popen(command, **quiet)]
    try:
        deadline = time.monotonic() + 60
        while not (file.exists() and file.read_text().strip()) and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(file.read_text())["address"]
        for name in ("w1", "w2"):
            worker = [DASK, "worker", address, "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1", "--name", name]
            processes.append(subprocess.Popen(worker, **quiet))
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
        yield address, processes[1:]
    finally:
        for process in processes:  # each with its nanny's children: the whole group
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        for process in processes:
            try:
                process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(timeout=30)
        assert all(p.poll() is not None for p in processes)  # nothing left running


def test_a_fleet_on_a_given_scheduler_gives_each_campaign_as_alone(heads: Path, alone: dict[str, dict], cluster) -> None:
    address, _ = cluster
    specs = [a for seed in SEEDS for a in ("--data", heads / f"head_{seed}.csv")]
    done = run_cli("diagnose", *specs, "--scheduler", address, "--json")
    assert done.returncode == 0, done.stderr
    fleet = json.loads(done.stdout)
    assert fleet["workers"] == 2 and fleet["workers_lost"] == 0 and fleet["failed"] == 0
    same_as_alone(fleet, alone)


def test_a_worker_killed_mid_fleet_loses_no_campaign_and_is_reported(heads: Path, alone: dict[str, dict], cluster) -> None:
    address, workers = cluster
    command = [sys.executable, "-m", "ph_explorer", "diagnose", "--data", str(heads / "head_*.csv"), "--scheduler", address, "--json"]
    fleet = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert fleet.stderr is not None
    for line in fleet.stderr:  # until the first campaign is done: the others are running or queued
        if "diagnosed" in line:
            break
    else:
        raise AssertionError(f"the fleet ended before a campaign was done: {fleet.communicate()}")
    os.killpg(workers[0].pid, signal.SIGKILL)  # the worker and its nanny: a machine lost
    out, err = fleet.communicate(timeout=300)
    assert fleet.returncode == 0, err
    result = json.loads(out)
    assert result["workers"] == 2 and result["workers_lost"] == 1 and "1 of 2 workers lost" in err
    same_as_alone(result, alone)
