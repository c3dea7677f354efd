"""What a campaign's design lets head touches see of each effect: the figures follow the mechanisms
(a centre shift is absorbed by the circle fit, the ring's form is learnt by the lattice, a 3-lobe
ball and the seat lobing are the same columns), on the shipped paper campaign."""

from __future__ import annotations

import numpy as np
import pytest

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.identifiability import describe_effect, effect_bases, identifiability, shared_between
from ph_explorer.diagnosis.separation import shared_variance
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.effects.effect import Effect, Parameter, full_shape, radial_unit
from ph_explorer.io import read_campaign
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.crossval import OutOfSampleSmoother
from ph_explorer.models.hybrid import fitted_basis
from ph_explorer.models.least_squares import Design
from ph_explorer.paths import assets_dir

FIELDS = {
    "id",
    "name",
    "axis",
    "kind",
    "symbol",
    "parameters",
    "scan",
    "evaluated_at",
    "columns",
    "rank_after_fit",
    "visible",
    "visible_rms_um",
    "magnitude",
    "absorbed_by_circle_fit",
    "learnable_by_data_model",
    "confounded_with",
    "over_scan",
    "note",
}


class CentreShift(Effect):
    """A constant displacement of the ball in the machine frame: -d . u_k, harmonic 1 at every ring."""

    id = "test_centre_shift"
    name = "Constant displacement of the ball"
    axis = None
    kind = "location"
    parameters = (
        Parameter("x_um", "um", 1.0, "displacement along machine x", plausible=(0.0, 5.0)),
        Parameter("y_um", "um", 0.5, "displacement along machine y", plausible=(0.0, 5.0)),
        Parameter("z_um", "um", 0.2, "displacement along machine z", plausible=(0.0, 5.0)),
    )

    def basis(self, touches):
        return full_shape(-radial_unit(touches), touches), ["x", "y", "z"]


@pytest.fixture(scope="module")
def paper():
    return read_campaign(assets_dir() / "data" / "paper.csv")


@pytest.fixture(scope="module")
def report(paper):
    return identifiability(paper, [*DEFAULT_CATALOG.values(), CentreShift])


def by_id(report):
    return {row["id"]: row for row in report["effects"]}


def test_every_effect_has_every_field(report):
    rows = by_id(report)
    assert list(rows) == [*DEFAULT_CATALOG, CentreShift.id]
    for row in report["effects"]:
        assert set(row) >= FIELDS, row["id"]
        assert row["axis"] in ("A", "B", "probe", "ring", "environment", None)
        for p in row["parameters"]:
            assert set(p) == {"name", "unit", "plausible"}
        for other in row["confounded_with"]:
            assert set(other) >= {"effect", "shared"} and 0.8 < other["shared"] <= 1.0 + 1e-9
    design = report["design"]
    assert design["rings"] == 135 and design["repetitions"] == 10 and design["held_out_rings"] == 12
    assert design["noise_floor_um"] == pytest.approx(design["noise_sigma_um"] / np.sqrt(10), rel=1e-4)
    assert 0 < design["rank_out_of_sample"] <= design["rank_after_fit"] <= design["columns"]
    # Scanned effects say where they were judged, and give the range over the scan.
    cyclic = rows["b_axis_cyclic"]
    assert cyclic["evaluated_at"] == {"cycles_per_rev": 3.0} and cyclic["over_scan"]["settings"] == 40
    assert (
        cyclic["over_scan"]["absorbed_by_circle_fit"][0]
        <= cyclic["absorbed_by_circle_fit"]
        <= cyclic["over_scan"]["absorbed_by_circle_fit"][1]
    )


