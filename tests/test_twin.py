"""Scenarios and simulated campaigns: the paper's figures, the teaching scenarios, the CLI."""

from __future__ import annotations

import numpy as np
import pytest
from command_line import run_cli  # in this process: the real process's start is tests/test_cli.py's

from ph_explorer.campaign import orientation_match
from ph_explorer.cli.simulate_command import simulate_command
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.errors import InputError
from ph_explorer.io import read_campaign
from ph_explorer.metrics import noise_floor
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.paths import assets_dir
from ph_explorer.twin import list_scenarios, load_scenario, scenario_from_dict, simulate

SIGMA = 0.175
FLOOR = noise_floor(SIGMA, 10)  # {"mean": 0.044, "single": 0.140} um
TEACHING = ("head_3", "head_5", "head_4")


def check_ring_errors(name: str) -> dict[str, np.ndarray]:
    """A plain interpolator (trilinear over the nominal grid) trained without the check rings."""
    campaign = simulate(load_scenario(name))
    held = campaign.holdout_mask()
    model = TrilinearModel().fit(campaign, ~held)
    measured = campaign.deviations[held]
    predicted = model.predict(campaign.orientations[held])
    return {
        "mean": np.abs(predicted - measured.mean(axis=1)).mean(axis=1),
        "single": np.abs(predicted[:, None] - measured).mean(axis=(1, 2)),
        "curves": measured.mean(axis=1),
    }


@pytest.fixture(scope="module")
def paper():
    return simulate(load_scenario("paper"))


def test_paper_scenario_has_the_papers_setting(paper):
    assert paper.deviations.shape == (135, 10, 64) and paper.times_s.shape == paper.deviations.shape
    assert (~paper.off_grid_mask()).sum() == 126
    checks = paper.check_orientations
    for ring in ([15, -20], [75, 40], [45, -20], [43, 90]):
        assert orientation_match(checks, [ring]).any()
    off_grid_checks = paper.off_grid_mask()[paper.holdout_mask()].sum()
    assert off_grid_checks >= 7
    assert paper.scenario["hidden"] == []
    assert paper.noise_sigma_um() == pytest.approx(SIGMA, rel=0.05)


def test_paper_check_rings_fall_in_the_papers_ranges(paper):
    curves = paper.deviations[paper.holdout_mask()].mean(axis=1)
    ranges, peaks = np.ptp(curves, axis=1), np.abs(curves).max(axis=1)
    assert np.all((ranges >= 0.5) & (ranges <= 1.3)), ranges
    assert np.all((peaks >= 0.25) & (peaks <= 0.8)), peaks


def test_paper_curves_change_with_b0_as_well_as_a0():
    data = load_scenario("paper")
    data.effects = [e for e in data.effects if e.id != "noise"]
    data.repetitions = 1
    curves = simulate(data).deviations[:126, 0].reshape(7, 18, 64)  # (A0, B0, point), noise-free
    b_part = curves - curves.mean(axis=1, keepdims=True)
    assert np.abs(b_part[0]).max() < 1e-9  # at A0 = 0 no B error reaches the ring
    for row in range(1, 7):
        assert np.sqrt(np.mean(b_part[row] ** 2)) > 0.2 * np.sqrt(np.mean(curves[row] ** 2))
    a_part = curves.mean(axis=1)
    assert np.sqrt(np.mean((a_part[2:] - a_part[-1]) ** 2)) > 0.02  # and with A0 beyond the lobing onset


def test_plain_interpolator_stays_near_the_floor_on_the_paper_scenario():
    errors = check_ring_errors("paper")
    assert errors["mean"].mean() <= 1.5 * FLOOR["mean"], errors["mean"]
    assert np.all((errors["single"] >= 0.08) & (errors["single"] <= 0.22)), errors["single"]


@pytest.mark.parametrize("name", ["head_3", "head_4"])
def test_plain_interpolator_misses_a_hidden_axis_error(name):
    scenario = load_scenario(name)
    hidden = [e for e, h in zip(scenario.effects, scenario.hidden) if h]
    assert len(hidden) == 1 and scenario.hidden_ids == [hidden[0].id]
    # The starting model has low-order terms of the same axis, never the hidden short period.
    same_axis = [e.params["cycles_per_rev"] for e in scenario.starting_effects if e.id == hidden[0].id]
    assert same_axis and max(same_axis) <= 4 < hidden[0].params["cycles_per_rev"]
    errors = check_ring_errors(name)
    assert errors["mean"].mean() >= 2.0 * FLOOR["mean"], errors["mean"]


def test_plain_interpolator_misses_lost_motion_that_alternates_between_repetitions():
    scenario = load_scenario("head_5")
    assert scenario.hidden_ids == ["direction"] and scenario.scan_direction == "alternating"
    errors = check_ring_errors("head_5")
    assert errors["single"].mean() >= 1.3 * FLOOR["single"], errors["single"]
    # The mean of 10 repetitions averages the two scan directions: there it stays near the floor.
    assert errors["mean"].mean() <= 1.5 * FLOOR["mean"]


def test_head_4_is_aliased_on_the_grid():
    errors = check_ring_errors("head_4")
    campaign = simulate(load_scenario("head_4"))
    off = campaign.off_grid_mask()[campaign.holdout_mask()]
    # Every grid ring sees the 15-deg error at the same phase: held-out grid rings are predicted well.
    assert errors["mean"][~off].mean() < 1.6 * FLOOR["mean"]
    assert errors["mean"][off].mean() > 2.5 * FLOOR["mean"]


