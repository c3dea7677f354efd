"""The checks of the experiment code only the benchmarks use (benchmarks/carried.py, the terms a
hybrid carries; benchmarks/stacking.py, the stacked hybrid): not part of the test suite (the
README's `python -m pytest` collects tests/ only), run on their own beside the benchmarks:

    .venv/bin/python -m pytest benchmarks/experiment_checks.py

The product's own parts they build on (the hybrid with each data part, the mean curve, the
cross-validation) are tested in tests/.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from benchmarks.carried import Identification, carried_effects, cross_validated_mae
from benchmarks.data_efficiency import designed_subsets, lattice_subsets
from benchmarks.stacking import WITH_GP, StackedHybrid, carried_hybrid, simplex_grid
from ph_explorer import metrics
from ph_explorer.campaign import Campaign
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.geometry import point_angles_deg
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models import least_squares
from ph_explorer.models.crossval import cross_val_predict
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.hybrid import HybridModel
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.twin import load_scenario, simulate
from tests.synthetic import scenario_with

pytestmark = pytest.mark.xdist_group("experiment_checks")  # one worker: the module fixtures made once

B_AXIS = DEFAULT_CATALOG["b_axis_cyclic"]


def training_columns(campaign: Campaign, k: int) -> Campaign:
    """The campaign's training rings on every A row x k B columns (the data-efficiency benchmark's subset)."""
    return campaign.subset(lattice_subsets(campaign, ~campaign.holdout_mask(), (k,))[0])


def designed_rings(campaign: Campaign, budget: int) -> Campaign:
    """The campaign's training rings `ph-explorer design --budget N` proposes (the benchmark's designed subset)."""
    return campaign.subset(designed_subsets(campaign, ~campaign.holdout_mask(), (budget,))[0][0])


def check_ring_mae(model: DeviationModel, campaign: Campaign) -> float:
    """A fitted model's MAE (um) against the repetition mean over every touch of the campaign's check rings."""
    check = campaign.holdout_mask()
    return metrics.mae(model.predict_touches(campaign_touches(campaign.subset(check))), campaign.deviations[check])["mean"]


# -- carried.py: the terms the data can carry -----------------------------------------------------
# The hybrid keeps only the physical terms the data can carry (carried_effects): terms the campaign
# identifies (no alias it cannot tell from them that predicts otherwise between the rings), a
# scanned setting only when the subset itself chooses it (Identification.setting_moves), chosen by
# its own cross-validation: the project's one (crossval.cross_val_predict).
@pytest.fixture(scope="module")
def head() -> Campaign:
    """The teaching head: B 2/rev 1.8 arcsec, B 4/rev 1.0, and a hidden B 22/rev 1.0 arcsec."""
    return simulate(load_scenario("head_3"))  # with the scenario's own seed


@pytest.fixture(scope="module")
def head_columns(head: Campaign) -> Identification:
    return Identification(training_columns(head, 3))


@pytest.fixture(scope="module")
def paper() -> Campaign:
    return simulate(load_scenario("paper"))  # with the scenario's own seed


@pytest.fixture(scope="module")
def three_columns(paper: Campaign) -> Campaign:
    return training_columns(paper, 3)


def test_explained_is_the_joint_least_squares(head_columns: Identification) -> None:
    terms = [B_AXIS(cycles_per_rev=2), B_AXIS(cycles_per_rev=22), DEFAULT_CATALOG["lobing"]()]
    joint = head_columns.design(terms[0]).stacked(head_columns.design(terms[1])).stacked(head_columns.design(terms[2]))
    expected = least_squares.fit(joint, head_columns.targets)[1][0]
    assert head_columns.explained(terms) == pytest.approx(expected, rel=1e-9)
    assert head_columns.explained([]) == 0.0


def test_a_setting_that_moves_beside_a_term_not_carried_is_not_carried(head_columns: Identification, head: Campaign) -> None:
    """Three B columns: the diagnosis finds B 25/rev, then B 2/rev (aliased with B 1/rev here:
    not carried). Beside the rest B 25/rev explains most of the data; beside B 2/rev, B 22/rev
    does (the head's hidden error). The setting hangs on a term the subset cannot settle: B 25/rev
    is not carried, and the hybrid is its data part, where B 25/rev alone would be 15 % worse."""
    subset = head_columns.campaign
    found = [B_AXIS(cycles_per_rev=25), B_AXIS(cycles_per_rev=2), DEFAULT_CATALOG["lobing"]()]
    moved = head_columns.setting_moves(found[0], [found[0], found[2]], [found[1]])
    assert moved is not None and moved[0].settings()["cycles_per_rev"] == 22 and "b_axis_cyclic 2" in moved[1]
    kept, _, report, _ = carried_effects(subset, found, identification=head_columns)
    assert not report[0]["carried"] and "setting" in report[0]["reason"]
    assert all(e.id != "b_axis_cyclic" for e in kept)
    assert check_ring_mae(HybridModel(found[:1]).fit(subset), head) > 1.05 * check_ring_mae(HybridModel(kept).fit(subset), head)


def test_a_setting_the_data_choose_is_carried(head: Campaign) -> None:
    """Six B columns: B 22/rev is what the data choose beside B 2/rev and B 4/rev."""
    check = Identification(training_columns(head, 6))
    effects = [B_AXIS(cycles_per_rev=n) for n in (22, 2, 4)]
    assert check.setting_moves(effects[0], effects, []) is None
    groups, report = check.groups(effects)
    assert report[0]["carried"] and any(e is effects[0] for g in groups for e in g)


def test_no_effect_is_the_data_part_cross_validated_as_any_model(three_columns: Campaign) -> None:
    every = np.ones(three_columns.n_orientations, dtype=bool)
    direct = cross_val_predict(TrilinearModel, three_columns, every, strict=True)
    expected = metrics.mae(direct, three_columns.deviations)["mean"]
    assert cross_validated_mae([], three_columns, every) == pytest.approx(expected, rel=1e-9)


def test_an_aliased_term_is_not_carried_though_the_cross_validation_likes_it(three_columns: Campaign, paper: Campaign) -> None:
    """Three B columns 120 deg apart: a B 4/rev error takes the values of a 1, 2 or 7/rev one at
    every ring (the paper head has 1.8 arcsec at 2/rev and 1.0 at 4/rev). Its own cross-validation
    prefers it by far (the rings left out lie on the same columns), yet between the columns it
    predicts worse than the data part alone: it is not carried. The seat lobing, which the data part
    reproduces between the rings, is not judged by its aliases."""
    cyclic, lobing = B_AXIS(cycles_per_rev=4), DEFAULT_CATALOG["lobing"]()
    every = np.ones(three_columns.n_orientations, dtype=bool)
    assert cross_validated_mae([cyclic], three_columns, every) < 0.7 * cross_validated_mae([], three_columns, every)
    assert check_ring_mae(HybridModel([cyclic]).fit(three_columns), paper) > check_ring_mae(HybridModel([]).fit(three_columns), paper)
    kept, path, report, _ = carried_effects(three_columns, [cyclic, lobing])
    assert not any(e.id == cyclic.id for e in kept)
    by_effect = {r["effect"]: r for r in report}
    cyclic_entry = by_effect["b_axis_cyclic 4 cycles/rev"]
    assert not cyclic_entry["carried"] and "aliased" in cyclic_entry["reason"]
    assert any(a.startswith("b_axis_cyclic 2 cycles/rev") for a in cyclic_entry["aliases"])
    assert by_effect["lobing"]["learnable_between"] > 0.8


def test_aliases_the_candidates_hold_are_carried_together(paper: Campaign) -> None:
    """Six B columns: 4/rev = -2/rev at every column. The joint fit separates the two through the
    rings' B sweeps; alone, B 4/rev would hold the share of the 2/rev error and is not carried."""
    six = training_columns(paper, 6)
    check = Identification(six)
    four, two = B_AXIS(cycles_per_rev=4), B_AXIS(cycles_per_rev=2)
    alone, report = check.groups([four])
    assert alone == [] and not report[0]["carried"]
    together, _ = check.groups([four, two])
    assert [[e.settings()["cycles_per_rev"] for e in g] for g in together] == [[4.0, 2.0]]
    kept, _, _, _ = carried_effects(six, [four, two], identification=check)
    assert len(kept) == 2
    assert check_ring_mae(HybridModel(kept).fit(six), paper) < check_ring_mae(HybridModel([]).fit(six), paper)


def test_an_identifiable_term_is_carried(paper: Campaign) -> None:
    """Nine B columns 40 deg apart: no catalog term shares more than 0.8 with B 4/rev there."""
    nine = training_columns(paper, 9)
    kept, _, report, _ = carried_effects(nine, [B_AXIS(cycles_per_rev=4)])
    assert report[0]["carried"] and report[0]["aliases"] == []
    assert [e.settings()["cycles_per_rev"] for e in kept] == [4.0]


def test_on_touch_noise_alone_nothing_is_kept(three_columns: Campaign) -> None:
    rng = np.random.default_rng(5)
    noise = remove_size_and_centre(rng.normal(0.0, 0.175, three_columns.deviations.shape))
    campaign = Campaign(three_columns.orientations, noise, geometry=three_columns.geometry)
    effects = [B_AXIS(cycles_per_rev=4), DEFAULT_CATALOG["lobing"]()]
    kept, _, _, _ = carried_effects(campaign, effects)
    assert kept == []


# -- stacking.py: the stacked hybrid --------------------------------------------------------------
# The hybrids with the trilinear tables, the mean curve and when asked the GP as their data part,
# averaged with the weights of their own cross-validation (carried_hybrid).
def b_two_campaign(seed: int):
    """A head whose only orientation-dependent error is a B 2/rev error of 1.8 arcsec, noise draw seed."""
    return simulate(scenario_with(B_AXIS(amplitude_arcsec=1.8, phase_deg=40.0, cycles_per_rev=2)), seed)


@pytest.fixture(scope="module")
def b_two_head():
    """The B 2/rev head of noise draw 3."""
    return b_two_campaign(3)


@pytest.fixture(scope="module")
def uncatalogued(b_two_head):
    """The same head with an error no catalog effect describes (with_uncatalogued_lobes)."""
    return with_uncatalogued_lobes(b_two_head)


def with_uncatalogued_lobes(campaign):
    """The campaign plus an error no catalog effect describes: a 0.3 um 5-lobe pattern growing with
    A (sin A) and turning with B."""
    a, b = np.radians(campaign.orientations[:, :1]), np.radians(campaign.orientations[:, 1:])
    theta = np.radians(point_angles_deg(campaign.n_points))[None, :]
    unknown = remove_size_and_centre(0.3 * np.sin(a) * np.cos(5 * theta - b))
    return dataclasses.replace(campaign, deviations=campaign.deviations + unknown[:, None, :])


def ends(model):
    """The stacked hybrid's members by data part."""
    return {m.data_part.name: m for m in model.members}


def test_when_the_terms_carry_the_orientation_dependence_the_mean_curve_weighs_most(b_two_head) -> None:
    """A head whose only orientation-dependent error is a B 2/rev error, measured on 12 designed
    rings: beside the term, interpolating the residuals between the 12 rings only carries their
    noise into every prediction; the mean curve averages it away. The cross-validation sees it and
    the check rings confirm it."""
    campaign = b_two_head
    subset = designed_rings(campaign, 12)
    model, details = carried_hybrid(subset, [B_AXIS(cycles_per_rev=2)])
    assert details["mean_curve_gain_in_standard_errors"] > 1.0 and model.weight_of("mean_curve") > 0.5
    assert details["mean_curve"]["kept"] == ["b_axis_cyclic 2 cycles/rev"]
    assert check_ring_mae(model, campaign) < 0.95 * check_ring_mae(ends(model)["trilinear"], campaign)


def test_an_orientation_dependence_no_term_holds_keeps_the_interpolation(uncatalogued) -> None:
    """The same head with an error no catalog effect describes (a 5-lobe pattern growing with A and
    turning with B): only an interpolation between the rings learns it."""
    campaign = uncatalogued
    subset = campaign.subset(~campaign.holdout_mask())
    model, details = carried_hybrid(subset, [B_AXIS(cycles_per_rev=2)])
    assert model.weight_of("trilinear") > 0.5
    assert details["trilinear"]["cv_mae_um"] < details["mean_curve"]["cv_mae_um"]
    assert check_ring_mae(model, campaign) < 0.9 * check_ring_mae(ends(model)["mean_curve"], campaign)


def test_on_few_rings_an_undecided_cross_validation_keeps_most_of_the_interpolation(uncatalogued) -> None:
    """The uncatalogued 5-lobe error on 12 designed rings: the rings' cross-validation cannot tell
    the data parts apart (within one standard error), yet only the interpolation learns the error
    between the rings (the mean curve alone is 17-19 % worse on the check rings here over seeds
    3-5). The weight the cross-validation gives the mean curve must not give that up."""
    campaign = uncatalogued
    subset = designed_rings(campaign, 12)
    model, details = carried_hybrid(subset, [B_AXIS(cycles_per_rev=2)])
    assert abs(details["mean_curve_gain_in_standard_errors"]) <= 1.0 and model.weight_of("trilinear") >= 0.5
    stacked = check_ring_mae(model, campaign)
    assert stacked < 1.05 * check_ring_mae(ends(model)["trilinear"], campaign)
    assert stacked < 0.9 * check_ring_mae(ends(model)["mean_curve"], campaign)


def test_with_the_gp_as_a_part_when_the_terms_carry_the_dependence_the_interpolation_weighs_least(b_two_head) -> None:
    """A head whose only orientation-dependent error is a B 2/rev error, measured on 12 designed
    rings: beside the term, interpolating the residuals between the 12 rings only carries their
    noise into every prediction; the mean curve averages it away, and so does the GP, whose length
    scales it learns from the rings. The cross-validation sees it and the check rings confirm it:
    on each of three noise draws below the trilinear end, and by 5 % over the three."""
    ratios = []
    for seed in (3, 4, 5):
        campaign = b_two_head if seed == 3 else b_two_campaign(seed)
        subset = designed_rings(campaign, 12)
        model, details = carried_hybrid(subset, [B_AXIS(cycles_per_rev=2)], parts=WITH_GP)
        assert details["mean_curve_gain_in_standard_errors"] > 1.0 and details["gp_gain_in_standard_errors"] > 1.0
        assert model.weight_of("trilinear") < 0.5
        assert details["mean_curve"]["kept"] == ["b_axis_cyclic 2 cycles/rev"]
        ratios.append(check_ring_mae(model, campaign) / check_ring_mae(ends(model)["trilinear"], campaign))
    assert max(ratios) < 1.0 and np.mean(ratios) < 0.95, ratios


def test_with_the_gp_as_a_part_a_dependence_no_term_holds_is_learnt_by_the_interpolations(uncatalogued) -> None:
    """The same head with an error no catalog effect describes (a 5-lobe pattern growing with A and
    turning with B): only an interpolation between the rings learns it, the trilinear tables or the
    GP, and the GP, whose features turn with the probe, learns it better."""
    campaign = uncatalogued
    subset = campaign.subset(~campaign.holdout_mask())
    model, details = carried_hybrid(subset, [B_AXIS(cycles_per_rev=2)], parts=WITH_GP)
    assert model.weight_of("mean_curve") < 0.5
    assert details["trilinear"]["cv_mae_um"] < details["mean_curve"]["cv_mae_um"]
    assert details["gp"]["cv_mae_um"] < details["trilinear"]["cv_mae_um"]
    stacked = check_ring_mae(model, campaign)
    assert stacked < 0.9 * check_ring_mae(ends(model)["mean_curve"], campaign)
    assert stacked < 0.95 * check_ring_mae(ends(model)["trilinear"], campaign)


def test_with_the_gp_as_a_part_on_few_rings_it_learns_what_the_others_cannot(uncatalogued) -> None:
    """The uncatalogued 5-lobe error on 12 designed rings: the rings' cross-validation cannot tell
    the trilinear tables from the mean curve (within one standard error), and neither learns the
    error between the rings (the mean curve alone is 17-19 % worse than the tables on the check rings
    here over seeds 3-5). The GP, whose features turn with the probe, learns it from the 12 rings:
    the cross-validation sees it, and the weight does not go to the mean curve."""
    campaign = uncatalogued
    subset = designed_rings(campaign, 12)
    model, details = carried_hybrid(subset, [B_AXIS(cycles_per_rev=2)], parts=WITH_GP)
    assert abs(details["mean_curve_gain_in_standard_errors"]) <= 1.0 and details["gp_gain_in_standard_errors"] > 1.0
    assert model.weight_of("mean_curve") < 0.5 and model.weight_of("gp") > 0.5
    stacked = check_ring_mae(model, campaign)
    assert stacked < 0.5 * check_ring_mae(ends(model)["trilinear"], campaign)
    assert stacked < 0.9 * check_ring_mae(ends(model)["mean_curve"], campaign)


def test_the_stacked_hybrid_is_its_members_weighted_and_round_trips(b_two_head, tmp_path) -> None:
    subset = designed_rings(b_two_head, 12)
    members = [HybridModel([B_AXIS(cycles_per_rev=2)], part).fit(subset) for part in ("trilinear", "mean_curve", "gp")]
    model = StackedHybrid(members, [0.3, 0.5, 0.2])
    at = np.array([[43.0, 90.0], [7.5, -170.0]])
    assert np.allclose(model.predict(at), 0.3 * members[0].predict(at) + 0.5 * members[1].predict(at) + 0.2 * members[2].predict(at))
    assert model.weight_of("gp") == pytest.approx(0.2) and model.weight_of("network") == 0.0
    again = StackedHybrid.load(model.save(tmp_path).parent.parent)
    assert np.allclose(again.predict(at), model.predict(at), atol=1e-12)
    with pytest.raises(ValueError):
        StackedHybrid(members, [0.5, 0.6, 0.0])


def test_the_weights_tried_are_every_point_of_the_simplex_in_tenths() -> None:
    grid = simplex_grid(3)
    assert grid.shape == (66, 3) and np.allclose(grid.sum(axis=1), 1.0) and (grid >= 0).all()
    assert len({tuple(np.round(g * 10).astype(int)) for g in grid}) == 66  # each once
    assert {tuple(g) for g in np.eye(3)} <= {tuple(g) for g in grid}  # each data part alone
