"""The nested gain (issue 55, item 3; docs/diagnosis.md): the fall in error of the rings, check
rings included, that took no part in choosing the effects, tested over those rings as a claim's
gain is; a claim stands only when it holds."""

from __future__ import annotations

import json
from dataclasses import replace
from types import SimpleNamespace

from benchmarks.multi_effects import multi_effect_head
from benchmarks.population import campaign_of
from benchmarks.unknown_shapes import unknown_shape_head
from ph_explorer.diagnosis import diagnose
from ph_explorer.diagnosis.choice import choose_effects
from ph_explorer.diagnosis.nested import held_out_claims, nested_after, reproduced_settings, unsettled_claims
from ph_explorer.diagnosis.replication import Replication
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects import DEFAULT_CATALOG, effect_label
from ph_explorer.effects.axes import BAxisCyclic
from ph_explorer.figures.diagnosis_text import report_text
from ph_explorer.twin import load_scenario, simulate


def test_the_nested_gain_is_tested_over_the_rings_that_took_no_part_and_reported():
    """head_3's hidden B-axis error, found: on the rings of the nested folds it gains, replicated
    over them, and the report says so; a gain that does not replicate is worded as such; the record
    round-trips the test; a front end's progress says when the folds run."""
    said: list[str] = []
    result = diagnose(simulate(load_scenario("head_3")), progress=said.append)
    assert result.verdict == "missing" and result.nested.gain is not None
    testing = said.index("testing the claims on rings left out of the choice (nested cross-validation)")
    assert testing > 0 and all(s.startswith("scanning ") for s in said[:testing])
    gain = result.nested.gain
    assert result.nested.gain_holds and gain.p_value < 0.05 and gain.rings_gaining > gain.rings / 2
    check = load_scenario("head_3")
    assert result.nested.check_rings == len(check.check_orientations) and result.nested.rings == 135
    assert "tested over them" in report_text(result, DEFAULT_CATALOG) and ": replicated" in report_text(result, DEFAULT_CATALOG)
    nil = Replication(p_value=0.6, p_without_top=0.7, rings_gaining=40, rings=80, check_gain=float("nan"), lattice_gain=-0.01)
    weak = replace(result, nested=replace(result.nested, gain=nil))
    assert not weak.nested.gain_holds and "not replicated: no effect the search chose is claimed" in report_text(weak, DEFAULT_CATALOG)
    # A campaign of too few training rings for the folds: its claims rest on the search's test, and the report says so.
    assert "rest on the search's own test" not in report_text(result, DEFAULT_CATALOG)
    few = replace(result, nested=None, rings=result.rings[:15])
    assert "These claims rest on the search's own test: 15 training rings make no 5 folds" in report_text(few, DEFAULT_CATALOG)
    data = json.loads(json.dumps(result.to_json()))
    assert data["nested_after"]["gain"]["p_value"] == round(gain.p_value, 5)
    assert Diagnosis.from_json(data).to_json() == data


def test_claims_whose_settings_move_in_the_folds_are_no_claims():
    """A step in the B axis's angular position (a test-only shape no catalog holds, 944000): the
    search alone takes two B-axis cyclic periods, 7 and 9/rev, replicated over the rings it chose
    them on; refitted in the folds, each without a fifth of the rings, 2 of 5 folds set the second
    at 5/rev, which the whole campaign excludes. Chosen together they fail the folds; the first
    alone holds in all 5 (a fixed sequence), so 7/rev stays claimed beside the step's shape and
    9/rev is suggested, not claimed: the verdict is not `missing`, and the report says why."""
    result = diagnose(unknown_shape_head(944000, "step").campaign)
    assert result.verdict == "uncatalogued" and result.nested.check_rings > 0
    assert [(c.effect, c.settings) for c in result.found] == [("b_axis_cyclic", {"cycles_per_rev": 7})]
    assert result.nested.chosen == (("b_axis_cyclic 7 cycles/rev",),) * 5
    withdrawn = [c for c in result.suggested if "rings left out of the choice" in c.note]
    assert [(c.effect, c.settings) for c in withdrawn] == [("b_axis_cyclic", {"cycles_per_rev": 9})] and withdrawn[0].replication.replicated
    assert "2 of 5 folds set b_axis_cyclic 9 cycles/rev at 5 cycles/rev, which the whole campaign excludes" in withdrawn[0].note
    assert withdrawn[0].note.endswith("; b_axis_cyclic 7 cycles/rev replicates without it")
    assert "do not replicate on rings left out of the choice" in report_text(result, DEFAULT_CATALOG)


