"""The nested gain (issue 55, item 3, measured; see docs/diagnosis.md): the fall in error of the
rings that took no part in choosing the effects, tested over those rings as a claim's gain is."""

from __future__ import annotations

import json
from dataclasses import replace

from ph_explorer.diagnosis import diagnose
from ph_explorer.diagnosis.replication import Replication
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.figures.diagnosis_text import report_text
from ph_explorer.twin import load_scenario, simulate


def test_the_nested_gain_is_tested_over_the_rings_that_took_no_part_and_reported():
    """head_3's hidden B-axis error, found: on the rings of the nested folds it gains, replicated
    over them, and the report says so; a gain that does not replicate is worded as such; the record
    round-trips the test."""
    result = diagnose(simulate(load_scenario("head_3")))
    assert result.verdict == "missing" and result.nested.gain is not None
    gain = result.nested.gain
    assert result.nested.gain_holds and gain.p_value < 0.05 and gain.rings_gaining > gain.rings / 2
    assert "tested over them" in report_text(result, DEFAULT_CATALOG) and ": replicated" in report_text(result, DEFAULT_CATALOG)
    nil = Replication(p_value=0.6, p_without_top=0.7, rings_gaining=40, rings=80, check_gain=float("nan"), lattice_gain=-0.01)
    weak = replace(result, nested=replace(result.nested, gain=nil))
    assert not weak.nested.gain_holds and "not replicated on these rings" in report_text(weak, DEFAULT_CATALOG)
    data = json.loads(json.dumps(result.to_json()))
    assert data["nested_after"]["gain"]["p_value"] == round(gain.p_value, 5)
    assert Diagnosis.from_json(data).to_json() == data
