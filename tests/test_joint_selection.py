"""Two effects that only replicate together are claimed together (diagnosis.choice.claimed_together):
two harmonics of the B axis's angular error, a beat, where one at a time stalls at a suggestion."""

from __future__ import annotations

import pytest

from benchmarks.multi_effects import claim_record, holds_truth
from ph_explorer.diagnosis import diagnose
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.effects.axes import BAxisCyclic
from ph_explorer.effects.motions import AAxisAxialMotion, AAxisRadialMotion, BAxisAxialMotion, BAxisRadialMotion, BAxisTiltMotion
from ph_explorer.models import least_squares
from ph_explorer.twin.random_heads import random_campaign


@pytest.fixture(scope="module")
def beat():
    # B 19/rev at 1.1" and 38/rev at 0.45" on a random head of another probe geometry (its seed's
    # own background and noise law): one at a time, the search stopped at B 19/rev suggested, its
    # gain over rings not significant.
    hidden = [
        BAxisCyclic(amplitude_arcsec=-1.1058, phase_deg=359.763, cycles_per_rev=19),
        BAxisCyclic(amplitude_arcsec=0.4538, phase_deg=303.4, cycles_per_rev=38),
    ]
    campaign = random_campaign(580025, "other_geometry", hidden)
    return campaign, diagnose(campaign, nested=False)


def test_two_harmonics_of_one_axis_are_both_claimed(beat) -> None:
    _, result = beat
    assert result.verdict == "missing"
    claimed = sorted((c.effect, c.settings["cycles_per_rev"]) for c in result.found)
    assert claimed == [("b_axis_cyclic", 19), ("b_axis_cyclic", 38)]
    # ... together: each note says so, and their joint gain is the replication each carries.
    assert all(c.note.startswith("claimed together with") and c.replication.replicated for c in result.found)
    # Each amplitude within its expanded uncertainty of the truth's (the sign convention: either).
    truth = {19: 1.1058, 38: 0.4538}
    for c in result.found:
        fitted, u = abs(c.params["amplitude_arcsec"]), c.params_u["amplitude_arcsec"]
        assert abs(fitted - truth[c.settings["cycles_per_rev"]]) <= u


def test_one_harmonic_alone_is_not_claimed_with_a_passenger() -> None:
    one = random_campaign(580025, "other_geometry", [BAxisCyclic(amplitude_arcsec=-1.6, phase_deg=359.763, cycles_per_rev=19)])
    result = diagnose(one, nested=False)
    assert [(c.effect, c.settings["cycles_per_rev"]) for c in result.found] == [("b_axis_cyclic", 19)]
    assert not any(c.note.startswith("claimed together") for c in result.found)


def test_a_pair_is_tried_from_the_next_candidate_when_the_best_is_an_untold_partner_whose_form_breaks() -> None:
    # B tilt motion 6/rev and B axial motion 7/rev on a coarse lattice: the best candidate beyond
    # noise is the radial motion 6/rev, which the rings cannot tell from the tilt motion by its
    # gain but whose parameters differ between low and high A beside any second effect; from it,
    # no pair was taken. From the next candidate, the tilt motion, the pair holds.
    hidden = [
        BAxisTiltMotion(
            about_x_amplitude_arcsec=-1.0252,
            about_x_phase_deg=147.85,
            about_y_amplitude_arcsec=1.0252,
            about_y_phase_deg=41.54,
            cycles_per_rev=6,
        ),
        BAxisAxialMotion(amplitude_um=-0.7003, phase_deg=307.08, cycles_per_rev=7),
    ]
    result = diagnose(random_campaign(975009, "coarse", hidden), nested=False)
    assert sorted((c.effect, c.settings["cycles_per_rev"]) for c in result.found) == [("b_axis_axial_motion", 7), ("b_axis_tilt_motion", 6)]
    assert all(c.note.startswith("claimed together with") for c in result.found)
    assert result.candidates[0].effect == "b_axis_radial_motion"