def test_a_centre_shift_at_every_orientation_is_absorbed_and_invisible(report):
    rows = by_id(report)
    for effect_id in (CentreShift.id, "stylus_bending"):  # the stylus's bending: size and centre only
        row = rows[effect_id]
        assert row["absorbed_by_circle_fit"] == pytest.approx(1.0, abs=1e-6), effect_id
        assert row["visible"] is False and row["visible_rms_um"] == 0.0 and row["rank_after_fit"] == 0
        assert row["learnable_by_data_model"] is None and row["confounded_with"] == []
    assert rows["noise"]["visible"] is None and rows["noise"]["note"]


def test_the_rings_form_is_seen_and_learnt_by_the_data_model(report):
    form = by_id(report)["ring_form"]
    # The same curve at every orientation: nothing absorbed, reproduced exactly by the lattice.
    assert form["absorbed_by_circle_fit"] < 1e-6 and form["visible"] is True
    assert form["learnable_by_data_model"] > 0.999


def test_lobing_and_the_ball_form_are_confounded_on_the_paper_design(report):
    rows = by_id(report)
    with_ball = {o["effect"]: o for o in rows["lobing"]["confounded_with"]}
    assert with_ball["ball_form"]["shared"] > 0.99 and with_ball["ball_form"]["other_settings"] == {"lobes": 3.0}
    assert {o["effect"] for o in rows["ball_form"]["confounded_with"]} >= {"lobing"}
    # Both depend on A0 alone: seen (from A0 = 15 up), and learnt by the lattice where it has rings.
    for effect_id in ("lobing", "ball_form"):
        assert rows[effect_id]["visible"] is True and rows[effect_id]["learnable_by_data_model"] > 0.99


def test_a_b_axis_error_grows_out_of_the_lattice_with_its_order(report):
    # 3/rev is smooth over the 20-deg B grid; a 22/rev error is not, and the lattice learns little of it.
    over = by_id(report)["b_axis_cyclic"]["over_scan"]
    assert over["visible"] >= 38 and over["learnable_by_data_model"][0] < 0.1


def test_shared_variance_is_the_diagnosis_one(paper):
    touches = campaign_touches(paper)
    smoother = OutOfSampleSmoother(paper.orientations, ~paper.holdout_mask())
    pairs = [
        (DEFAULT_CATALOG["lobing"](), DEFAULT_CATALOG["ball_form"](lobes=3)),
        (DEFAULT_CATALOG["gravity"](), DEFAULT_CATALOG["a_axis_cyclic"](cycles_per_rev=24)),
        (DEFAULT_CATALOG["b_axis_cyclic"](cycles_per_rev=22), DEFAULT_CATALOG["direction"]()),
    ]
    for a, b in pairs:
        designs = [Design(fitted_basis(e, touches)[0], smoother) for e in (a, b)]
        ours = shared_between(effect_bases(a, touches, smoother), effect_bases(b, touches, smoother))
        assert ours == pytest.approx(shared_variance(*designs), abs=1e-6), (a.id, b.id)


def test_one_repetition_has_no_noise_floor_to_judge_visibility_by():
    rng = np.random.default_rng(1)
    orientations = np.array([(a, b) for a in (0.0, 45.0, 90.0) for b in (-120.0, 0.0, 120.0)] + [(30.0, 60.0)])
    campaign = Campaign(orientations, rng.normal(0.0, 0.1, (len(orientations), 1, 32)))
    out = identifiability(campaign, [DEFAULT_CATALOG["ring_form"], DEFAULT_CATALOG["drift"]])
    form, drift = out["effects"]
    assert out["design"]["noise_floor_um"] is None and form["visible"] is None
    assert form["absorbed_by_circle_fit"] < 1e-6
    # Drift needs touch times: not judged, and the note says why.
    assert drift["absorbed_by_circle_fit"] is None and "t_s" in drift["note"]


def test_the_description_of_every_builtin_names_its_parameters():
    for cls in DEFAULT_CATALOG.values():
        row = describe_effect(cls)
        assert row["id"] == cls.id and [p["name"] for p in row["parameters"]] == [p.name for p in cls.parameters]
