"""Campaign CSV + sidecar TOML: round trip, files from other programs, one test per bad input."""

from __future__ import annotations

import csv
import json
import os
from pathlib import Path

import numpy as np
import pytest
from command_line import run_cli  # in this process: the real process's start is tests/test_cli.py's

from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.geometry import Geometry, point_angles_deg
from ph_explorer.io import read_campaign, sidecar_path, write_campaign


def small_campaign(times: bool = True, seed: int = 0) -> Campaign:
    """3 x 4 lattice + one off-grid ring, 3 repetitions, 16 points."""
    rng = np.random.default_rng(seed)
    grid = [(a, b) for a in (0.0, 30.0, 60.0) for b in (-90.0, 0.0, 90.0, 180.0)]
    orientations = np.array(grid + [(43.0, 95.0)])
    deviations = rng.normal(0.0, 0.2, (len(orientations), 3, 16))
    t = np.arange(deviations.size, dtype=float).reshape(deviations.shape) * 0.7 if times else None
    return Campaign(orientations, deviations, t)


# -- round trip -----------------------------------------------------------------------------


def test_round_trip_keeps_everything(tmp_path: Path) -> None:
    c = small_campaign()
    c.check_orientations = np.array([[43.0, 95.0]])
    c.scenario = {"name": "demo", "seed": np.int64(7), "hidden": ["b_cyclic"], "effects": [{"id": "lobing", "amplitude_um": 0.3}]}
    c.geometry = Geometry(pivot_to_ball_mm=100.0, ball_diameter_mm=3.0, bore_diameter_mm=25.0, points_per_circle=16)
    write_campaign(c, tmp_path / "c.csv")
    back = read_campaign(tmp_path / "c.csv")
    np.testing.assert_allclose(back.orientations, c.orientations)
    np.testing.assert_allclose(back.deviations, c.deviations, atol=5.01e-6)
    np.testing.assert_allclose(back.times_s, c.times_s, atol=5.01e-4)
    assert back.geometry == c.geometry
    np.testing.assert_allclose(back.check_orientations, [[43.0, 95.0]])
    assert back.scenario == {"name": "demo", "seed": 7, "hidden": ["b_cyclic"], "effects": [{"id": "lobing", "amplitude_um": 0.3}]}
    assert back.source == str(tmp_path / "c.csv")