def test_a_setting_chosen_before_a_later_effect_is_refitted_beside_it() -> None:
    # Three effects on a coarse lattice: the A-axis radial motion 11/rev was taken at 13/rev while
    # the B-axis tilt motion was still missing; scanned again beside it, it moves.
    hidden = [
        BAxisTiltMotion(
            about_x_amplitude_arcsec=-0.5054,
            about_x_phase_deg=26.93,
            about_y_amplitude_arcsec=0.5054,
            about_y_phase_deg=28.80,
            cycles_per_rev=10,
        ),
        AAxisRadialMotion(y_amplitude_um=0.4143, y_phase_deg=43.0, z_amplitude_um=0.4143, z_phase_deg=44.85, cycles_per_rev=11),
        BAxisCyclic(amplitude_arcsec=-2.7388, phase_deg=273.69, cycles_per_rev=32),
    ]
    result = diagnose(random_campaign(580006, "coarse", hidden), nested=False)
    radial = next(c for c in result.found if c.effect == "a_axis_radial_motion")
    assert radial.note == "its setting refitted beside the other effects (was 13)"
    # ... to a setting whose set of those the rings cannot exclude holds the truth.
    assert radial.settings == {"cycles_per_rev": 11} or {"cycles_per_rev": 11} in radial.settings_not_excluded
    assert sorted(c.effect for c in result.found) == ["a_axis_radial_motion", "b_axis_cyclic", "b_axis_tilt_motion"]


def test_an_effect_that_stood_in_for_a_later_one_gives_way_beside_it() -> None:
    # Three effects on a random head: the B-axis axial motion 16/rev was first taken as a B-axis
    # tilt motion 17/rev, while the B radial and A axial motions were still missing; beside them,
    # the rings prefer the axial motion in its place (choice.chosen_beside).
    hidden = [
        BAxisAxialMotion(amplitude_um=-0.1694, phase_deg=37.17, cycles_per_rev=16),
        AAxisAxialMotion(amplitude_um=-0.2515, phase_deg=31.13, cycles_per_rev=13),
        BAxisRadialMotion(x_amplitude_um=-0.2275, x_phase_deg=295.9, y_amplitude_um=-0.2275, y_phase_deg=297.46, cycles_per_rev=33),
    ]
    result = diagnose(random_campaign(571000, "paper", hidden), nested=False)
    claimed = {c.effect: c for c in result.found}
    assert sorted(claimed) == ["a_axis_axial_motion", "b_axis_axial_motion", "b_axis_radial_motion"]
    axial = claimed["b_axis_axial_motion"]
    assert axial.settings == {"cycles_per_rev": 16}
    assert axial.note == "taken in place of B-axis tilt error motion 17 beside the other effects"
    # The effect it replaced is in the ranking still, no claim, saying what took its place.
    gave_way = next(
        c for ranking in (result.candidates, *result.reranked) for c in ranking if c.effect == "b_axis_tilt_motion" and c.not_needed
    )
    assert "B-axis axial error motion explains more in its place" in gave_way.note


def test_a_scan_whose_best_fit_is_implausible_takes_its_best_plausible_setting() -> None:
    # Two harmonics of the A axis's tilt motion (31/rev at 0.97", 19/rev at 0.76") on a random
    # head of the paper's design (975008, its own background and noise law). The A axis turns
    # through part of a revolution only: the tilt's low periods fit the beat with tens of arcsec,
    # and while the scan's best fit decided, the tilt was "implausible" and the verdict a shape.
    tilt_motion = DEFAULT_CATALOG["a_axis_tilt_motion"]
    hidden = [
        tilt_motion(
            about_y_amplitude_arcsec=0.9734,
            about_y_phase_deg=286.49,
            about_z_amplitude_arcsec=0.9734,
            about_z_phase_deg=188.76,
            cycles_per_rev=31,
        ),
        tilt_motion(
            about_y_amplitude_arcsec=0.7571,
            about_y_phase_deg=339.84,
            about_z_amplitude_arcsec=-0.7571,
            about_z_phase_deg=187.62,
            cycles_per_rev=19,
        ),
    ]
    campaign = random_campaign(975008, "paper", hidden)
    search = CandidateSearch(campaign, ~campaign.holdout_mask(), detail=False)
    scan = search.scan(tilt_motion())
    best = tilt_motion().with_settings(**scan.scanned[0][1])
    assert best.implausible(best.from_coefficients(least_squares.fit(search.design([best]), search.targets)[0][:, 0]))
    tilt = search.judge(scan, float(scan.null_best.max()))
    assert tilt.beyond_noise and not tilt.implausible and tilt.settings["cycles_per_rev"] >= 20
    result = diagnose(campaign)
    assert result.verdict == "missing"
    held = [any(holds_truth(claim_record(c), "a_axis_tilt_motion", {"cycles_per_rev": float(n)}) for c in result.found) for n in (31, 19)]
    assert held == [True, True]
    # The setting the rings cannot tell from a claim's, named for the rings that would decide, is plausible too.
    rivals = [(c.effect, c.rival_setting) for c in result.found if c.rival_setting is not None]
    assert rivals and all(not DEFAULT_CATALOG[effect].implausible(rival.params) for effect, rival in rivals)
