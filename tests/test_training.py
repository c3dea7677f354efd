"""`ph-explorer train` and `evaluate`: the model folder, its card, atomic writing, holdouts."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from synthetic import lobing_campaign
from typer.testing import CliRunner

from ph_explorer.cli import app
from ph_explorer.cli.evaluate_command import evaluate_command
from ph_explorer.cli.train_command import parse_holdout, train_command
from ph_explorer.errors import InputError
from ph_explorer.io import read_campaign, sidecar_path, write_campaign
from ph_explorer.models.folder import load_card, load_models
from ph_explorer.models.network import FourierNetwork, NetworkConfig

QUICK = NetworkConfig(max_epochs=8, early_stopping_patience=8)
CHECKS = [(15.0, -20.0), (43.0, 91.0)]


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("data")
    return write_campaign(lobing_campaign(seed=2, check_orientations=CHECKS), folder / "lobing.csv")


@pytest.fixture(scope="module")
def trained(data, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("models") / "lobing"
    assert train_command(data, out, network_config=QUICK, quiet=True, data_part="gp") == 0  # the GP beside them
    return out


def test_train_writes_the_model_folder_and_card(data, trained):
    assert sorted(p.name for p in trained.iterdir()) == ["card.json", "gp.npz", "network.safetensors", "trilinear.npz", "uncertainty.npz"]
    card = load_card(trained)
    import hashlib

    assert card["data"]["sha256"] == hashlib.sha256(data.read_bytes()).hexdigest()
    assert card["holdout"] == [list(c) for c in CHECKS] and card["holdout_source"] == "sidecar check orientations"
    assert card["network"]["K"] == 8 and card["network"]["epochs"] == 8
    assert card["network"]["hyperparameters"]["hidden"] == [256, 256, 128]
    assert card["training_seconds"]["total"] > 0 and card["geometry"]["pivot_to_ball_mm"] == 80.0
    assert set(load_models(trained)) == {"network", "trilinear", "gp"}
    # No held-out ring was seen by either model.
    held = np.array(CHECKS)
    assert not np.isin(card["network"]["validation_orientations"], held).all(axis=1).any()
    assert card["trilinear"]["filled_nodes"] == 1  # A15 B-20 is a lattice node, held out


def test_card_agrees_with_evaluate_json(data, trained, capsys):
    card = load_card(trained)
    assert evaluate_command(trained, data, json_output=True) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["noise_floor_um"] == card["metrics"]["noise_floor_um"]
    assert report["orientations"] == card["metrics"]["orientations"]
    row = report["orientations"][0]
    assert set(row) == {"A_deg", "B_deg", "range_um", "max_abs_um", "mae_um"}
    assert set(row["range_um"]) == {"measured", "network", "trilinear", "gp"}  # the folder holds the GP too
    assert set(row["mae_um"]["network"]) == {"mean", "single"}


def test_evaluate_text_and_cli(data, trained):
    result = CliRunner().invoke(app, ["evaluate", "--model", str(trained), "--data", str(data)])
    assert result.exit_code == 0, result.output
    assert "Table 3" in result.output and "A 43 B 91" in result.output and "noise floor" in result.output
    missing = CliRunner().invoke(app, ["evaluate", "--model", str(trained.parent / "nope"), "--data", str(data)])
    assert missing.exit_code == 2


@pytest.mark.parametrize("text", ["15", "15:-20:3", "a:b", "15:-20,,x", "10:10", ":", "nan:3"])
def test_bad_holdout_strings_are_input_errors(data, text):
    campaign = read_campaign(data)
    with pytest.raises(InputError):
        parse_holdout(text, campaign)


def test_holdout_option_selects_orientations(data):
    campaign = read_campaign(data)
    mask = parse_holdout("75:40, 0:180,0:-180", campaign)
    assert mask.sum() == 2 and campaign.orientations[mask].tolist() == [[0.0, 180.0], [75.0, 40.0]]


def test_interrupted_training_leaves_the_existing_folder_intact(data, trained, tmp_path, monkeypatch):
    out = tmp_path / "model"
    import shutil

    shutil.copytree(trained, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}

    def interrupted(self, campaign, train=None):
        raise KeyboardInterrupt

    monkeypatch.setattr(FourierNetwork, "fit", interrupted)
    with pytest.raises(KeyboardInterrupt):
        train_command(data, out, network_config=QUICK, quiet=True)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert [p.name for p in tmp_path.iterdir()] == ["model"]  # no temporary folder left behind


def test_retraining_replaces_the_folder(data, trained, tmp_path):
    out = tmp_path / "model"
    assert train_command(data, out, holdout="75:40", network_config=QUICK, quiet=True) == 0
    assert train_command(data, out, holdout="45:-20", seed=1, network_config=QUICK, quiet=True) == 0
    card = load_card(out)
    assert card["holdout"] == [[45.0, -20.0]] and card["seed"] == 1 and card["holdout_source"] == "option"
    assert [p.name for p in tmp_path.iterdir()] == ["model"]


def test_a_campaign_without_sidecar_holds_out_the_off_grid_rings(tmp_path):
    """A CSV written by another program (the documented format, no sidecar): holdout = the off-grid orientations."""
    campaign = lobing_campaign(seed=5, n_repetitions=3, extra_orientations=[(43, 91), (20, 50)])
    path = write_campaign(campaign, tmp_path / "other.csv")
    sidecar_path(path).unlink()
    out = tmp_path / "model"
    assert train_command(path, out, network_config=QUICK, quiet=True) == 0
    card = load_card(out)
    assert card["holdout_source"] == "off-grid orientations"
    assert sorted(map(tuple, card["holdout"])) == [(20.0, 50.0), (43.0, 91.0)]
    result = CliRunner().invoke(app, ["evaluate", "--model", str(out), "--data", str(path), "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert len(report["orientations"]) == 2 and report["noise_floor_um"]["mean"] > 0


# -- the paper scenario --------------------------------------------------------------------------
def check_done_when(report: dict) -> None:
    """The issue's figures: single-repetition MAE 0.08-0.22 um at every check ring, and the mean
    of the rings' MAE against the 10-repetition mean within 1.6x its noise floor, for both models."""
    floor = report["noise_floor_um"]["mean"]
    for name in ("network", "trilinear"):
        singles = [row["mae_um"][name]["single"] for row in report["orientations"]]
        assert all(0.08 <= s <= 0.22 for s in singles), (name, singles)
        means = [row["mae_um"][name]["mean"] for row in report["orientations"]]
        assert np.mean(means) <= 1.6 * floor, (name, np.mean(means), floor)


