"""The hybrid keeps only the physical terms the data can carry (hybrid.carried_effects), chosen by
its own cross-validation: the project's one (crossval.cross_val_predict)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.data_efficiency import lattice_subsets
from ph_explorer import metrics
from ph_explorer.campaign import Campaign
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.models.crossval import cross_val_predict
from ph_explorer.models.hybrid import carried_effects, cross_validated_mae
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.twin import load_scenario, simulate


@pytest.fixture(scope="module")
def three_columns() -> Campaign:
    """The paper campaign's training rings on 7 A rows x 3 B columns (21 rings)."""
    scenario = load_scenario("paper")
    campaign = simulate(scenario, scenario.seed)
    mask = lattice_subsets(campaign, ~campaign.holdout_mask(), (3,))[0]
    return campaign.subset(mask)


def test_no_effect_is_the_data_part_cross_validated_as_any_model(three_columns: Campaign) -> None:
    every = np.ones(three_columns.n_orientations, dtype=bool)
    direct = cross_val_predict(TrilinearModel, three_columns, every, strict=True)
    expected = metrics.mae(direct, three_columns.deviations)["mean"]
    assert cross_validated_mae([], three_columns, every) == pytest.approx(expected, rel=1e-9)


def test_a_term_the_data_carries_is_kept_one_it_does_not_is_dropped(three_columns: Campaign) -> None:
    """B 4/rev: what three B columns 120 deg apart cannot interpolate (the B errors of the head);
    the seat lobing: the lattice's rows learn it already."""
    cyclic, lobing = DEFAULT_CATALOG["b_axis_cyclic"](cycles_per_rev=4), DEFAULT_CATALOG["lobing"]()
    kept, path = carried_effects(three_columns, [cyclic, lobing])
    assert [e.id for e in kept] == ["b_axis_cyclic"]
    scores = {tuple(p["effects"]): p["cv_mae_um"] for p in path}
    assert scores[("b_axis_cyclic cycles_per_rev 4",)] < 0.7 * scores[()]  # the data part alone, compared too


def test_on_touch_noise_alone_nothing_is_kept(three_columns: Campaign) -> None:
    rng = np.random.default_rng(5)
    noise = remove_size_and_centre(rng.normal(0.0, 0.175, three_columns.deviations.shape))
    campaign = Campaign(three_columns.orientations, noise, geometry=three_columns.geometry)
    effects = [DEFAULT_CATALOG["b_axis_cyclic"](cycles_per_rev=4), DEFAULT_CATALOG["lobing"]()]
    kept, path = carried_effects(campaign, effects)
    assert kept == []
