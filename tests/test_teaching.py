"""Spoiler-free teaching (issue 15, item 5): what a student sees of a shipped teaching scenario —
`simulate --list`, `simulate --out`, `inspect` (text and JSON) and the explorer's messages — names
none of its hidden effects; the sidecar's hidden list keeps the answer; Reveal shows it next to
what the session found.

A scenario's name is the handle a student types, and is left out of the check: three older names
(head_3, head_4, head_5) still hint at their answer (docs/twin.md, "Shipped scenarios").
"""

from __future__ import annotations

import json
import re

import pytest
from fake_browser import open_session, wait_for
from synthetic import lobing_campaign

from ph_explorer import twin
from ph_explorer.app.dataset import dataset_for
from ph_explorer.app.server import ExplorerApp
from ph_explorer.cli.inspect_command import inspect_command
from ph_explorer.cli.simulate_command import simulate_command
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.io import read_campaign

TEACHING = [s.name for s in twin.list_scenarios() if s.hidden_ids]


def spoilers(name: str) -> set[str]:
    """What would name a scenario's hidden effects: their ids, their names, and the telling parts of the ids."""
    words: set[str] = set()
    for effect_id in twin.load_scenario(name).hidden_ids:
        words |= {effect_id, DEFAULT_CATALOG[effect_id].name}
        words |= {part for part in effect_id.split("_") if len(part) > 3 and part != "axis"}
    return words


def named(text: str, name: str) -> list[str]:
    """The spoilers of scenario `name` that `text` contains as words."""
    text = text.lower()
    return [w for w in spoilers(name) if re.search(rf"(?<![a-z]){re.escape(w.lower())}(?![a-z])", text)]


def test_there_are_teaching_scenarios_and_the_check_would_catch_a_spoiler() -> None:
    assert len(TEACHING) >= 4
    assert set(named("a hidden 22/rev B-axis cyclic angular error", "head_3")) == {"cyclic", "B-axis cyclic angular error"}
    assert named("lost motion: Lost motion by direction of approach", "head_5")


@pytest.mark.parametrize("name", TEACHING)
def test_the_command_line_names_no_hidden_effect(name: str, tmp_path, capsys) -> None:
    simulate_command(list_scenarios=True)
    listed = capsys.readouterr().out
    assert name in listed and not named(listed, name), named(listed, name)
    out = tmp_path / "campaign.csv"
    simulate_command(scenario=name, out=out)
    printed = capsys.readouterr().out
    assert "hidden effects: 1" in printed and not named(printed, name), named(printed, name)
    # The answer lives in the sidecar's hidden list.
    assert read_campaign(out).scenario["hidden"] == twin.load_scenario(name).hidden_ids
    inspect_command(out)
    text = capsys.readouterr().out
    assert "hidden effects" in text and not named(text, name), named(text, name)
    inspect_command(out, json_output=True)
    summary = capsys.readouterr().out
    assert json.loads(summary)["scenario"]["hidden_effects"] == 1 and not named(summary, name), named(summary, name)


@pytest.fixture(scope="module")
def app():
    explorer = ExplorerApp(dataset_for(lobing_campaign(seed=4, n_repetitions=3), "synthetic", None), port=0)
    yield explorer
    explorer.stop()


def test_the_explorer_names_no_hidden_effect_until_reveal(app) -> None:
    fake, s = open_session(app)
    try:
        for name in TEACHING:
            s.load_scenario(name)
            assert name in s.data_panel.source.content
            messages = [
                s.data_panel.message.content,
                s.data_panel.source.content,
                s.ring.title,
                s.physics.status.content,
                s.physics.summary.content,
                s.physics.revealed.content,
                s.polar.plot.content,
            ]
            for text in messages:
                assert not named(text, name), (name, named(text, name), text)
            # Reveal: the truth (the hidden effect and its parameters), here before any diagnosis.
            fake.click("Reveal the hidden effect")
            assert wait_for(lambda: "truth" in s.physics.revealed.content)
            revealed = s.physics.revealed.content
            for entry in [e for e in s.dataset.campaign.scenario["effects"] if e["hidden"]]:
                cls = DEFAULT_CATALOG[entry["id"]]
                truth = {k: v for k, v in entry.items() if k not in ("id", "hidden")}
                assert cls.name in revealed and f"`{entry['id']}`" in revealed
                assert f"truth: {cls.parameters_text(truth)}" in revealed, revealed
            assert "not diagnosed yet" in revealed
    finally:
        s.wait(timeout=120)
        fake.close()
