"""`ph-explorer effects` as a user meets it, through the command line's own path (tests/command_line.py)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from command_line import run_cli

from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.paths import assets_dir

DESCRIBED = {"id", "name", "axis", "kind", "symbol", "parameters"}
JUDGED = {"visible", "absorbed_by_circle_fit", "learnable_by_data_model", "confounded_with"}


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return run_cli(*args)


def one_line_error(result: subprocess.CompletedProcess[str]) -> str:
    assert result.returncode == 2, (result.stdout, result.stderr)
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    return lines[0]


def test_effects_json_lists_every_effect_of_the_catalog_with_its_description() -> None:
    result = run("effects", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["design"] is None
    assert [row["id"] for row in report["effects"]] == list(DEFAULT_CATALOG)
    for row in report["effects"]:
        assert set(row) >= DESCRIBED and not set(row) & JUDGED, row["id"]
        assert all(set(p) == {"name", "unit", "plausible"} for p in row["parameters"])
    symbols = {row["id"]: row["symbol"] for row in report["effects"]}
    assert symbols["b_axis_cyclic"] == "ECB" and symbols["a_axis_cyclic"] == "EAA"


def test_effects_text_is_one_aligned_line_per_effect_and_takes_user_effects() -> None:
    result = run("effects", "--effects", str(assets_dir() / "effects_example.py"))
    assert result.returncode == 0, result.stderr
    lines = result.stdout.splitlines()
    assert lines[0].split()[:4] == ["id", "symbol", "axis", "kind"]
    assert [line.split()[0] for line in lines[1:]] == [*DEFAULT_CATALOG, "my_ball_form"]
    assert len({line.index(line.split()[1], len(line.split()[0])) for line in lines}) == 1  # aligned columns


def test_the_confounded_partners_are_listed_below_the_table_not_in_a_column() -> None:
    from ph_explorer.cli.effects_command import effects_text

    row = {"id": "b_axis_tilt_motion", "symbol": "EAB", "axis": "B", "kind": "tilt_motion", "parameters": [], "scan": {}}
    partner = {"effect": "a_axis_cyclic", "shared": 1.0, "settings": {"cycles_per_rev": 1.0}, "other_settings": {"cycles_per_rev": 1.0}}
    design = dict.fromkeys(("file", "rings", "held_out_rings", "repetitions", "points", "columns", "rank_after_fit"), 1)
    design |= {"noise_floor_um": 0.05, "rank_out_of_sample": 1, "confounding": "above 0.8"}
    text = effects_text({"design": design, "effects": [row | {"confounded_with": [partner] * 12}, row | {"id": "drift"}]})
    table = text.splitlines()[5:8]
    assert "confounded" not in table[0] and max(len(line) for line in table) < 140
    block = text[text.index("Confounded with") :].splitlines()[1:]
    assert block[0].startswith("  b_axis_tilt_motion: a_axis_cyclic 1.00 (cycles per rev 1, both)")
    assert len(block) > 1 and all(len(line) <= 118 for line in block) and "drift" not in text[text.index("Confounded with") :]


@pytest.mark.slow
def test_effects_with_data_judges_every_effect_on_the_paper_campaign() -> None:
    result = run("effects", "--data", str(assets_dir() / "data" / "paper.csv"), "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["design"]["file"] == "paper.csv" and report["design"]["rings"] == 135
    for row in report["effects"]:
        assert set(row) >= DESCRIBED | JUDGED, row["id"]
    rows = {row["id"]: row for row in report["effects"]}
    assert rows["stylus_bending"]["visible"] is False and rows["ring_form"]["visible"] is True
    assert "lobing" in {o["effect"] for o in rows["ball_form"]["confounded_with"]}


def test_a_bad_data_path_is_one_line_and_exit_2(tmp_path: Path) -> None:
    line = one_line_error(run("effects", "--data", str(tmp_path / "missing.csv")))
    assert "missing.csv" in line


def test_a_user_file_that_reuses_a_built_in_id_is_one_line_and_exit_2(tmp_path: Path) -> None:
    path = tmp_path / "mine.py"
    path.write_text(
        "from ph_explorer.effects.effect import Effect\n"
        "class Mine(Effect):\n    id = 'ball_form'\n    def basis(self, touches):\n        return None\n"
    )
    line = one_line_error(run("effects", "--effects", str(path)))
    assert "'ball_form' is already a built-in effect" in line
