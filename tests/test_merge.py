"""`ph-explorer merge`: new rings appended to a campaign, refused in one line when they conflict
(ph_explorer.io.merge)."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ph_explorer.io import read_campaign, write_campaign
from ph_explorer.twin.random_heads import random_campaign
from tests.command_line import run_cli


@pytest.fixture(scope="module")
def head():
    return random_campaign(3, "coarse")


def written(tmp_path, name, campaign):
    return write_campaign(campaign, tmp_path / f"{name}.csv")


def test_new_rings_are_appended_after_the_base_in_time(tmp_path, head):
    base, new = written(tmp_path, "base", head.subset(np.arange(30))), written(tmp_path, "new", head.subset(np.arange(30, 40)))
    result = run_cli("merge", base, new, "--out", tmp_path / "all.csv", "--json")
    assert result.returncode == 0, result.stderr
    merged, original = read_campaign(tmp_path / "all.csv"), read_campaign(base)
    assert merged.n_orientations == 40
    assert np.allclose(merged.orientations, head.orientations[:40])
    assert np.allclose(merged.deviations, np.concatenate([original.deviations, read_campaign(new).deviations]))
    # the new touches begin after the base's last one, in their own order
    assert merged.times_s[30:].min() > merged.times_s[:30].max()
    assert np.allclose(np.diff(merged.times_s[30:].ravel()), np.diff(read_campaign(new).times_s.ravel()), atol=2e-3)
    record = merged.scenario["merges"][-1]
    assert len(record["added"]) == 10 and record["replaced"] == [] and record["added_from"].endswith("new.csv")
    assert merged.scenario["hidden"] == head.scenario["hidden"]  # the twin's record (and its Reveal) kept


def test_a_ring_measured_twice_is_refused_unless_replace(tmp_path, head):
    base, new = written(tmp_path, "base", head.subset(np.arange(30))), written(tmp_path, "new", head.subset(np.arange(25, 35)))
    out = tmp_path / "all.csv"
    result = run_cli("merge", base, new, "--out", out)
    assert result.returncode == 2 and "5 ring(s) measured twice" in result.stderr and "--replace" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not out.exists() and not out.with_suffix(".toml").exists()
    result = run_cli("merge", base, new, "--out", out, "--replace")
    assert result.returncode == 0, result.stderr
    merged = read_campaign(out)
    assert merged.n_orientations == 35 and len(merged.scenario["merges"][-1]["replaced"]) == 5


@pytest.mark.parametrize(
    "change, words",
    [
        (lambda c: dataclasses.replace(c, geometry=dataclasses.replace(c.geometry, pivot_to_ball_mm=100.0)), "pivot_to_ball_mm is 100"),
        (lambda c: dataclasses.replace(c, deviations=c.deviations[:, :3], times_s=c.times_s[:, :3]), "repetitions here"),
        (lambda c: dataclasses.replace(c, times_s=None), "has touch times"),
        (
            lambda c: dataclasses.replace(
                c,
                deviations=c.deviations[..., ::2],
                times_s=c.times_s[..., ::2],
                geometry=dataclasses.replace(c.geometry, points_per_circle=c.n_points // 2),
            ),
            "points per circle here",
        ),
    ],
    ids=["geometry", "repetitions", "times", "points"],
)
def test_another_set_up_is_refused_in_one_line_and_nothing_is_written(tmp_path, head, change, words):
    base = written(tmp_path, "base", head.subset(np.arange(30)))
    new = written(tmp_path, "new", change(head.subset(np.arange(30, 40))))
    out = tmp_path / "all.csv"
    result = run_cli("merge", base, new, "--out", out)
    assert result.returncode == 2 and words in result.stderr and "new.csv" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not out.exists()


def test_the_merge_never_writes_over_an_input(tmp_path, head):
    base, new = written(tmp_path, "base", head.subset(np.arange(30))), written(tmp_path, "new", head.subset(np.arange(30, 40)))
    before = base.read_bytes()
    result = run_cli("merge", base, new, "--out", base)
    assert result.returncode == 2 and "--out" in result.stderr and base.read_bytes() == before


def test_a_study_continues_on_its_campaign_merged_with_new_rings_and_records_them(tmp_path, head):
    n = head.n_orientations
    later = np.arange(n) // 6 == 2  # six lattice rings measured after the others
    base, new = written(tmp_path, "base", head.subset(~later)), written(tmp_path, "new", head.subset(later))
    study = tmp_path / "study.json"
    assert run_cli("diagnose", "--data", base, "--save", study, "--json").returncode == 0
    assert run_cli("merge", base, new, "--out", tmp_path / "all.csv").returncode == 0
    result = run_cli("diagnose", "--data", tmp_path / "all.csv", "--resume", study, "--json")
    assert result.returncode == 0, result.stderr
    saved = json.loads(study.read_text())
    added = saved["runs"][-1]["rings_added"]
    assert len(added) == 1 and len(added[0]["added"]) == 6 and added[0]["from"].endswith("new.csv")
    assert saved["campaign"]["orientations"] == n and "rings_added" not in saved["runs"][0]
    # Another campaign is still refused, in one line.
    other = written(tmp_path, "other", random_campaign(4, "coarse"))
    refused = run_cli("diagnose", "--data", other, "--resume", study)
    assert refused.returncode == 2 and "nor on a campaign merged from it" in refused.stderr


def test_new_rings_off_the_lattice_join_the_base_check_rings_when_the_new_file_names_none(head):
    from ph_explorer.io.merge import merged_campaign

    assert head.check_orientations is not None and len(head.check_orientations)
    lattice = ~head.off_grid_mask()
    base = head.subset(np.flatnonzero(lattice)[:-2])
    # two lattice rings the base lacks and one ring off the lattice, in a file that names no check rings
    off = dataclasses.replace(head.subset([0]), orientations=head.orientations[[0]] + [[2.5, 7.0]])
    new = dataclasses.replace(head.subset(np.flatnonzero(lattice)[-2:]), check_orientations=None)
    both = dataclasses.replace(
        new,
        orientations=np.concatenate([new.orientations, off.orientations]),
        deviations=np.concatenate([new.deviations, off.deviations]),
        times_s=np.concatenate([new.times_s, off.times_s]),
    )
    merged, _ = merged_campaign(base, both)
    held = merged.holdout_mask()
    assert held[-1] and not held[-3:-1].any()  # the ring off the lattice is a check ring, the lattice ones train
    assert held[: base.n_orientations].sum() == base.holdout_mask().sum()


def test_a_campaign_made_in_memory_is_named_by_what_it_is_in_a_refusal(head):
    from ph_explorer.errors import InputError
    from ph_explorer.io.merge import merged_campaign

    base = dataclasses.replace(head.subset([0, 1]), source=None)  # a merge, or the twin's rings
    with pytest.raises(InputError, match="already in the base campaign:") as refused:
        merged_campaign(base, dataclasses.replace(head.subset([1]), source=None))
    assert "None" not in str(refused.value)
