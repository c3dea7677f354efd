"""The paper's Tables 1-3 and the noise floors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from synthetic import lobing_campaign, systematic_curves

from ph_explorer.cli.evaluate_command import format_report
from ph_explorer.metrics import noise_floor
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.paper.tables import evaluation_report, mean_mae, orientation_tables
from tests.command_line import run_cli


class Oracle(DeviationModel):
    """A perfect model: the campaign's true systematic curves."""

    name = "oracle"

    def fit(self, campaign, train=None):
        return self

    def predict(self, orientations, n_points=None):
        return systematic_curves(orientations, n_points or 64)

    def repetition_sigma(self, orientations, n_points=None):
        return np.full((len(np.reshape(orientations, (-1, 2))), n_points or 64), 0.175)

    def save(self, directory):
        return Path(directory)

    @classmethod
    def load(cls, directory):
        return cls()


def test_noise_floor_values():
    floor = noise_floor(0.175, 10)
    assert floor["single"] == pytest.approx(0.175 * math.sqrt(2 / math.pi))
    assert floor["single"] == pytest.approx(0.1396, abs=1e-4)  # physics.md: 0.80 sigma = 0.14 um
    assert floor["mean"] == pytest.approx(floor["single"] / math.sqrt(10))


def test_the_noise_floor_is_kept_until_the_deviations_change():
    """A diagnosis asks for the law and the floor at every step: kept, but an edit in place is seen."""
    campaign = lobing_campaign(seed=3, n_repetitions=4)
    first = campaign.noise_floor_um()
    single = first["single"]
    first["mean"] = -1.0  # a caller's copy: the kept floor is not touched
    assert campaign.noise_floor_um()["mean"] > 0 and campaign.noise_law() is campaign.noise_law()
    campaign.deviations[:, 0] += 0.5 * np.random.default_rng(1).standard_normal(campaign.deviations[:, 0].shape)
    assert campaign.noise_floor_um()["single"] > 1.5 * single


@pytest.mark.parametrize("dof", [0.0, 3.0, 5.0])
def test_a_perfect_model_sits_on_the_noise_floor(dof):
    """Gaussian touch noise, or Student-t's heavier tails (E|e| 0.64 sigma at 3 degrees of freedom,
    0.73 at 5, not the Gaussian's 0.80): the floor reads the law from the repetitions. A residual
    about the repetition mean is partly the other repetitions' mean, near Gaussian: the law it reads
    is a little nearer the Gaussian, so a heavy tail's floor is a little high, never low."""
    campaign = lobing_campaign(seed=3, n_repetitions=10, dof=dof)
    everything = np.ones(campaign.n_orientations, bool)
    report = evaluation_report(campaign, {"oracle": Oracle()}, everything)
    average = mean_mae(report)["oracle"]
    floor = report["noise_floor_um"]
    # 127 orientations x 64 points x 10 repetitions: the averages are within a few percent of E|e|.
    assert 0.95 * floor["single"] <= average["single"] <= 1.03 * floor["single"]
    assert average["mean"] == pytest.approx(floor["mean"], rel=0.05)
    gaussian = noise_floor(campaign.noise_sigma_um(), 10)["single"]
    assert (gaussian > 1.15 * average["single"]) == (dof == 3.0)  # the Gaussian's floor, 26 % above at 3


def test_tables_at_the_default_holdout_follow_the_paper():
    campaign = lobing_campaign(seed=4, extra_orientations=[(43, 91), (20, 50)])
    model = TrilinearModel().fit(campaign, ~campaign.holdout_mask())
    rows = orientation_tables(campaign, {"trilinear": model, "oracle": Oracle()})
    assert [(r["A_deg"], r["B_deg"]) for r in rows] == [(43.0, 91.0), (20.0, 50.0)]
    for row, index in zip(rows, [campaign.index_of(43, 91), campaign.index_of(20, 50)]):
        mean = campaign.deviations[index].mean(axis=0)
        assert row["range_um"]["measured"] == pytest.approx(np.ptp(mean), abs=1e-5)
        assert row["max_abs_um"]["measured"] == pytest.approx(np.abs(mean).max(), abs=1e-5)
        predicted = model.predict([[row["A_deg"], row["B_deg"]]])[0]
        assert row["range_um"]["trilinear"] == pytest.approx(np.ptp(predicted), abs=1e-5)
        eps = predicted[None, :] - campaign.deviations[index]
        assert row["mae_um"]["trilinear"]["single"] == pytest.approx(np.abs(eps).mean(), abs=1e-5)
        assert row["mae_um"]["trilinear"]["mean"] == pytest.approx(np.abs(predicted - mean).mean(), abs=1e-5)
        # Against single repetitions a model always does worse than against their mean.
        assert row["mae_um"]["trilinear"]["single"] > row["mae_um"]["trilinear"]["mean"]
    text = format_report(evaluation_report(campaign, {"trilinear": model}))
    assert "Table 1" in text and "Table 3" in text and "A 43 B 91" in text and "noise floor" in text


def test_evaluate_says_in_one_line_when_the_model_was_trained_on_another_file(tmp_path):
    from ph_explorer.paths import assets_dir

    model = assets_dir() / "models" / "paper"
    other = tmp_path / "head_3.csv"
    assert run_cli("simulate", "--scenario", "head_3", "--out", other).returncode == 0
    result = run_cli("evaluate", "--model", model, "--data", other)
    assert result.returncode == 0 and "Table 1" in result.stdout
    warnings = [line for line in result.stderr.splitlines() if "warning" in line]
    assert len(warnings) == 1 and "trained on paper.csv" in warnings[0] and "not on head_3.csv" in warnings[0]
    strict = run_cli("evaluate", "--model", model, "--data", other, "--strict")
    assert strict.returncode == 2 and "not on head_3.csv" in strict.stderr and len(strict.stderr.strip().splitlines()) == 1
    same = run_cli("evaluate", "--model", model, "--data", assets_dir() / "data" / "paper.csv", "--strict")
    assert same.returncode == 0 and "warning" not in same.stderr


def test_the_explorer_and_the_report_note_a_model_trained_on_another_file(tmp_path):
    from ph_explorer.io import read_campaign
    from ph_explorer.models.folder import campaign_models
    from ph_explorer.paths import assets_dir

    other = tmp_path / "head_3.csv"
    assert run_cli("simulate", "--scenario", "head_3", "--out", other).returncode == 0
    notes = campaign_models(read_campaign(other), assets_dir() / "models" / "paper")[2]
    assert any(n.startswith("warning: the model was trained on paper.csv") and "head_3.csv" in n for n in notes)
    notes = campaign_models(read_campaign(assets_dir() / "data" / "paper.csv"), assets_dir() / "models" / "paper")[2]
    assert not any(n.startswith("warning") for n in notes)
