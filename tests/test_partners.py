"""A confounded partner is named at the settings that stand in for the claim (diagnosis.partners):
an A-axis tilt motion at n/rev reads at the ball as an axial motion at n - 1 or n + 1, so a claim
of one names the other one setting around its own, not at the other's best ranking."""

from __future__ import annotations

import pytest

from ph_explorer.diagnosis import diagnose
from ph_explorer.diagnosis.partners import SHARE_TIE, partner_settings, standing_in_order
from ph_explorer.diagnosis.search import CandidateSearch
from ph_explorer.diagnosis.separation import shared_variance
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.effects.motions import AAxisAxialMotion, AAxisTiltMotion, BAxisRadialMotion
from ph_explorer.figures.diagnosis_text import verdict_headline
from ph_explorer.twin.random_heads import random_campaign

# A coning A axis (its tilt about Y and Z a quarter turn apart) at 21/rev beside a B-axis radial
# motion 14/rev, on a coarse lattice: the tilt's one sideband, 20/rev, is all the touches show.
CONING = {"about_y_amplitude_arcsec": -0.6067, "about_y_phase_deg": 45.77, "about_z_amplitude_arcsec": 0.6067, "about_z_phase_deg": 134.63}
HIDDEN = [
    AAxisTiltMotion(**CONING, cycles_per_rev=21),
    BAxisRadialMotion(x_amplitude_um=0.5426, x_phase_deg=196.53, y_amplitude_um=0.5426, y_phase_deg=192.52, cycles_per_rev=14),
]


def test_settings_that_share_alike_keep_the_order_tried() -> None:
    """Shares equal but for the arithmetic's last digits (1.0 each, as one machine or another makes
    them) stand in in the order tried, so reports are the same everywhere; a share closer by more
    than rounding comes first, and one below the tie is left out."""
    tilt = [AAxisTiltMotion().with_settings(cycles_per_rev=k) for k in (20, 19, 21, 30, 22)]
    tried = [(1.0 - 2e-16, tilt[0]), (1.0, tilt[1]), (1.0 - 1e-15, tilt[2]), (0.5, tilt[3]), (1.0 - SHARE_TIE / 2, tilt[4])]
    assert [o for _, o in standing_in_order(tried)] == [tilt[0], tilt[1], tilt[2], tilt[4]]
    assert [o for _, o in standing_in_order([(0.97, tilt[0]), (0.975, tilt[1])])] == [tilt[1], tilt[0]]


@pytest.fixture(scope="module")
def coning():
    campaign = random_campaign(570012, "coarse", HIDDEN)
    return campaign, diagnose(campaign, nested=False)


def test_an_axial_motion_shares_all_with_a_tilt_one_setting_around(coning) -> None:
    campaign, _ = coning
    search = CandidateSearch(campaign, ~campaign.holdout_mask())
    axial = AAxisAxialMotion().with_settings(cycles_per_rev=20)
    tried = {o.settings()["cycles_per_rev"] for o in partner_settings(axial, AAxisTiltMotion().with_settings(cycles_per_rev=30))}
    assert tried == {19, 20, 21, 30}  # its own best, and one scan step around the claim's
    shares = {k: shared_variance(search.design([axial]), search.design([AAxisTiltMotion().with_settings(cycles_per_rev=k)])) for k in tried}
    assert shares[19] > 0.99 and shares[21] > 0.99 and shares[30] < 0.5
    # ... and a B-axis partner is tried at its own setting only.
    assert len(partner_settings(axial, BAxisRadialMotion().with_settings(cycles_per_rev=30))) == 1


def test_the_untold_partner_is_named_at_the_settings_that_stand_in(coning) -> None:
    _, result = coning
    claim = next(c for c in result.found if c.effect.startswith("a_axis"))
    truth = {"a_axis_tilt_motion": 21}
    named = {claim.effect: [claim.settings["cycles_per_rev"]]} | {p.effect: [s["cycles_per_rev"] for s in p.settings] for p in claim.untold}
    assert any(truth[e] in k for e, k in named.items() if e in truth), named  # the pair holds the truth
    line = verdict_headline(result.headline, DEFAULT_CATALOG)
    assert all(e in line for e in named)
    # A partner the rings cannot tell is fitted where it stands in, for the rings that would decide.
    assert all(p.params and p.settings for p in claim.untold)
