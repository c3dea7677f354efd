"""Rings that decide (ph_explorer.planning.deciding), the rings file (ph_explorer.io.rings) and the
twin measuring a scenario's head at them (`simulate --rings`). The whole loop over seeds is the
`deciding` benchmark."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.geometry import stylus_direction
from ph_explorer.io import read_campaign
from ph_explorer.io.rings import read_rings, rings_csv_text
from ph_explorer.io.writer import write_campaign
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.planning.deciding import DECIDE_A_STEP_DEG, DECIDING_POWER, DECIDING_RINGS, rings_for, rings_needed
from ph_explorer.planning.ring_design import candidate_orientations, distinct_rings, on_measured_side
from ph_explorer.planning.ring_evidence import Evidence, Question, decision_power, one_sided, scatter_ratio, spectral_products
from ph_explorer.twin import load_scenario, simulate, twin_scenario
from ph_explorer.twin.random_heads import random_campaign, random_head
from tests.command_line import run_cli
from tests.synthetic import mirrored, mirrored_campaign

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
    before = decision_power(*evidence.every_ring([]))
    rings, each, power = rings_for(evidence, np.ones(len(pool), dtype=bool), 8)
    assert DECIDING_RINGS <= len(rings) <= 8 and len(set(rings)) == len(rings)
    assert power >= DECIDING_POWER > before and len(each) == len(rings)
    # How many would, counted without proposing them: as many as rings_for takes; none within too few.
    assert rings_needed(evidence, np.ones(len(pool), dtype=bool), 3 * 8) == len(rings)
    assert rings_needed(evidence, np.ones(len(pool), dtype=bool), len(rings) - 1) is None
    # Fewer rings than a decision needs: none proposed, and the power they would reach is said.
    rings, each, power = rings_for(evidence, np.ones(len(pool), dtype=bool), DECIDING_RINGS - 1)
    assert rings == [] and power < DECIDING_POWER


def test_rings_equal_to_rounding_are_chosen_the_same_whatever_the_last_digits(paper):
    """An A-axis pair does not see a turn of B: rings at one A tie, and the choice among them must
    not hang on the BLAS's last digits (it did: another numpy wheel proposed other rings)."""
    campaign, pool, weights = paper
    evidence = Evidence(Question(ANGULAR, RADIAL), campaign, pool, weights)
    exact = evidence.per_ring
    chosen = rings_for(evidence, np.ones(len(pool), dtype=bool), 8)[0]
    for seed in range(3):
        jitter = np.random.default_rng(seed)
        evidence.per_ring = lambda rings, extra: exact(rings, extra) * (1.0 + 1e-12 * jitter.standard_normal((len(extra), 1)))
        assert rings_for(evidence, np.ones(len(pool), dtype=bool), 8)[0] == chosen


def test_the_power_is_the_diagnosis_test_over_rings_on_the_expected_gains():
    check = np.array([True] * 6 + [False] * 6)
    assert decision_power(np.zeros(12), check) == 0.0  # nothing to see: never passes
    assert decision_power(np.full(12, 400.0), check) == 1.0  # every ring far beyond its scatter
    # One ring carrying it all never decides: the test must hold without its most influential ring.
    assert decision_power(np.r_[1e4, np.zeros(11)], check) == 0.0


def white(campaign, times: float = 1.0) -> np.ndarray:
    """The spectrum of white noise of `times` the variance of a repetition mean's touch noise."""
    return times * one_sided(campaign.n_points) * campaign.noise_sigma_um() ** 2 / campaign.n_repetitions / campaign.n_points


