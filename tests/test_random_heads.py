"""A population of heads: random healthy heads from documented distributions, one hidden effect at
a known strength, and the verdicts that must hold on them (ph_explorer.twin.random_heads,
ph_explorer.diagnosis.detection)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy import stats

from ph_explorer.diagnosis import diagnose
from ph_explorer.diagnosis.detection import head_with_effect
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.io import read_campaign
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.hybrid import fitted_basis
from ph_explorer.twin.random_heads import DESIGNS, random_campaign, random_head
from tests.command_line import run_cli


def test_a_seed_is_a_head_and_every_background_term_is_plausible():
    first, again = random_campaign(11, "paper"), random_campaign(11, "paper")
    assert np.array_equal(first.deviations, again.deviations)
    assert not np.allclose(first.deviations, random_campaign(12, "paper").deviations)
    for seed in range(40):
        scenario = random_head(seed)
        assert not any(scenario.hidden)
        for effect in scenario.effects:
            assert not effect.implausible(effect.params), (seed, effect.describe())
        noise = scenario.effects[0].params
        assert 0.1 <= noise["sigma_um"] <= 0.3 and noise["dof"] in (0, 3, 4, 5)


@pytest.mark.parametrize("design", sorted(DESIGNS))
def test_each_design_gives_its_campaign(design):
    campaign = random_campaign(5, design)
    recipe = DESIGNS[design]
    assert campaign.n_repetitions == recipe["repetitions"]
    assert (campaign.times_s is not None) == recipe["times"]
    assert len(campaign.check_orientations) == len(recipe["check_orientations"])
    assert campaign.n_points == recipe.get("geometry", {}).get("points_per_circle", 64)


def test_student_t_noise_has_the_same_sigma_and_heavier_tails():
    gaussian, heavy = (DEFAULT_CATALOG["noise"](sigma_um=0.2, dof=dof) for dof in (0, 3.5))
    touches = campaign_touches(random_campaign(1, "paper"))
    a, b = (effect.forward(touches, np.random.default_rng(0)).ravel() for effect in (gaussian, heavy))
    assert abs(a.std() - 0.2) < 0.005 and abs(b.std() - 0.2) < 0.02
    assert stats.kurtosis(b) > 1.0 > abs(stats.kurtosis(a))


def test_a_hidden_effect_scales_with_its_strength_and_is_recorded_as_hidden():
    heads = [head_with_effect(21, "b_axis_cyclic", strength, "paper") for strength in (1.0, 2.0)]
    hidden = [[e for e in campaign.scenario["effects"] if e["hidden"]] for campaign, _ in heads]
    assert [len(h) for h in hidden] == [1, 1] and hidden[0][0]["id"] == "b_axis_cyclic"
    assert hidden[1][0]["amplitude_arcsec"] == pytest.approx(2.0 * hidden[0][0]["amplitude_arcsec"])
    assert heads[0][0].scenario["hidden"] == ["b_axis_cyclic"]


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (["--random-head", "x"], "--random-head"),
        (["--random-head", "3", "--design", "nope"], "--design"),
        (["--random-head", "3", "--hidden-effect", "wobble"], "--hidden-effect"),
        (["--random-head", "3", "--hidden-effect", "b_axis_cyclic", "--strength", "big"], "--strength"),
        (["--random-head", "3", "--strength", "2"], "--strength"),
        (["--design", "paper"], "--design"),
    ],
)
def test_bad_random_head_options_are_one_line_and_write_nothing(tmp_path, args, option):
    out = tmp_path / "head.csv"
    result = run_cli("simulate", *args, "--out", str(out))
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and option in lines[0]
    assert not list(tmp_path.iterdir())


def test_the_command_writes_a_random_head_without_naming_its_hidden_effect(tmp_path):
    out = tmp_path / "head.csv"
    result = run_cli("simulate", "--random-head", "4", "--design", "no_times", "--hidden-effect", "b_axis_cyclic", "--out", str(out))
    assert result.returncode == 0, result.stderr
    assert "hidden effects: 1" in result.stdout and "b_axis_cyclic" not in result.stdout
    campaign = read_campaign(out)
    assert campaign.times_s is None and campaign.scenario["hidden"] == ["b_axis_cyclic"]


def test_a_catalog_effect_most_rings_see_is_claimed_and_what_it_leaves_is_judged_as_the_healthy_head_was():
    """One yardstick: the head without the effect is called none; with it, the effect is found and
    what it leaves (the same background and noise) is within noise again: missing, not partial."""
    healthy = diagnose(random_campaign(7, "paper"), nested=False)
    assert healthy.verdict == "none"
    campaign, _ = head_with_effect(7, "b_axis_cyclic", 2.0, "paper")
    truth = next(e for e in campaign.scenario["effects"] if e["hidden"])
    result = diagnose(campaign, nested=False)
    assert result.verdict == "missing" and not result.within_noise["after"].fails
    found = result.found[0]
    assert (found.effect, found.settings["cycles_per_rev"]) == ("b_axis_cyclic", truth["cycles_per_rev"])
    assert found.replication.replicated and found.replication.rings_gaining > found.replication.rings / 2


def test_one_deviant_ring_on_a_healthy_head_is_no_claim():
    """A check ring that alone shows a catalog effect's curve, at many times its noise, claims nothing."""
    healthy = random_campaign(2, "paper")
    ring = int(np.flatnonzero(healthy.holdout_mask())[4])
    effect = DEFAULT_CATALOG["b_axis_cyclic"]().with_settings(cycles_per_rev=22)
    column = fitted_basis(effect, campaign_touches(healthy))[0][ring].sum(axis=-1)
    deviations = healthy.deviations.copy()
    deviations[ring] += remove_size_and_centre(3.0 * column)
    result = diagnose(dataclasses.replace(healthy, deviations=deviations), nested=False)
    assert result.verdict != "missing" and not result.found
    assert result.verdict == "none" or result.failing[ring]
