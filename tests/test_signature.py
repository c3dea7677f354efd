"""The signature of what is left: the out-of-sample residual described in the head's own variables.

On the twin: a hidden B-axis 22/rev error reads as periodic in the B joint at 22 cycles/rev; an
effect outside the catalog (a radial bump over a narrow range of the B joint) reads as localised
there; the paper's campaign (nothing hidden) shows only what its own background leaves, and
nothing once that background is in the model.
"""

from __future__ import annotations

import dataclasses
import tomllib

import numpy as np
import pytest

from ph_explorer.diagnosis.search import NULL_MARGIN, CandidateSearch
from ph_explorer.diagnosis.signature import ALL, Localised, Periodic, Sign, probes, signature
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect, Parameter
from ph_explorer.errors import InputError
from ph_explorer.geometry import wrap_deg
from ph_explorer.kinematics import campaign_touches
from ph_explorer.paths import scenarios_dir
from ph_explorer.twin import load_scenario, scenario_from_dict, simulate

B_CYCLIC = DEFAULT_CATALOG["b_axis_cyclic"]


class CableSnag(Effect):
    """Outside the catalog: the touch reads 0.3 um long while the B joint is within 10 deg of +60."""

    id = "cable_snag"
    name = "Cable snag at one B angle"
    teaching = "A cable pulls the probe while the B joint passes +60 deg."
    parameters = (Parameter("height_um", "um", 0.3, "radial step inside the zone"),)

    def basis(self, touches):
        inside = np.abs(wrap_deg(touches.b_deg - 60.0)) <= 10.0
        return np.broadcast_to(inside.astype(float), touches.shape)[..., None], ["cable_snag"]


def search_of(campaign) -> CandidateSearch:
    return CandidateSearch(campaign, ~campaign.holdout_mask())


@pytest.fixture(scope="module")
def b22():
    search = search_of(simulate(load_scenario("head_3")))
    return search, signature(search)


@pytest.fixture(scope="module")
def paper():
    search = search_of(simulate(load_scenario("paper")))
    return search, signature(search)


def significant(entries):
    return [e for e in entries if e["significant"]]


def test_entries_are_complete_and_best_first(b22):
    _, entries = b22
    names = {(e["variable"], e["kind"]) for e in entries}
    assert {v for v, _ in names} == set(ALL)
    assert len(entries) == 2 * len(ALL)  # periodic + localised per variable, A and B signs for the approach
    for e in entries:
        assert {"variable", "kind", "explained_fraction", "noise_fraction", "significant", "evidence"} <= set(e)
        if e["significant"]:  # the search's own null (figures rounded to 1e-5)
            assert e["explained_fraction"] + 1e-5 >= NULL_MARGIN * e["noise_fraction"] and e["explained_fraction"] > 0
        key = {"periodic": "cycles_per_rev", "localised": "centre_deg", "sign": "joint"}[e["kind"]]
        if e["variable"] == "time_s":
            key = {"periodic": "cycles_per_span", "localised": "centre_s"}[e["kind"]]
        elif e["variable"] == "order_in_repetition":
            key = {"periodic": "cycles_per_span", "localised": "centre_touch"}[e["kind"]]
        assert key in e, (e["variable"], e["kind"])
    ranks = [(e["significant"], e["explained_fraction"]) for e in entries]
    assert ranks == sorted(ranks, reverse=True)
    # A term in the ring angle alone is the same at every ring: the interpolator predicts it.
    assert all(e["explained_fraction"] == 0 and not e["significant"] for e in entries if e["variable"] == "ring_angle_deg")


def test_a_hidden_b_axis_error_reads_periodic_in_the_b_joint_at_its_period(b22):
    search, entries = b22
    top = significant(entries)[0]
    assert (top["variable"], top["kind"], top["cycles_per_rev"]) == ("b_joint_deg", "periodic", 22.0)
    # A joint error moves the ball: it reads as a displacement, not as a radial change.
    assert top["params"]["displacement_um"] > 5 * top["params"]["radial_um"]
    evidence = top["evidence"]
    assert np.corrcoef(evidence["residual"], evidence["fitted"])[0, 1] > 0.9
    # With the error in the model, nothing at 22/rev is left in the B joint.
    after = signature(search, fixed=search.design([B_CYCLIC(cycles_per_rev=22)]), variables=["b_joint_deg"])
    assert not [e for e in significant(after) if e.get("cycles_per_rev") == 22]


