"""Effects' fitted columns made once per campaign and shared by the nested folds' searches
(ph_explorer.diagnosis.fitted_bases)."""

from __future__ import annotations

import numpy as np

from ph_explorer.diagnosis.fitted_bases import FittedBases
from ph_explorer.diagnosis.loop import DEFAULT_CATALOG
from ph_explorer.kinematics import campaign_touches
from ph_explorer.twin import load_scenario, simulate


def test_a_folds_scan_library_is_the_campaigns_at_its_rings_and_is_made_once(monkeypatch):
    campaign = simulate(load_scenario("paper"))
    touches = campaign_touches(campaign)
    fresh = FittedBases(touches, keep=False)
    effects = [cls() for cls in DEFAULT_CATALOG.candidates().values()]
    with_library = [e for e in effects if fresh.library(e) is not None]
    assert with_library  # the catalog scans some effect (drift's histories) from one library
    made: list[str] = []
    for effect in with_library:
        scan = type(effect).scan_library
        monkeypatch.setattr(type(effect), "scan_library", lambda self, t, scan=scan: made.append(self.id) or scan(self, t))
    shared = FittedBases(touches)
    rng = np.random.default_rng(0)
    for _fold in range(3):
        rings = np.sort(rng.choice(campaign.n_orientations, campaign.n_orientations - 20, replace=False))
        for effect in with_library:
            columns, indices = shared.subset(rings).library(effect)
            expected, expected_indices = fresh.library(effect)
            assert np.array_equal(columns, expected[rings]) and all(map(np.array_equal, indices, expected_indices))
            assert columns.flags.writeable  # the search's own copy: its design may take it over in place
    # Made once by the shared bases (the first fold), once per call by the bases that keep nothing.
    assert sorted(made) == sorted([e.id for e in with_library] * (1 + 3))