def test_write_is_deterministic_and_stable(tmp_path: Path) -> None:
    c = small_campaign()
    write_campaign(c, tmp_path / "a.csv")
    write_campaign(small_campaign(), tmp_path / "b.csv")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()
    # Reading and writing again changes nothing: the format is a fixed point.
    write_campaign(read_campaign(tmp_path / "a.csv"), tmp_path / "c.csv")
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "c.csv").read_bytes()
    header = (tmp_path / "a.csv").read_text().splitlines()[0]
    assert header == "A_deg,B_deg,rep,point,dev_um,t_s"
    assert "-0.00000" not in (tmp_path / "a.csv").read_text()
    mask = os.umask(0)
    os.umask(mask)
    for name in ("a.csv", "a.toml"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~mask  # a normal file, not mkstemp's 0600


def test_write_without_times_has_no_t_s(tmp_path: Path) -> None:
    write_campaign(small_campaign(times=False), tmp_path / "c.csv")
    assert (tmp_path / "c.csv").read_text().splitlines()[0] == "A_deg,B_deg,rep,point,dev_um"
    assert read_campaign(tmp_path / "c.csv").times_s is None


def test_failed_write_leaves_nothing(tmp_path: Path) -> None:
    c = small_campaign()
    c.deviations[2, 1, 3] = np.nan
    with pytest.raises(InputError):
        write_campaign(c, tmp_path / "c.csv")
    assert list(tmp_path.iterdir()) == []


def test_write_replaces_an_old_file_completely(tmp_path: Path) -> None:
    write_campaign(small_campaign(seed=1), tmp_path / "c.csv")
    write_campaign(small_campaign(times=False, seed=2), tmp_path / "c.csv")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.csv", "c.toml"]
    back = read_campaign(tmp_path / "c.csv")
    np.testing.assert_allclose(back.deviations, small_campaign(seed=2).deviations, atol=5.01e-6)


def test_geometry_overrides_win_over_the_sidecar(tmp_path: Path) -> None:
    c = small_campaign()
    c.geometry = Geometry(pivot_to_ball_mm=100.0, points_per_circle=16)
    write_campaign(c, tmp_path / "c.csv")
    back = read_campaign(tmp_path / "c.csv", {"pivot_to_ball_mm": 90.0, "bore_diameter_mm": 30.0})
    assert back.geometry.pivot_to_ball_mm == 90.0
    assert back.geometry.bore_diameter_mm == 30.0
    assert back.geometry.points_per_circle == 16


# -- files written by another program ---------------------------------------------------------


def _other_program_rows(with_times: bool, one_based: bool) -> tuple[list[str], list[list[object]], np.ndarray]:
    """Rows in a different column order, shuffled, with 1-based rep and point when asked."""
    rng = np.random.default_rng(3)
    orientations = [(0.0, 0.0), (15.0, 20.0), (45.0, -160.0)]
    n_rep, n_pt = 2, 8
    dev = np.round(rng.normal(0, 0.3, (3, n_rep, n_pt)), 4)
    header = ["point", "rep", "dev_um", "B_deg", "A_deg"] + (["t_s"] if with_times else [])
    rows = []
    for o, (a, b) in enumerate(orientations):
        for r in range(n_rep):
            for k in range(n_pt):
                row: list[object] = [k + one_based, r + one_based, dev[o, r, k], b, a]
                if with_times:
                    row.append(((o * n_rep + r) * n_pt + (n_pt - 1 - k)) * 2.0)  # each circle scanned backwards
                rows.append(row)
    order = rng.permutation(len(rows))
    return header, [rows[i] for i in order], dev


@pytest.mark.parametrize("with_times", [True, False])
@pytest.mark.parametrize("one_based", [True, False])
def test_csv_from_another_program_loads_and_inspects(tmp_path: Path, with_times: bool, one_based: bool) -> None:
    header, rows, dev = _other_program_rows(with_times, one_based)
    path = tmp_path / "other.csv"
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\r\n")  # Windows line ends, as a spreadsheet would write
        writer.writerow(header)
        writer.writerows(rows)
    c = read_campaign(path)
    assert c.deviations.shape == (3, 2, 8)
    index = [c.index_of(a, b) for a, b in [(0, 0), (15, 20), (45, -160)]]
    assert sorted(index) == [0, 1, 2]
    np.testing.assert_allclose(c.deviations[index], dev)
    if with_times:
        assert index == [0, 1, 2]  # orientations in the order of their first touch
        # The touch order follows t_s: point 7 first within each circle.
        assert c.touch_order()[0, 0, 7] == 0 and c.touch_order()[0, 0, 0] == 7
    else:
        assert c.times_s is None
    result = run_cli("inspect", str(path), "--json")
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["orientations"] == 3 and summary["repetitions"] == 2 and summary["points"] == 8
    assert summary["has_times"] is with_times
    text = run_cli("inspect", str(path))
    assert text.returncode == 0 and "orientations" in text.stdout


def test_raw_points_without_dev_um_are_fitted(tmp_path: Path) -> None:
    """x_mm, y_mm and no dev_um: deviations come from the LS circle of each repetition."""
    n_pt = 32
    theta = np.radians(point_angles_deg(n_pt))
    form = 0.5 * np.cos(3 * theta) - 0.2 * np.sin(5 * theta)  # um, no harmonic 0 or 1
    lines = ["y_mm,x_mm,rep,A_deg,point,B_deg"]
    for _o, (a, b, cx, cy, radius) in enumerate([(0, 0, 0.3, -0.1, 9.0), (30, 40, -1.2, 2.0, 9.001)]):
        for r in range(2):
            rr = radius + 1e-3 * form
            x = cx + rr * np.cos(theta)
            y = cy + rr * np.sin(theta)
            lines += [f"{y[k]:.9f},{x[k]:.9f},{r},{a},{k},{b}" for k in range(n_pt)]
    (tmp_path / "raw.csv").write_text("\n".join(lines) + "\n")
    c = read_campaign(tmp_path / "raw.csv")
    assert c.deviations.shape == (2, 2, n_pt)
    np.testing.assert_allclose(c.deviations, np.broadcast_to(form, c.deviations.shape), atol=2e-3)
    result = run_cli("inspect", str(tmp_path / "raw.csv"), "--json")
    assert result.returncode == 0, result.stderr


def test_sidecar_toml_from_another_program(tmp_path: Path) -> None:
    write_campaign(small_campaign(), tmp_path / "c.csv")
    (tmp_path / "c.toml").write_text('[geometry]\nbore_diameter_mm = 30\n\n[scenario]\nname = "mine"\ncheck_orientations = [[43, 95]]\n')
    c = read_campaign(tmp_path / "c.csv")
    assert c.geometry.bore_diameter_mm == 30.0 and c.geometry.pivot_to_ball_mm == 80.0
    assert c.scenario == {"name": "mine"}
    np.testing.assert_allclose(c.check_orientations, [[43, 95]])
    assert c.holdout_mask().sum() == 1


# -- bad input: one test each; exit 2, one stderr line naming file, row, column, nothing written ---

GOOD_HEADER = "A_deg,B_deg,rep,point,dev_um"


def good_lines(n_pt: int = 4, reps: int = 2, orientations=((0, 0), (30, 20))) -> list[str]:
    lines = [GOOD_HEADER]
    for a, b in orientations:
        for r in range(reps):
            lines += [f"{a},{b},{r},{k},{0.01 * k:.2f}" for k in range(n_pt)]
    return lines


def assert_one_line_error(path: Path, row: int | None, column: str | None, words: str) -> None:
    before = sorted(p.name for p in path.parent.iterdir())
    result = run_cli("inspect", str(path))
    assert result.returncode == 2, (result.stdout, result.stderr)
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    line = lines[0]
    assert "Traceback" not in result.stderr
    assert str(path) in line
    if row is not None:
        assert f"row {row}" in line, line
    if column is not None:
        assert f"column {column}" in line, line
    assert words in line.lower(), line
    assert sorted(p.name for p in path.parent.iterdir()) == before  # nothing written
    # The library raises the same InputError.
    with pytest.raises(InputError) as info:
        read_campaign(path)
    assert info.value.row == row and info.value.column == column


def write_lines(tmp_path: Path, lines: list[str]) -> Path:
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_missing_column(tmp_path: Path) -> None:
    lines = [line.rsplit(",", 1)[0] for line in good_lines()]  # dev_um dropped
    assert_one_line_error(write_lines(tmp_path, lines), 1, "dev_um", "missing column")


def test_unknown_column(tmp_path: Path) -> None:
    lines = [line + ",1" for line in good_lines()]
    lines[0] = GOOD_HEADER + ",temperature_C"
    assert_one_line_error(write_lines(tmp_path, lines), 1, "temperature_C", "unknown column")


def test_non_numeric_value(tmp_path: Path) -> None:
    lines = good_lines()
    lines[5] = "0,0,1,0,abc"
    assert_one_line_error(write_lines(tmp_path, lines), 6, "dev_um", "not a number")


def test_nan_value(tmp_path: Path) -> None:
    lines = good_lines()
    lines[3] = "0,0,0,2,nan"
    assert_one_line_error(write_lines(tmp_path, lines), 4, "dev_um", "not finite")


def test_inf_value(tmp_path: Path) -> None:
    lines = good_lines()
    lines[7] = "inf,0,1,2,0.1"
    assert_one_line_error(write_lines(tmp_path, lines), 8, "A_deg", "not finite")


def test_duplicate_touch(tmp_path: Path) -> None:
    lines = good_lines()
    lines.append("30,20,1,2,0.5")
    assert_one_line_error(write_lines(tmp_path, lines), len(lines), "point", "duplicate touch")


def test_repetition_with_missing_points(tmp_path: Path) -> None:
    lines = good_lines()
    del lines[11]  # orientation 2, repetition 0, point 2 (file line 12)
    assert_one_line_error(write_lines(tmp_path, lines), 10, "point", "missing point 2")


def test_unequal_point_counts(tmp_path: Path) -> None:
    lines = good_lines(n_pt=4, orientations=((0, 0),)) + good_lines(n_pt=5, orientations=((30, 20), (60, 40)))[1:]
    assert_one_line_error(write_lines(tmp_path, lines), 2, "point", "unequal point counts")


def test_unequal_repetition_counts(tmp_path: Path) -> None:
    lines = good_lines(reps=3, orientations=((0, 0), (15, 0))) + good_lines(reps=2, orientations=((30, 20),))[1:]
    assert_one_line_error(write_lines(tmp_path, lines), 26, "rep", "repetitions")


def test_a_out_of_range(tmp_path: Path) -> None:
    lines = good_lines(orientations=((0, 0), (116, 20)))
    assert_one_line_error(write_lines(tmp_path, lines), 10, "A_deg", "outside [-115, 115]")


def test_b_out_of_range(tmp_path: Path) -> None:
    lines = good_lines(orientations=((0, 0), (30, -181)))
    assert_one_line_error(write_lines(tmp_path, lines), 10, "B_deg", "outside [-180, 180]")


def test_empty_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(b"")
    assert_one_line_error(path, 1, None, "empty file")


def test_header_only_file(tmp_path: Path) -> None:
    assert_one_line_error(write_lines(tmp_path, [GOOD_HEADER]), 2, None, "empty file")


def test_binary_file(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\x00\x00")
    assert_one_line_error(path, 3, None, "not a csv text file")  # the NUL is on line 3


def test_wrong_encoding(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    text = "\n".join(good_lines()) + "\n"
    path.write_bytes(text.encode("ascii") + "0,0,9,0,0.1 # Meßpunkt\n".encode("latin-1"))
    assert_one_line_error(path, 18, None, "not a utf-8 csv text file")


def test_ragged_row(tmp_path: Path) -> None:
    lines = good_lines()
    lines[4] = "0,0,0,3"
    assert_one_line_error(write_lines(tmp_path, lines), 5, "dev_um", "fields where the header has 5")


def test_non_integer_point(tmp_path: Path) -> None:
    lines = good_lines()
    lines[2] = "0,0,0,1.5,0.0"
    assert_one_line_error(write_lines(tmp_path, lines), 3, "point", "must be an integer")


def test_bad_sidecar_names_the_toml_file(tmp_path: Path) -> None:
    path = write_lines(tmp_path, good_lines())
    sidecar_path(path).write_text("[geometry]\npivot_to_ball_mm = 'long'\n")
    result = run_cli("inspect", str(path))
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1
    assert str(sidecar_path(path)) in result.stderr and "pivot_to_ball_mm" in result.stderr


def test_degenerate_raw_points(tmp_path: Path) -> None:
    lines = ["A_deg,B_deg,rep,point,x_mm,y_mm"] + [f"0,0,0,{k},{k},{2 * k}" for k in range(6)]
    assert_one_line_error(write_lines(tmp_path, lines), 2, "x_mm", "do not define a circle")


def test_missing_file(tmp_path: Path) -> None:
    result = run_cli("inspect", str(tmp_path / "nothing.csv"))
    assert result.returncode == 2 and "no such file" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_paper_sized_campaign_round_trip(tmp_path: Path) -> None:
    """127 orientations x 10 repetitions x 64 points (81,280 touches) load back intact."""
    a_values, b_values = np.arange(0, 91, 15.0), np.arange(-160, 181, 20.0)
    orientations = np.array([(a, b) for a in a_values for b in b_values] + [(43.0, 90.0)])
    rng = np.random.default_rng(1)
    c = Campaign(orientations, rng.normal(0, 0.2, (127, 10, 64)), np.arange(127 * 640, dtype=float).reshape(127, 10, 64))
    write_campaign(c, tmp_path / "paper.csv")
    back = read_campaign(tmp_path / "paper.csv")
    assert back.deviations.shape == (127, 10, 64)
    np.testing.assert_allclose(back.deviations, c.deviations, atol=5.01e-6)
    a_grid, b_grid = back.grid()
    assert len(a_grid) == 7 and len(b_grid) == 18
    np.testing.assert_allclose(back.orientations[back.off_grid_mask()], [[43.0, 90.0]])


def test_semicolon_separated_file_gets_a_hint(tmp_path: Path) -> None:
    lines = [line.replace(",", ";") for line in good_lines()]
    with pytest.raises(InputError, match="separated by commas") as info:
        read_campaign(write_lines(tmp_path, lines))
    assert info.value.row == 1


def test_utf16_file_gets_a_hint(tmp_path: Path) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(("\n".join(good_lines()) + "\n").encode("utf-16"))
    with pytest.raises(InputError, match="UTF-16") as info:
        read_campaign(path)
    assert info.value.row == 1