def test_one_fold_that_moves_a_claim_by_a_cycle_does_not_withdraw_it():
    """An A-axis tilt motion 11/rev near its detection limit (population head 200084): one fold of
    five, without a fifth of the rings, sets it at 12/rev, which the whole campaign excludes; the
    other four keep 11/rev and its gain replicates on the rings left out, so it stays claimed: no
    single fold decides."""
    campaign, truth = campaign_of({"group": "catalog_effect", "seed": 200084})
    result = diagnose(campaign)
    assert truth["id"] == "a_axis_tilt_motion" and truth["cycles_per_rev"] == 11
    assert [(c.effect, c.settings) for c in result.found] == [("a_axis_tilt_motion", {"cycles_per_rev": 11})]
    folds = sorted(fold[0].removeprefix("a_axis_tilt_motion ") for fold in result.nested.chosen)
    assert folds == ["11 cycles/rev"] * 4 + ["12 cycles/rev"]
    assert result.verdict == "missing" and result.nested.gain_holds


def test_a_fold_reproduces_a_period_within_one_step_of_the_scans_grid():
    """A claim at 22/rev whose campaign does not exclude 21/rev: folds at 20 or 23/rev reproduce it
    (a grid step from a setting not excluded: a period between two whole ones shows at either), two
    folds at 24 and 19/rev do not, and one alone never withdraws it."""
    effect = BAxisCyclic().with_settings(cycles_per_rev=22)
    claim = SimpleNamespace(settings={"cycles_per_rev": 22.0}, settings_not_excluded=[{"cycles_per_rev": 21.0}])
    assert sorted({s["cycles_per_rev"] for s in reproduced_settings(claim, effect)}) == [20.0, 21.0, 22.0, 23.0]

    def unsettled(*periods: int) -> dict[int, list[str]]:
        chosen = [(effect_label(effect.with_settings(cycles_per_rev=k)),) for k in periods]
        return unsettled_claims([claim], [effect], SimpleNamespace(chosen=chosen))

    assert unsettled(23, 20, 22, 22, 22) == {} and unsettled(24, 22, 22, 22, 22) == {}
    assert unsettled(24, 19, 22, 22, 22) == {0: ["b_axis_cyclic 24 cycles/rev", "b_axis_cyclic 19 cycles/rev"]}


def test_a_fold_at_a_setting_the_rings_do_not_tell_from_the_claims_reproduces_it():
    """A setting is excluded only when the touches' profile likelihood and the rings as units both
    exclude it (the report's "cannot exclude", docs/diagnosis.md step 3): two folds at 2/rev for a
    claim at 25/rev withdraw it unless the rings do not tell 2/rev from 25/rev, asked of that claim
    at the folds' setting."""
    effect = BAxisCyclic().with_settings(cycles_per_rev=25)
    claim = SimpleNamespace(settings={"cycles_per_rev": 25.0}, settings_not_excluded=[])
    nested = SimpleNamespace(chosen=[(effect_label(effect.with_settings(cycles_per_rev=k)),) for k in (2, 25, 2, 25, 25)])
    asked = []

    def rings(told: bool):
        def untold(i: int, other: BAxisCyclic) -> bool:
            asked.append((i, other.settings()["cycles_per_rev"]))
            return not told

        return untold

    assert unsettled_claims([claim], [effect], nested, rings(told=True)) == {0: ["b_axis_cyclic 2 cycles/rev"] * 2}
    assert unsettled_claims([claim], [effect], nested, rings(told=False)) == {}
    assert asked == [(0, 2.0), (0, 2.0)]


def test_a_claim_the_folds_withdraw_is_suggested_as_its_own_ranking_told_it():
    """An A-axis tilt motion (38/rev) and a B-axis cyclic error (25/rev) on one head (975036): the
    search takes the B error second, beside the tilt; 2 of 5 folds set it at 2/rev, which the rings
    beside the tilt tell from 25/rev, so it is withdrawn. Its suggestion is the re-ranked one: fitted
    beside the tilt, its settings asked there, so the report never lists as "not excluded" the
    setting its note says the campaign excludes (asked beside nothing, 2/rev is not excluded)."""
    result = diagnose(multi_effect_head(975036).campaign)
    assert [c.effect for c in result.found] == ["a_axis_tilt_motion"]
    withdrawn = next(c for c in result.suggested if c.effect == "b_axis_cyclic")
    assert "2 of 5 folds set b_axis_cyclic 25 cycles/rev at 2 cycles/rev, which the whole campaign excludes" in withdrawn.note
    assert withdrawn == next(c for c in result.reranked[0] if c.effect == "b_axis_cyclic")
    assert {"cycles_per_rev": 2} not in withdrawn.settings_not_excluded
    alone = next(c for c in result.candidates if c.effect == "b_axis_cyclic")
    assert alone.suggested and {"cycles_per_rev": 2} in alone.settings_not_excluded


