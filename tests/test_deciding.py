"""Rings that decide (ph_explorer.planning.deciding), the rings file (ph_explorer.io.rings) and the
twin measuring a scenario's head at them (`simulate --rings`). The whole loop over seeds is the
`deciding` benchmark."""

from __future__ import annotations

import numpy as np
import pytest

from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.io import read_campaign
from ph_explorer.io.rings import read_rings, rings_csv_text
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.planning.deciding import DECIDE_A_STEP_DEG, DECIDING_EVIDENCE, DECIDING_RINGS, Evidence, Question, rings_for
from ph_explorer.planning.ring_design import candidate_orientations, distinct_rings
from ph_explorer.twin import load_scenario, simulate
from tests.command_line import run_cli

ANGULAR = DEFAULT_CATALOG["a_axis_cyclic"](amplitude_arcsec=1.5, phase_deg=70.0, cycles_per_rev=26)
# The radial motion that mimics it: the ball's displacement at the stylus length (80 mm x 1.5 arcsec).
RADIAL = DEFAULT_CATALOG["a_axis_radial_motion"](
    y_amplitude_um=0.58, y_phase_deg=70.0, z_amplitude_um=0.3, z_phase_deg=160.0, cycles_per_rev=26
)


@pytest.fixture(scope="module")
def paper():
    """The paper's campaign with its A axis's 26/rev angular error, and the pool of new rings."""
    scenario = load_scenario("paper")
    scenario.effects, scenario.hidden = [*scenario.effects, ANGULAR], [*scenario.hidden, True]
    campaign = simulate(scenario, 5)
    pool = distinct_rings(candidate_orientations(campaign.geometry, a_step_deg=DECIDE_A_STEP_DEG), campaign.orientations)
    pool = pool[pool[:, 0] <= 90.0]
    train = np.concatenate([~campaign.holdout_mask(), np.zeros(len(pool), dtype=bool)])
    weights = OutOfSampleSmoother(np.concatenate([campaign.orientations, pool]), train).weights
    return campaign, pool, weights


def test_an_angular_error_and_the_radial_motion_that_mimics_it_are_decided_by_a_few_rings_none_alone(paper):
    campaign, pool, weights = paper
    evidence = Evidence(Question(ANGULAR, RADIAL), campaign, pool, weights)
    rings, each, without_top = rings_for(evidence, np.ones(len(pool), dtype=bool), 8)
    assert DECIDING_RINGS <= len(rings) <= 8 and len(set(rings)) == len(rings)
    assert without_top >= DECIDING_EVIDENCE and sum(each) - max(each) == pytest.approx(without_top)
    # Fewer rings than a decision needs: none proposed, and what they would show is said.
    rings, each, without_top = rings_for(evidence, np.ones(len(pool), dtype=bool), DECIDING_RINGS - 1)
    assert rings == [] and 0 < without_top < DECIDING_EVIDENCE


def test_an_effect_cannot_be_told_from_itself_so_no_ring_is_proposed(paper):
    campaign, pool, weights = paper
    evidence = Evidence(Question(ANGULAR, ANGULAR), campaign, pool, weights)
    rings, each, without_top = rings_for(evidence, np.ones(len(pool), dtype=bool), 8)
    assert rings == [] and abs(without_top) < 1e-6 * DECIDING_EVIDENCE


def test_a_suggested_candidate_is_confirmed_where_its_term_is_largest_and_its_evidence_grows_as_its_square(paper):
    campaign, pool, weights = paper
    one = Evidence(Question(ANGULAR), campaign, pool, weights)
    twice = Evidence(Question(type(ANGULAR)(**{**ANGULAR.params, "amplitude_arcsec": 3.0})), campaign, pool, weights)
    every = np.arange(len(pool))
    assert np.allclose(twice.per_ring([], every), 4.0 * one.per_ring([], every))
    rings, each, _ = rings_for(one, np.ones(len(pool), dtype=bool), 8)
    assert rings and each[0] == pytest.approx(one.per_ring([], every)[:, 0].max())


def test_the_twin_measures_a_scenarios_head_at_the_rings_of_a_file_after_its_campaign(tmp_path):
    rings = tmp_path / "rings.csv"
    rings.write_text(
        rings_csv_text(
            [
                {"A_deg": 7.5, "B_deg": 20, "order": 1, "reason": "tells a from b: 3, of 9"},
                {"A_deg": 50, "B_deg": -100, "order": 2, "reason": "x"},
            ]
        )
    )
    assert np.allclose(read_rings(rings), [[7.5, 20], [50, -100]])
    result = run_cli("simulate", "--scenario", "head_3", "--rings", rings, "--out", tmp_path / "new.csv")
    assert result.returncode == 0, result.stderr
    new, base = read_campaign(tmp_path / "new.csv"), simulate(load_scenario("head_3"))
    assert np.allclose(new.orientations, [[7.5, 20], [50, -100]]) and new.n_repetitions == base.n_repetitions
    assert np.allclose(new.check_orientations, new.orientations)  # every new ring is a check ring
    assert new.times_s.min() > base.times_s.max()  # measured after the campaign
    # another noise draw than the campaign's: a seed from the scenario's and the rings, said in the line
    assert f"seed {new.scenario['seed']}" in result.stdout and new.scenario["seed"] != base.scenario["seed"]


@pytest.mark.parametrize(
    "text, words",
    [
        ("A,B\n1,2\n", "no A_deg column"),
        ("A_deg,B_deg\n", "no rings"),
        ("A_deg,B_deg\n10,20\n10,x\n", "not a number: 'x'"),
        ("A_deg,B_deg\n10,20\n30,40\n10,20\n", "A10 B20 is listed twice (first on row 2)"),
    ],
)
def test_a_bad_rings_file_is_one_line_naming_its_row_and_column(tmp_path, text, words):
    rings = tmp_path / "rings.csv"
    rings.write_text(text)
    result = run_cli("simulate", "--scenario", "head_3", "--rings", rings, "--out", tmp_path / "new.csv")
    assert result.returncode == 2 and words in result.stderr and "rings.csv" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and not (tmp_path / "new.csv").exists()


def test_rings_are_for_a_scenario(tmp_path):
    result = run_cli("simulate", "--random-head", "3", "--rings", tmp_path / "r.csv", "--out", tmp_path / "new.csv")
    assert result.returncode == 2 and "--rings" in result.stderr and "--scenario" in result.stderr
