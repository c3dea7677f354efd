"""The explorer opens and continues a study (`serve --study`, issue 13 item 8), with fake browsers.

A small twin campaign (40 rings of 4 repetitions of 32 points, a hidden 22/rev B-axis error of
2 arcsec) keeps each diagnosis to seconds; its study is made by the core as `diagnose --save`
makes it (diagnose, then Study.of_run), so the app opens what the command line writes.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from fake_browser import open_session, wait_for

from ph_explorer.app.server import build_server
from ph_explorer.diagnosis import diagnose
from ph_explorer.diagnosis.study import Study
from ph_explorer.effects import DEFAULT_CATALOG, effect_label
from ph_explorer.errors import InputError
from ph_explorer.io import file_sha256, read_campaign, write_campaign, write_json_object
from ph_explorer.twin import scenario_from_dict, simulate

SMALL = {
    "name": "small_b22",
    "seed": 5,
    "repetitions": 4,
    "check_orientations": [[43, 90], [22, -130], [67, -70], [28, 50]],
    "geometry": {"points_per_circle": 32},
    "orientations": {"a_deg": [0, 90, 30], "b_deg": [-160, 180, 40], "off_grid": [[43, 90], [22, -130], [67, -70], [28, 50]]},
    "effects": [
        {"id": "noise", "sigma_um": 0.1},
        {"id": "b_axis_cyclic", "hidden": True, "amplitude_arcsec": 2.0, "phase_deg": 30.0, "cycles_per_rev": 22},
    ],
}
B22 = "b_axis_cyclic 22 cycles/rev"


@pytest.fixture(scope="module")
def small_csv(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("study")
    return write_campaign(simulate(scenario_from_dict(SMALL)), folder / "small.csv")


@pytest.fixture(scope="module")
def cli_study(small_csv: Path) -> dict:
    """The study `diagnose --data small.csv --save` writes (the same core calls, in-process)."""
    campaign = read_campaign(small_csv)
    result = diagnose(campaign, nested=False)
    assert [effect_label(e) for e in result.chain] == [B22] and result.verdict == "missing"
    described = {
        "file": small_csv.name,
        "sha256": file_sha256(small_csv),
        "orientations": campaign.n_orientations,
        "repetitions": campaign.n_repetitions,
    }
    return Study.of_run(result, result.chain, described, "trilinear").to_json()


def checked(path: Path) -> dict:
    """The study on disk, as JSON, once it reads back whole as a Study."""
    saved = json.loads(path.read_text())
    Study.parse(saved, str(path), DEFAULT_CATALOG)
    return saved


@pytest.fixture()
def study_file(cli_study: dict, tmp_path: Path) -> Path:
    path = tmp_path / "s.json"
    write_json_object(path, cli_study)
    return path


def test_a_study_opens_with_its_history_continues_from_its_chain_and_saves_a_run(small_csv, study_file, cli_study, monkeypatch):
    app = build_server(data=small_csv, study=study_file, port=0)
    (fake, s), (fake2, s2) = open_session(app), open_session(app)
    try:
        p = s.physics
        # The study line: which study, its runs, the model it reached, its verdict; Save study is offered.
        assert "s.json" in p.study_line.content and "1 run;" in p.study_line.content
        assert B22 in p.study_line.content and "missing" in p.study_line.content and p.save_study.visible
        # The history starts with the study's steps (Step objects rebuilt from the JSON).
        assert [list(st.added) for st in s.loop.steps] == [st["added"] for st in cli_study["steps"]] == [[], ["b_axis_cyclic"]]
        assert [st.mae_um["mean"] for st in s.loop.steps] == [st["mae_um"]["mean"] for st in cli_study["steps"]]
        assert p.history.visible and "+ b_axis_cyclic" in p.history_table.content
        # Saving before any diagnosis is refused in one line: a run records a diagnosis.
        fake.click("Save study")
        assert wait_for(lambda: "diagnose first" in p.study_status.content)
        s.wait()
        # Diagnose continues from the chain: the candidates re-ranked with the 22/rev error in the model.
        fake.click("Diagnose")
        # Wait on the Diagnose's own outcome (any other job of the session could satisfy "a job runs").
        done = wait_for(lambda: s.loop.diagnosis is not None or "Cannot diagnose" in p.verdict.content, timeout=300)
        s.wait(timeout=300)
        result = s.loop.diagnosis
        assert done and result is not None, f"no diagnosis: status {p.status.content!r}, verdict {p.verdict.content!r}"
        assert result.started_from == 1 and [effect_label(e) for e in result.chain[:1]] == [B22]
        assert f"Resumed with {B22} in the model" in p.verdict.content and "continuing the study" in p.status.content
        assert len(s.loop.steps) == 2  # the study's history goes on, not restarted at the baseline
        # Refit: the chain + the ticked effect, at the diagnosis's settings.
        ticked = next(c for c in result.candidates if c.effect != "b_axis_cyclic")
        p.effects[ticked.effect].value = True
        fake.click("Refit the hybrid")
        assert wait_for(lambda: len(s.jobs) > 0)
        s.wait(timeout=300)
        assert s.loop.steps[-1].added == ("b_axis_cyclic", ticked.effect) and len(s.loop.steps) == 3
        # A write that fails (disk full) is one line in the panel; the study on disk is untouched.
        before = study_file.read_text()
        from ph_explorer.diagnosis import study as study_module

        def full(path, document):
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(study_module, "write_json_object", full)
        fake.click("Save study")
        assert wait_for(lambda: "No space left on device" in p.study_status.content)
        s.wait()
        assert "Cannot save" in p.study_status.content and study_file.read_text() == before
        monkeypatch.undo()
        # Save study: the next run, on disk and valid; the session keeps it as the study it continues.
        fake.click("Save study")
        assert wait_for(lambda: "Saved: run 2" in p.study_status.content)
        s.wait()
        saved = checked(study_file)
        assert len(saved["runs"]) == 2 and saved["runs"][0] == cli_study["runs"][0]
        assert saved["runs"][1]["started_from"] == 1 and saved["runs"][1]["added"] == [effect_label(s.loop.chain[1])]
        assert [e["effect"] for e in saved["chain"]] == ["b_axis_cyclic", ticked.effect]
        assert saved["chain"][0]["settings"] == {"cycles_per_rev": 22.0} and saved["chain"][0]["params"]
        assert [st["added"] for st in saved["steps"]] == [[], ["b_axis_cyclic"], ["b_axis_cyclic", ticked.effect]]
        assert saved["runs"][-1]["verdict"] == result.verdict and saved["campaign"] == cli_study["campaign"]
        assert s.loop.previous.to_json() == saved and "2 runs" in p.study_line.content and not p.effects[ticked.effect].value
        # The other browser opened the study before that save: its save would drop run 2, so it is refused.
        s2.loop.diagnosis, s2.loop.diagnosed = result, True  # as if it had diagnosed too
        fake2.click("Save study")
        assert wait_for(lambda: "another browser saved this study" in s2.physics.study_status.content)
        s2.wait()
        assert json.loads(study_file.read_text()) == saved
        # Other data in a browser: the study no longer applies there; Save study goes away.
        s.load_upload("small.csv", small_csv.read_bytes())
        assert "reload the page" in p.study_line.content and not p.save_study.visible and s.loop.steps == []
    finally:
        fake.close()
        fake2.close()
        app.stop()


def test_a_new_study_is_written_on_the_first_save(small_csv, tmp_path):
    path = tmp_path / "new.json"
    app = build_server(data=small_csv, study=path, port=0)
    fake, s = open_session(app)
    try:
        assert "(new)" in s.physics.study_line.content and s.loop.steps == [] and not path.exists()
        fake.click("Diagnose")
        assert wait_for(lambda: bool(s.jobs))
        s.wait(timeout=300)
        assert s.loop.diagnosis.started_from == 0 and s.loop.diagnosis.nested is not None  # the honest "after", as the CLI
        assert "The same, out of sample: the claims fitted" in s.physics.history_table.content
        fake.click("Save study")
        assert wait_for(lambda: "Saved: run 1" in s.physics.study_status.content)
        saved = checked(path)
        assert saved["campaign"]["sha256"] == file_sha256(small_csv) and saved["chain"] == []
        assert saved["runs"][-1]["verdict"] == "missing" and [st["added"] for st in saved["steps"]] == [[]]
        assert sorted(p.name for p in tmp_path.iterdir()) == ["new.json"]  # nothing else written beside it
    finally:
        fake.close()
        app.stop()


def test_a_study_of_another_campaign_or_place_is_refused_before_the_server_starts(small_csv, study_file, tmp_path):
    other = write_campaign(simulate(scenario_from_dict({**SMALL, "seed": 6})), tmp_path / "other.csv")
    with pytest.raises(InputError, match="the study was made on small.csv"):
        build_server(data=other, study=study_file, port=0)
    with pytest.raises(InputError, match="simulate the scenario to a CSV"):
        build_server(scenario="head_3", study=study_file, port=0)
    with pytest.raises(InputError, match="no such folder"):
        build_server(data=small_csv, study=tmp_path / "nowhere" / "s.json", port=0)
    with pytest.raises(InputError, match="small.csv"):  # a file that is not a study
        build_server(data=small_csv, study=small_csv, port=0)
    # Through the command line: one line, exit 2, nothing served.
    env = dict(os.environ, COLUMNS="120")
    done = subprocess.run(
        [sys.executable, "-m", "ph_explorer", "serve", "--data", str(other), "--study", str(study_file), "--port", "0"],
        capture_output=True,
        text=True,
        env=env,
        timeout=120,
    )
    assert done.returncode == 2, (done.stdout, done.stderr)
    assert len(done.stderr.strip().splitlines()) == 1 and "the study was made on small.csv" in done.stderr
    assert "serving" not in done.stdout
