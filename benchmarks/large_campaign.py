"""A bigger campaign (issue 16, item 5): the paper's design four times denser, 256 points per ring.

The paper scenario with its lattice at A every 7.5 deg and B every 10 deg (4x the rings) and 256
points per circle (4x the points): 16x the touches. Each command a user runs on it (simulate,
train, evaluate, diagnose, serve) runs as its own process through the command line, at the paper's
size and at this size; recorded per command: the wall seconds and the peak resident memory of
that process (MiB, from the kernel's rusage of the child, through benchmarks/peak.py), and the growth exponent between the two
sizes, log(large / paper) / log(touches large / touches paper): 1 is linear in the touches.
"""

from __future__ import annotations

import copy
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import tomli_w

from ph_explorer.paths import scenarios_dir

REPOSITORY = Path(__file__).resolve().parent.parent
DIAGNOSIS_TARGET = {"seconds": 30.0, "peak_mib": 2048.0}  # issue 28: the dense campaign diagnosed within 30 s and 2 GiB

QUICK_EPOCHS = 10  # the network's epochs in quick mode (every quick NetworkConfig of the benchmarks): a smoke test


def large_scenario() -> dict[str, Any]:
    """The paper scenario, four times denser in rings and points (the check and off-grid rings kept)."""
    data = copy.deepcopy(tomllib.loads((scenarios_dir() / "paper.toml").read_text(encoding="utf-8")))
    data["name"] = "paper_dense"
    data["description"] = "The paper's campaign, A every 7.5 deg, B every 10 deg, 256 points per ring (benchmark)"
    data["orientations"]["a_deg"] = [0, 90, 7.5]
    data["orientations"]["b_deg"] = [-170, 180, 10]
    data.setdefault("geometry", {})["points_per_circle"] = 256
    return data


def run_command(args: list[str], stop_when: Callable[[str], bool] | None = None, timeout: float = 3600.0) -> dict[str, Any]:
    """`python -m ph_explorer ARGS` in its own process: wall seconds and peak RSS (MiB).

    stop_when: for a server, a test on each output line; the process is interrupted once it holds
    (the figures are then those of start-up) and must then stop with status 0.
    """
    start = time.perf_counter()
    process = subprocess.Popen(  # through benchmarks/peak.py: the command's own peak, not this process'
        [sys.executable, "-m", "benchmarks.peak", sys.executable, "-m", "ph_explorer", *args],
        cwd=REPOSITORY,
        start_new_session=True,  # one group: the killer below stops the command, not only its launcher
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    output: list[str] = []
    wall = None  # set when a server's line is seen (then Ctrl-C is sent)
    # A command that outlives the timeout (or a server that does not stop on Ctrl-C) is killed.
    killer = threading.Timer(timeout, os.killpg, (process.pid, signal.SIGKILL))
    killer.start()
    assert process.stdout is not None
    for line in process.stdout:
        output.append(line)
        if stop_when is not None and stop_when(line):
            wall = time.perf_counter() - start
            process.send_signal(signal.SIGINT)
            killer.cancel()
            killer = threading.Timer(10.0, os.killpg, (process.pid, signal.SIGKILL))  # a command that ignores Ctrl-C
            killer.start()
            output.extend(process.stdout)  # what it says while it stops; EOF when it has
            break
    _, status, _ = os.wait4(process.pid, 0)
    killer.cancel()
    process.stdout.close()
    served = wall is not None
    wall = wall if served else time.perf_counter() - start
    peaks = [int(line.split()[1]) for line in output if line.startswith("PEAK_KIB ")]
    output = [line for line in output if not line.startswith("PEAK_KIB ")]
    # A server counts only if it printed its line and then stopped on Ctrl-C with status 0.
    exit_status = os.waitstatus_to_exitcode(status)
    ok = exit_status == 0 and bool(peaks) and (stop_when is None or served)
    return {
        "seconds": round(wall, 2),
        "peak_mib": round(peaks[-1] / 1024.0, 1) if peaks else None,  # ru_maxrss is in KiB on Linux
        "ok": bool(ok),
        "tail": f"exit status {exit_status}: " + "".join(output[-3:]).strip()[-400:] if not ok else "",
    }


def commands(folder: Path, name: str, quick: bool = False) -> list[tuple[str, list[str], Callable[[str], bool] | None]]:
    csv, model = folder / f"{name}.csv", folder / f"{name}_model"
    # quick: a short network (as the other sections' quick mode), the commands' paths all the same
    short = ["--max-epochs", str(QUICK_EPOCHS)] if quick else []
    scenario = folder / f"{name}_scenario.toml"
    serving = re.compile(r"serving at \S+")
    return [
        ("simulate", ["simulate", "--scenario", str(scenario), "--out", str(csv)], None),
        ("train", ["train", "--data", str(csv), "--out", str(model), *short], None),
        ("evaluate", ["evaluate", "--model", str(model), "--data", str(csv), "--json"], None),
        ("diagnose", ["diagnose", "--data", str(csv), "--json"], None),
        ("serve", ["serve", "--data", str(csv), "--model", str(model), "--port", "0"], lambda line: bool(serving.search(line))),
    ]


def run(folder: Path, quick: bool = False, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Every command at the paper's size and at the dense size (quick: the paper's rings with twice
    its points, so that a smoke test stays short); figures and growth exponents."""
    folder.mkdir(parents=True, exist_ok=True)
    paper = tomllib.loads((scenarios_dir() / "paper.toml").read_text(encoding="utf-8"))
    dense = large_scenario()
    if quick:  # the paper's rings, twice its points: more touches, at the cost of few rings
        dense["orientations"] = paper["orientations"]
        dense["geometry"]["points_per_circle"] = 128
    sizes: dict[str, Any] = {}
    for name, data in (("paper", paper), ("dense", dense)):
        (folder / f"{name}_scenario.toml").write_text(tomli_w.dumps(data), encoding="utf-8")
        figures: dict[str, Any] = {}
        for command, args, stop_when in commands(folder, name, quick):
            figures[command] = run_command(args, stop_when)
            log(f"  {name} {command}: {figures[command]}")
        sizes[name] = figures
    touches = {name: touch_count(folder / f"{name}.csv") for name in sizes}
    growth = {
        command: {
            key: round(
                math.log(sizes["dense"][command][key] / sizes["paper"][command][key]) / math.log(touches["dense"] / touches["paper"]), 2
            )
            for key in ("seconds", "peak_mib")
            if (sizes["paper"][command][key] or 0) > 0 and (sizes["dense"][command][key] or 0) > 0
        }
        for command in sizes["paper"]
    }
    diagnosis = sizes["dense"]["diagnose"]
    return {
        "design": "paper scenario, A every 7.5 deg x B every 10 deg + the paper's off-grid rings, 256 points, 10 repetitions"
        if not quick
        else "quick: the paper's rings, 128 points",
        "touches": touches,
        "paper": sizes["paper"],
        "dense": sizes["dense"],
        "growth_exponent": growth,
        "diagnosis_target": DIAGNOSIS_TARGET,
        "diagnosis_holds": bool(
            diagnosis["ok"]
            and diagnosis["seconds"] <= DIAGNOSIS_TARGET["seconds"]
            and diagnosis["peak_mib"] <= DIAGNOSIS_TARGET["peak_mib"]
        ),
        "note": "each command a separate process through the command line (interpreter and imports included); serve: until it prints its URL",
    }


def touch_count(csv: Path) -> int:
    with csv.open(encoding="utf-8") as handle:
        return sum(1 for _ in handle) - 1