def test_scan_times_follow_order_and_direction():
    scenario = load_scenario("head_5")
    t = scenario.times_s()
    assert np.all(np.diff(t[:, 0], axis=-1) == pytest.approx(scenario.touch_s))
    assert np.all(np.diff(t[:, 1], axis=-1) == pytest.approx(-scenario.touch_s))
    assert np.unique(t).size == t.size
    by_ring = np.sort(t.reshape(len(t), -1), axis=1)
    assert np.all(by_ring[1:, 0] > by_ring[:-1, -1])  # orientation by orientation


def test_same_seed_same_campaign_other_seed_other_noise():
    scenario = load_scenario("head_3")
    a, b, c = simulate(scenario), simulate(scenario), simulate(scenario, seed=scenario.seed + 1)
    assert np.array_equal(a.deviations, b.deviations)
    assert not np.array_equal(a.deviations, c.deviations)
    # The systematic part does not depend on the seed.
    assert np.abs(a.deviations.mean(axis=1) - c.deviations.mean(axis=1)).mean() < 0.08


def test_scenario_errors_are_input_errors(tmp_path):
    base = {"orientations": {"a_deg": [0, 30, 15], "b_deg": [0, 40, 20]}, "effects": [{"id": "noise"}]}
    scenario_from_dict(base)
    with pytest.raises(InputError, match="not measured"):
        scenario_from_dict({**base, "check_orientations": [[10, 10]]})
    with pytest.raises(InputError, match="unknown effect"):
        scenario_from_dict({**base, "effects": [{"id": "wobble"}]})
    with pytest.raises(InputError, match="scan.direction"):
        scenario_from_dict({**base, "scan": {"direction": "sideways"}})
    with pytest.raises(InputError, match="unknown key"):
        scenario_from_dict({**base, "colour": "red"})
    with pytest.raises(InputError, match="unknown scenario"):
        load_scenario("no_such_scenario")
    bad = tmp_path / "bad.toml"
    bad.write_text("name = [\n")
    with pytest.raises(InputError, match="TOML"):
        load_scenario(bad)


def test_scenario_from_a_user_path_with_a_user_effect(tmp_path):
    path = tmp_path / "mine.toml"
    path.write_text(
        'name = "mine"\ndescription = "ball form only"\nseed = 3\nrepetitions = 2\n'
        "[orientations]\na_deg = [0, 90, 45]\nb_deg = [0, 90, 90]\n"
        '[[effects]]\nid = "my_ball_form"\namplitude_um = 0.1\n'
    )
    # The user's effect is known only to the catalog that was given its file.
    with pytest.raises(InputError, match="unknown effect 'my_ball_form'"):
        load_scenario(path)
    catalog = DEFAULT_CATALOG.with_file(assets_dir() / "effects_example.py")
    campaign = simulate(load_scenario(path, catalog=catalog))
    assert campaign.deviations.shape == (6, 2, 64)
    assert np.abs(campaign.deviations[:2]).max() < 1e-12  # A0 = 0: fixed in the probe frame, psi constant
    assert np.ptp(campaign.deviations[4:], axis=-1).min() > 0.15


def test_list_scenarios_describes_every_shipped_scenario():
    shipped = {s.name: s for s in list_scenarios()}
    assert {"paper", *TEACHING} <= set(shipped)
    assert all(s.description and "\n" not in s.description for s in shipped.values())
    # The explorer's list shows each one's purpose: short, and nothing of what is hidden in it
    # (neither the hidden effect's id nor a word of its name or id, such as "axis" or "cyclic").
    for s in shipped.values():
        assert 10 <= len(s.purpose) <= 60, (s.name, s.purpose)
        hidden = [e for e, h in zip(s.effects, s.hidden) if h]
        words = {w.lower() for e in hidden for w in [*e.id.split("_"), *e.name.replace("-", " ").split()] if len(w) > 3}
        assert not words & set(s.purpose.lower().replace(";", " ").replace("?", " ").split()), (s.name, s.purpose, words)


def test_simulate_command_writes_campaign_and_sidecar(tmp_path, capsys):
    out = tmp_path / "a.csv"
    assert simulate_command(scenario="head_3", out=out, seed=5) == 0
    campaign = read_campaign(out)
    assert campaign.scenario["name"] == "head_3" and campaign.scenario["seed"] == 5
    assert campaign.scenario["hidden"] == ["b_axis_cyclic"]
    assert len(campaign.check_orientations) == 12 and campaign.times_s is not None
    assert capsys.readouterr().out.startswith(f"{out}: scenario head_3, seed 5, 135 orientations")
    with pytest.raises(InputError) as info:
        simulate_command(scenario=None, out=out)
    assert info.value.option == "--scenario" and "option --scenario" in info.value.line()


def test_simulate_cli_is_byte_identical_and_lists(tmp_path):
    first, second = tmp_path / "one.csv", tmp_path / "two.csv"
    for path in (first, second):
        done = run_cli("simulate", "--scenario", "paper", "--out", str(path), "--seed", "7")
        assert done.returncode == 0, done.stderr
    assert first.read_bytes() == second.read_bytes()
    assert first.with_suffix(".toml").read_bytes() == second.with_suffix(".toml").read_bytes()
    listed = run_cli("simulate", "--list")
    assert listed.returncode == 0
    lines = listed.stdout.strip().splitlines()
    assert len(lines) == len(list_scenarios()) and any(line.startswith("paper ") for line in lines)
    unknown = run_cli("simulate", "--scenario", "nope", "--out", str(tmp_path / "x.csv"))
    assert unknown.returncode == 2 and len(unknown.stderr.strip().splitlines()) == 1