def test_shipped_paper_model_card_agrees_with_evaluate(capsys):
    """assets/models/paper was trained on assets/data/paper.csv: its card is what evaluate computes from it."""
    from ph_explorer.paths import assets_dir, default_model_dir

    model, data = default_model_dir(), assets_dir() / "data" / "paper.csv"
    card = load_card(model)
    import hashlib

    assert card["data"]["sha256"] == hashlib.sha256(data.read_bytes()).hexdigest()
    assert evaluate_command(model, data, json_output=True) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["noise_floor_um"] == card["metrics"]["noise_floor_um"]
    assert report["orientations"] == card["metrics"]["orientations"]
    assert len(report["orientations"]) == 12
    check_done_when(report)
    assert card["training_seconds"]["total"] < 180


@pytest.mark.slow
def test_paper_scenario_end_to_end(tmp_path):
    """simulate --scenario paper -> train -> evaluate --json, through the CLI."""
    runner = CliRunner()
    data = tmp_path / "paper.csv"
    assert runner.invoke(app, ["simulate", "--scenario", "paper", "--out", str(data)]).exit_code == 0
    # The paper's training stops early at its best epoch (115 for the shipped model): a cap above
    # it gives the same network, and the folds of its model error train no longer than it.
    cap = 200
    result = runner.invoke(app, ["train", "--data", str(data), "--out", str(tmp_path / "model"), "--max-epochs", str(cap)])
    assert result.exit_code == 0, result.output
    assert load_card(tmp_path / "model")["network"]["best_epoch"] < cap - 40  # well before the cap: the cap chose nothing
    result = runner.invoke(app, ["evaluate", "--model", str(tmp_path / "model"), "--data", str(data), "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert [(r["A_deg"], r["B_deg"]) for r in report["orientations"]][:3] == [(15.0, -20.0), (45.0, -20.0), (75.0, 40.0)]
    check_done_when(report)


def test_a_campaign_of_single_repetitions_trains_and_evaluates(tmp_path):
    """No repetitions: no measured spread; the floor is reported as unknown (null), not NaN."""
    path = write_campaign(lobing_campaign(seed=6, n_repetitions=1), tmp_path / "single.csv")
    out = tmp_path / "model"
    assert train_command(path, out, network_config=QUICK, quiet=True) == 0
    result = CliRunner().invoke(app, ["evaluate", "--model", str(out), "--data", str(path), "--json"])
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["noise_floor_um"] == {"mean": None, "single": None}
    row = report["orientations"][0]
    assert row["mae_um"]["trilinear"]["mean"] == row["mae_um"]["trilinear"]["single"] > 0
    text = CliRunner().invoke(app, ["evaluate", "--model", str(out), "--data", str(path)])
    assert text.exit_code == 0 and "n/a" in text.output


def test_train_cli_rejects_bad_options_with_one_line(data, tmp_path):
    runner = CliRunner()
    bad = runner.invoke(app, ["train", "--data", str(data), "--out", str(tmp_path / "m"), "--holdout", "15;-20"])
    assert bad.exit_code == 2 and "--holdout" in bad.output and "Traceback" not in bad.output
    (tmp_path / "file").write_text("x")
    clash = runner.invoke(app, ["train", "--data", str(data), "--out", str(tmp_path / "file")])
    assert clash.exit_code == 2 and (tmp_path / "file").read_text() == "x"
    assert not (tmp_path / "m").exists()


def test_max_epochs_caps_the_networks_training(data, tmp_path):
    out = tmp_path / "short"
    result = CliRunner().invoke(app, ["train", "--data", str(data), "--out", str(out), "--max-epochs", "3"])
    assert result.exit_code == 0, result.output
    assert load_card(out)["network"]["epochs"] == 3
    bad = CliRunner().invoke(app, ["train", "--data", str(data), "--out", str(tmp_path / "none"), "--max-epochs", "0"])
    assert bad.exit_code == 2 and "--max-epochs" in bad.output and not (tmp_path / "none").exists()


def test_train_with_the_gp_data_part_writes_it_and_its_own_error(data, trained, tmp_path):
    """`train --data-part gp` (the `trained` folder): the Gaussian process beside the two models, its
    kernel on the card, its error from its posterior (read back with its model), in evaluate's tables
    and in `uncertainty`; an unknown part is one line and nothing is written."""
    from ph_explorer.uncertainty.model_error import PosteriorError, load_errors

    assert "Matern" in load_card(trained)["gp"]["kernel"]
    models = load_models(trained)
    errors, _ = load_errors(trained, models)
    assert isinstance(errors["gp"], PosteriorError) and errors["gp"].model is models["gp"]
    assert "gp" not in load_errors(trained)[0]  # without its model a posterior's error cannot be read
    runner = CliRunner()
    report = json.loads(runner.invoke(app, ["evaluate", "--model", str(trained), "--data", str(data), "--json"]).stdout)
    assert set(report["orientations"][0]["mae_um"]) == {"network", "trilinear", "gp"}
    quick = ["--digits", "1", "--seed", "1"]  # a quick look: which models have a band, not its last digit
    bands = runner.invoke(app, ["uncertainty", "--model", str(trained), "--orientations", "43:91", "--json", *quick])
    assert bands.exit_code == 0, bands.output
    assert [b["model"] for b in json.loads(bands.stdout)["bands"]] == ["network", "trilinear", "gp"]
    bad = runner.invoke(app, ["train", "--data", str(data), "--out", str(tmp_path / "other"), "--data-part", "forest"])
    assert bad.exit_code == 2 and "--data-part" in bad.output and not (tmp_path / "other").exists()