def test_the_folds_scan_each_claim_beside_the_others():
    """Three catalog effects at once (a head of its own seed, 975013: B-axis radial motion 13/rev,
    B-axis axial motion 19/rev, A-axis axial motion 28/rev). While the folds scanned the claims in
    the chain's order, each without those after it in the model, the verdict was `uncatalogued`:
    the B-axis axial motion left to a shape. Each scanned beside the others, as the search chose
    it, the folds keep the B-axis pair, and the verdict is `missing` with both."""
    result = diagnose(multi_effect_head(975013).campaign)
    claimed = {(c.effect, c.settings["cycles_per_rev"]) for c in result.found}
    assert result.verdict == "missing" and {("b_axis_radial_motion", 13), ("b_axis_axial_motion", 19)} <= claimed
    assert all(fold[:1] == ("b_axis_radial_motion 13 cycles/rev",) for fold in result.nested.chosen)


def test_a_claim_whose_gain_is_nil_on_rings_left_out_is_no_claim():
    """An A-axis cyclic error forced on the paper's head (which holds none) at the period its noise
    fits best: on the rings left out of each fold's fit it gains nothing replicated, so it is withdrawn, with
    why, and the chain falls back to what came before it."""
    campaign = simulate(load_scenario("paper"))
    choice = choose_effects(campaign, ~campaign.holdout_mask(), [cls() for cls in DEFAULT_CATALOG.candidates().values()], detail=False)
    candidate = next(c for c in choice.candidates if c.effect == "a_axis_cyclic")
    effect = DEFAULT_CATALOG[candidate.effect]().with_settings(**candidate.settings)
    forced = replace(choice, found=[candidate], chain=[*choice.chain, effect])
    kept, honest = held_out_claims(forced, campaign, len(choice.chain))
    assert not honest.gain_holds and not kept.found and kept.chain == choice.chain
    note = next(c for c in kept.rankings[0] if c.effect == "a_axis_cyclic").note
    assert note.startswith("the claim does not replicate on rings left out of the choice (nested cross-validation, 5 folds: ")


def test_a_claim_that_replicates_does_not_sink_with_one_taken_after_it():
    """head_3's B-axis error, claimed, and after it an A-axis cyclic error forced at 3/rev, where
    the folds' scans do not put it (they set it where the head's noise fits best): together the
    claims fail the folds, so the first is put to them alone (a fixed sequence) and kept; only the
    forced one is withdrawn, and its note says which claim replicates without it. The honest after
    is the kept claim's."""
    campaign = simulate(load_scenario("head_3"))
    choice = choose_effects(campaign, ~campaign.holdout_mask(), [cls() for cls in DEFAULT_CATALOG.candidates().values()], detail=False)
    (claim,) = choice.found
    ranked = next(c for c in choice.rankings[-1] if c.effect == "a_axis_cyclic")
    candidate = replace(ranked, settings={"cycles_per_rev": 3.0}, settings_not_excluded=())
    last = [candidate if c is ranked else c for c in choice.rankings[-1]]
    effect = DEFAULT_CATALOG["a_axis_cyclic"](cycles_per_rev=3.0)
    forced = replace(choice, found=[claim, candidate], chain=[*choice.chain, effect], rankings=[*choice.rankings[:-1], last])
    fixed = len(choice.chain) - 1
    both = nested_after(campaign, forced.chain[fixed:], forced.chain[:fixed])
    assert 1 in unsettled_claims(forced.found, forced.chain[fixed:], both)
    kept, honest = held_out_claims(forced, campaign, fixed)
    assert kept.found == [claim] and kept.chain == choice.chain and honest.gain_holds
    assert all(len(fold) == 1 for fold in honest.chosen)
    note = next(c for c in kept.rankings[-1] if c.effect == "a_axis_cyclic").note
    assert note.startswith("the claims chosen together do not replicate") and note.endswith(
        f"; {effect_label(choice.chain[-1])} replicates without it"
    )