def test_the_residuals_spectrum_weighs_a_rings_harmonics_as_its_covariance_does():
    rng = np.random.default_rng(3)
    columns, signal = rng.standard_normal((4, 64, 2)), rng.standard_normal((4, 64))
    flat = 0.3 * one_sided(64) / 64  # white noise of variance 0.3 per touch: 0.3 x the plain products (Parseval)
    gram, cross, energy = spectral_products(columns, signal, flat)
    assert np.allclose(gram, 0.3 * np.einsum("opi,opj->oij", columns, columns))
    assert np.allclose(cross, 0.3 * np.einsum("opi,op->oi", columns, signal))
    assert np.allclose(energy, 0.3 * (signal**2).sum(axis=1))
    # A residual of five lobes alone: a five-lobe difference meets it, a seven-lobe one does not.
    theta = 2 * np.pi * np.arange(64) / 64
    five = np.zeros(33)
    five[5] = 1.0
    lobes = np.stack([np.cos(5 * theta), np.cos(7 * theta)])
    assert spectral_products(lobes[..., None], lobes, five)[2] == pytest.approx([32.0**2, 0.0], abs=1e-9)


def test_a_rings_gain_scatters_with_what_the_model_leaves_there_and_more_rings_are_needed(paper):
    """The gain of X over Y at a ring is its evidence g plus twice its product with what the model
    leaves there. The touch noise of a repetition mean alone gives the variance 4 g; a residual
    three times that noise's variance, 12 g, and the same rings decide less often."""
    campaign, pool, weights = paper
    plain = Evidence(Question(ANGULAR, RADIAL), campaign, pool, weights)
    noise = Evidence(Question(ANGULAR, RADIAL), campaign, pool, weights, white(campaign))
    rough = Evidence(Question(ANGULAR, RADIAL), campaign, pool, weights, white(campaign, 3.0))
    rings, _, power = rings_for(plain, np.ones(len(pool), dtype=bool), 8)
    gains, check, scatter = noise.every_ring(rings)
    assert plain.every_ring(rings)[2] is None and np.allclose(gains, plain.every_ring(rings)[0])
    assert np.allclose(scatter, 4.0 * gains) and scatter_ratio(gains, scatter) == pytest.approx(1.0)
    assert decision_power(gains, check, scatter) == power
    gains, check, scatter = rough.every_ring(rings)
    assert np.allclose(scatter, 12.0 * gains) and scatter_ratio(gains, scatter) == pytest.approx(3.0)
    assert decision_power(gains, check, scatter) < power
    more, _, reached = rings_for(rough, np.ones(len(pool), dtype=bool), 8)
    assert (len(more) > len(rings) and reached >= DECIDING_POWER) or (more == [] and reached < DECIDING_POWER)


def test_an_effect_cannot_be_told_from_itself_so_no_ring_is_proposed(paper):
    campaign, pool, weights = paper
    evidence = Evidence(Question(ANGULAR, ANGULAR), campaign, pool, weights)
    rings, each, power = rings_for(evidence, np.ones(len(pool), dtype=bool), 8)
    assert rings == [] and power == 0.0 and max(abs(v) for v in each) < 1e-6


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