def test_an_effect_outside_the_catalog_reads_localised_where_it_acts():
    data = tomllib.loads((scenarios_dir() / "paper.toml").read_text(encoding="utf-8"))
    data["effects"].append({"id": "cable_snag", "hidden": True, "height_um": 0.3})
    catalog = Catalog([*DEFAULT_CATALOG.values(), CableSnag])
    search = search_of(simulate(scenario_from_dict(data, catalog=catalog)))
    entries = signature(search)
    top = significant(entries)[0]
    assert (top["variable"], top["kind"]) == ("b_joint_deg", "localised")
    assert abs(wrap_deg(top["centre_deg"] - 60.0)) <= 10.0
    assert top["width_deg"] <= 10.0
    # A radial step, not a displacement of the ball.
    assert top["params"]["radial_um"] > 2 * top["params"]["displacement_um"]
    assert top["explained_fraction"] > 20 * top["noise_fraction"]


def test_the_paper_campaign_shows_only_its_own_background(paper):
    """Nothing is hidden in the paper's campaign, yet the interpolator does not reproduce all of
    its background: the B-axis 2/rev and 4/rev errors it holds (1.8 and 1.0 arcsec) leave a few
    per cent of the residual beyond pure noise, seen in the B joint at 4/rev, in B0 (4/rev aliased
    on the 20-deg grid) and in time (the rings are scanned one after the other). The signature is
    shown for failing campaigns only; here it must stay small, and vanish once that background is
    in the model."""
    search, entries = paper
    flagged = significant(entries)
    assert max(e["explained_fraction"] for e in entries) < 0.03
    assert {e["variable"] for e in flagged} <= {"b_joint_deg", "b0_deg", "time_s"}
    assert all(e["cycles_per_rev"] == 4.0 for e in flagged if e["variable"] == "b_joint_deg" and e["kind"] == "periodic")
    background = search.design([B_CYCLIC(cycles_per_rev=2), B_CYCLIC(cycles_per_rev=4)])
    after = signature(search, fixed=background, variables=sorted({e["variable"] for e in flagged}))
    assert not significant(after)


def test_probes_are_no_candidates_and_time_needs_touch_times(paper):
    search, _ = paper
    touches = search.touches
    assert not any(cls.candidate for cls in (Periodic, Localised, Sign))
    assert not any(issubclass(cls, (Periodic, Localised, Sign)) for cls in DEFAULT_CATALOG.values())
    names = {p.variable.name for p in probes(ALL, touches)}
    assert "time_s" in names
    untimed = campaign_touches(dataclasses.replace(search.campaign, times_s=None))
    assert {p.variable.name for p in probes(ALL, untimed)} == names - {"time_s"}
    # Columns: a function of the variable times 1, cos theta, sin theta (A0: ring harmonics 2-4).
    widths = {("b_joint_deg", "periodic"): 6, ("b_joint_deg", "localised"): 3, ("a0_deg", "periodic"): 12, ("a0_deg", "localised"): 6}
    for probe in probes(["b_joint_deg", "a0_deg", "approach_direction"], touches):
        columns, labels = probe.basis(touches)
        assert columns.shape[:3] in {touches.shape, (touches.shape[0], 1, touches.shape[2])}
        assert columns.shape[-1] == len(labels) == widths.get((probe.variable.name, probe.kind), 3)
    with pytest.raises(InputError, match="no signature variable"):
        signature(search, variables=["b_joint"])


def test_a_scan_through_the_effects_library_is_the_scan_setting_by_setting(paper, monkeypatch):
    """Drift's 36 settings scored from its library (each distinct column made once) explain what
    they explain when each setting's columns are made on their own, alone and beyond a fixed term."""
    search, _ = paper
    drift = DEFAULT_CATALOG["drift"]()
    fixed = search.design([B_CYCLIC(cycles_per_rev=2)])
    through_library = [search.scan(drift), search.scan(drift, fixed)]
    monkeypatch.setattr(type(drift), "scan_library", lambda self, touches: None)
    one_by_one = [search.scan(drift), search.scan(drift, fixed)]
    for a, b in zip(through_library, one_by_one):
        assert [s for _, s in a.scanned] == [s for _, s in b.scanned]  # the same order of settings
        # Equal but for rounding: products summed in another order, through near-collinear drift columns.
        assert np.allclose([e for e, _ in a.scanned], [e for e, _ in b.scanned], rtol=1e-6)
        assert np.allclose(a.null_best, b.null_best, rtol=1e-6)


def test_a_signature_entry_in_time_says_hours() -> None:
    """A localised entry of the touch time reads in hours (a campaign lasts hours to days), an angle's in deg."""
    from ph_explorer.figures.diagnosis_text import signature_text

    entry = {"variable": "time_s", "kind": "localised", "centre_s": 120645.0, "explained_fraction": 0.006, "noise_fraction": 0.0004}
    assert signature_text(entry) == "time_s localised, at 33.5 h, 0.6 % (0.04 %)"
    angle = entry | {"variable": "b_joint_deg", "centre_deg": -10.0}
    del angle["centre_s"]
    assert signature_text(angle) == "b_joint_deg localised, at -10 deg, 0.6 % (0.04 %)"
    assert "at 74.3 deg," in signature_text(angle | {"centre_deg": 74.348})  # a tenth of a degree, not a float's digits
