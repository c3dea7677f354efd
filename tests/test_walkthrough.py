"""docs/walkthrough_unknown_effect.md, run: an effect in no catalog -> a shape and its signature ->
the user's own effect written from it -> missing, the error at the floor; and
docs/walkthrough_shape.md: a shape found, exported, added, every figure it quotes as printed."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from command_line import run_cli

from ph_explorer.diagnosis import diagnose
from ph_explorer.effects import BUILTIN_EFFECTS, Catalog
from ph_explorer.figures.diagnosis_text import report_text
from ph_explorer.io import write_campaign
from ph_explorer.twin import load_scenario, simulate

WALKTHROUGH = Path(__file__).resolve().parent.parent / "docs" / "walkthrough_unknown_effect.md"


def user_effect_source() -> str:
    """The effect of step 3, as the walk-through prints it."""
    text = WALKTHROUGH.read_text(encoding="utf-8")
    block = re.findall(r"```python\n(.*?)```", text, flags=re.S)[1]
    return "\n".join(line[3:] if line.startswith("   ") else line for line in block.splitlines()) + "\n"


@pytest.mark.slow
def test_the_loop_closes_on_an_effect_in_no_catalog(tmp_path):
    campaign = simulate(load_scenario("head_3"))
    lacking = Catalog([cls for cls in BUILTIN_EFFECTS if cls.axis != "B"])

    first = diagnose(campaign, catalog=lacking)
    assert first.verdict == "uncatalogued" and first.within_noise["baseline"].fails and not first.found
    assert first.claimed_shapes[0].group == "b_angular"  # a shape no catalog holds, on the right axis
    top = next(entry for entry in first.signature if entry["significant"])
    assert (top["variable"], top["kind"], top["cycles_per_rev"]) == ("b_joint_deg", "periodic", 22)
    assert "b_joint_deg periodic, 22 cycles/rev" in report_text(first, lacking)

    effects_file = tmp_path / "my_effects.py"
    effects_file.write_text(user_effect_source())
    mine = lacking.with_file(effects_file)
    second = diagnose(campaign, catalog=mine)
    assert second.verdict == "missing" and [c.effect for c in second.found] == ["b_wobble"]
    amplitude = (second.found[0].params["sin_arcsec"] ** 2 + second.found[0].params["cos_arcsec"] ** 2) ** 0.5
    assert amplitude == pytest.approx(1.0, rel=0.1)
    final = second.steps[-1]
    assert final.mae_um["mean"] <= 1.3 * final.noise_floor_um["mean"]
    assert report_text(second, mine).startswith("Verdict: missing - b_wobble or a shape: angular positioning of the B axis")
    # The command line adds the effect to the whole catalog, which holds it: one effect, two names.
    csv = write_campaign(campaign, tmp_path / "b22.csv")
    printed = run_cli("diagnose", "--data", csv, "--effects", effects_file)
    assert printed.returncode == 0, printed.stderr
    verdict = next(line for line in printed.stdout.splitlines() if line.startswith("Verdict"))
    # As the walkthrough quotes it.
    assert verdict.startswith(
        "Verdict: missing - b_wobble or b_axis_cyclic 22 cycles/rev or a shape: angular positioning of the B axis (these rings cannot tell)"
    )
    assert "b_axis_cyclic 22 cycles/rev, which explains 100 % of what this campaign shows of b_wobble" in printed.stdout
    assert "no measurement tried here separates them, so the name stays a pair" in printed.stdout


SHAPE_WALKTHROUGH = WALKTHROUGH.parent / "walkthrough_shape.md"


def quoted_blocks(path: Path, language: str) -> list[str]:
    """The walk-through's code blocks of one language, unindented as a user would copy them."""
    blocks = re.findall(rf"```{language}\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)
    return ["\n".join(line[3:] if line.startswith("   ") else line for line in block.splitlines()) + "\n" for block in blocks]


@pytest.mark.slow
def test_the_shape_walkthrough_says_what_the_commands_print(tmp_path, monkeypatch):
    # Step 1 as printed makes the campaign; steps 2 and 4 run the commands it prints, and every
    # figure the page quotes is what they print.
    monkeypatch.chdir(tmp_path)
    exec(compile(quoted_blocks(SHAPE_WALKTHROUGH, "python")[0], "walkthrough_shape.md", "exec"), {})
    first, again = (run_cli(*command.split()[1:]) for command in quoted_blocks(SHAPE_WALKTHROUGH, "bash"))
    assert first.returncode == 0 and again.returncode == 0, first.stderr + again.stderr
    for line in quoted_blocks(SHAPE_WALKTHROUGH, "text")[0].splitlines():
        if line.strip() and "..." not in line:
            assert " ".join(line.split()) in " ".join(first.stdout.split()), line
    assert "b_joint_deg periodic, 30 cycles/rev" in first.stdout and "75 of 135 rings exceed their noise" in first.stdout
    for report in (first.stdout, again.stdout):
        assert "baseline (trilinear)                               mean 0.131" in report
        assert "+ shape_b_angular (hybrid, trilinear data part)    mean 0.070 (floor 0.055)" in report
    assert "Read shapes.toml: shape_b_angular; added to the model: shape_b_angular." in again.stderr
    assert "b_axis_cyclic (amplitude" in first.stdout and "it does not survive leaving out its most influential ring" in first.stdout