def test_design_decide_names_the_rings_that_decide_head_6_and_writes_them_for_a_cmm(tmp_path):
    """head_6's A-axis pair: its gains scatter more than the touch noise alone would make them (what
    the model leaves at its check rings), so the default six rings do not decide it and the command
    says so; ten do, and are written for a CMM."""
    campaign = tmp_path / "head_6.csv"
    assert run_cli("simulate", "--scenario", "head_6", "--out", campaign).returncode == 0
    said = run_cli("design", "--data", campaign, "--decide", "--out", tmp_path / "six.csv")  # no ring: no file, and it says so
    assert said.returncode == 0 and said.stdout.rstrip().endswith(f"No ring to measure: {tmp_path / 'six.csv'} not written.")
    assert not (tmp_path / "six.csv").exists()
    result = run_cli("design", "--data", campaign, "--decide", "--json")
    assert result.returncode == 0, result.stderr
    expected = json.loads(result.stdout)["expected"]["a_axis_cyclic vs a_axis_radial_motion"]
    assert not expected["decided_by_rings"] and expected["power"] < DECIDING_POWER and expected["scatter"] > 1.5
    assert expected["pair"]  # its words say "decide", not "confirm" (figures.decision_text)
    result = run_cli("design", "--data", campaign, "--decide", "--budget", "10", "--out", tmp_path / "rings.csv", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["questions"] == ["a_axis_cyclic vs a_axis_radial_motion"] and report["verdict"] == "missing"
    expected = report["expected"]["a_axis_cyclic vs a_axis_radial_motion"]
    assert expected["decided_by_rings"] and expected["power"] >= DECIDING_POWER and expected["shared_now"] > 0.99
    assert 6 < len(report["rings"]) <= 10 and report["minutes"] > 0
    assert [r["order"] for r in report["rings"]] == list(range(1, len(report["rings"]) + 1))
    written = read_rings(tmp_path / "rings.csv")
    assert np.allclose(written, [[r["A_deg"], r["B_deg"]] for r in report["rings"]])
    # The same rings in space, the same touches, labelled at (-A0, B0 + 180) (point k is then the
    # point at k + N/2): the same answer, its rings proposed on that side (before: a failure).
    write_campaign(mirrored_campaign(read_campaign(campaign)), tmp_path / "mirrored.csv")
    result = run_cli("design", "--data", tmp_path / "mirrored.csv", "--decide", "--budget", "10", "--json")
    assert result.returncode == 0, result.stderr
    again = json.loads(result.stdout)
    assert again["verdict"] == report["verdict"] and again["expected"] == report["expected"]
    assert [(r["expected_gain"], r["question"]) for r in again["rings"]] == [(r["expected_gain"], r["question"]) for r in report["rings"]]
    np.testing.assert_allclose([[r["A_deg"], r["B_deg"]] for r in again["rings"]], mirrored(written), atol=1e-9)


@pytest.mark.parametrize(
    "args, words",
    [
        (("--decide",), "--data FILE.csv"),
        (("--budget", "3", "--study", "s.json"), "--decide"),
        (("--budget", "3", "--out", "r.csv"), "--decide"),
    ],
)
def test_design_decide_options_out_of_place_are_one_line(args, words):
    result = run_cli("design", *args)
    assert result.returncode == 2 and words in result.stderr and len(result.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(
    "make", [lambda: random_campaign(3), lambda: simulate(load_scenario("head_6"), 11)], ids=["random head", "scenario"]
)
def test_the_twin_of_a_simulated_campaign_is_its_head_so_it_can_measure_more_rings_of_it(make):
    campaign = make()
    head = twin_scenario(campaign)
    assert head is not None and head.seed == campaign.scenario["seed"]
    again = simulate(head)  # the same head, the same draw: the same campaign, to the last digit
    assert np.array_equal(again.deviations, campaign.deviations) and np.array_equal(again.orientations, campaign.orientations)
    assert head.hidden_ids == campaign.scenario["hidden"]
    # Measured data (no scenario recorded) has no twin.
    assert twin_scenario(dataclasses.replace(campaign, scenario={})) is None


def test_the_report_lists_the_rings_that_would_decide_without_naming_a_teaching_scenarios_effects():
    from ph_explorer.figures.diagnosis_report import EffectNames, decision_section

    campaign = simulate(load_scenario("head_6"))
    decision = {
        "rings": [
            {
                "A_deg": 10.0,
                "B_deg": -20.0,
                "order": 1,
                "reason": "tells a_axis_cyclic from a_axis_radial_motion: evidence 19 of the set's 57",
            }
        ],
        "expected": {
            "a_axis_cyclic vs a_axis_radial_motion": {"decided_by_rings": True, "power": 0.97},
            "b_axis_cyclic": {"decided_by_rings": False, "power": 0.4},
        },
        "minutes": 68.0,
        "questions": ["a_axis_cyclic vs a_axis_radial_motion", "b_axis_cyclic"],
        "note": "",
    }
    teaching = "".join(decision_section(decision, EffectNames(campaign, DEFAULT_CATALOG, reveal=False)))
    assert "A10 B-20" in teaching and "68 minutes" in teaching and "power 40 %" in teaching
    assert "a_axis" not in teaching and "b_axis" not in teaching and "effect A" in teaching
    revealed = "".join(decision_section(decision, EffectNames(campaign, DEFAULT_CATALOG, reveal=True)))
    assert "tells a_axis_cyclic from a_axis_radial_motion" in revealed


def test_a_campaign_measured_at_negative_a_is_offered_the_same_rings_in_space_on_its_own_side():
    """The ring at (A0, B0) is the ring at (-A0, B0 + 180): a campaign measured at negative A0 gets
    the candidates a positive one gets, mirrored to its side; a positive one's are as before (A0 = 0
    to its largest A0)."""
    candidates = candidate_orientations(a_step_deg=DECIDE_A_STEP_DEG)
    paper = load_scenario("paper").orientations
    positive = on_measured_side(candidates, paper)
    assert np.array_equal(positive, candidates[candidates[:, 0] <= paper[:, 0].max()])
    negative = on_measured_side(candidates, mirrored(paper))
    assert len(negative) == len(positive) and (negative[:, 0] <= 0.0).all()
    # The same stylus directions, ring for ring in the same order: the same rings in space.
    np.testing.assert_allclose(
        stylus_direction(negative[:, 0], negative[:, 1]), stylus_direction(positive[:, 0], positive[:, 1]), atol=1e-12
    )


def test_one_repetition_is_said_in_the_verdict_and_no_ring_is_weighed_against_noise_it_does_not_show(tmp_path):
    """One repetition per ring has no repetition spread: the verdict line says nothing is tested
    against noise (not 'within noise'), and the rings that decide say why they weigh nothing
    (before: an IndexError on the evidence's NaN)."""
    radial = DEFAULT_CATALOG["a_axis_radial_motion"](
        y_amplitude_um=-1.17, y_phase_deg=170.6, z_amplitude_um=1.17, z_phase_deg=130.1, cycles_per_rev=36
    )
    head = dataclasses.replace(random_head(204012, "paper", [radial]), repetitions=1)
    campaign = tmp_path / "once.csv"
    write_campaign(simulate(head), campaign)
    result = run_cli("diagnose", "--data", campaign)
    assert result.returncode == 0, result.stderr
    verdict, following = result.stdout.splitlines()[:2]
    assert "nothing here is tested against noise" in verdict and "within" not in verdict
    assert "measure each ring again" in following
    # The report (and the explorer, by the same words: figures.diagnosis_text.report_sections) says so too.
    assert run_cli("report", "--data", campaign, "--out", tmp_path / "once.html").returncode == 0
    assert "nothing here is tested against noise" in (tmp_path / "once.html").read_text()
    result = run_cli("design", "--data", campaign, "--decide", "--json")
    assert result.returncode == 0, result.stderr
    decision = json.loads(result.stdout)
    assert decision["rings"] == [] and decision["questions"] and "one repetition" in decision["note"]


@pytest.mark.parametrize("pair", [True, False])
def test_what_no_ring_decides_is_worded_as_a_pair_or_as_a_suggestion(pair):
    """A pair that no ring and no other measurement separates keeps its name as a pair; a single
    suggestion too small to confirm stays a suggestion (it was told it "stays a pair")."""
    from ph_explorer.figures.decision_text import decision_words
    from ph_explorer.planning.deciding import Decision

    words = "a_axis_cyclic 26 cycles/rev" + (" or a_axis_radial_motion 26 cycles/rev" if pair else "")
    question = {"words": words, "pair": pair, "decided_by_rings": False, "power": 0.12, "expected_gain": 3.0, "scatter": 1.0}
    sentence = " ".join(decision_words(Decision([], {"q": {**question, "rings_needed": None}}, None, budget=6), 6).undecided)
    assert words in sentence and "not even 18 rings would" in sentence
    assert ("the name stays a pair" in sentence) == pair and ("stays a suggestion" in sentence) == (not pair)
    assert sentence.startswith("No 6 rings of this stylus " + ("decide " if pair else "confirm or refute "))
