"""docs/walkthrough_unknown_effect.md, run: an effect in no catalog -> unexplained, with its
signature -> the user's own effect written from it -> missing, the error at the floor."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ph_explorer.diagnosis import diagnose
from ph_explorer.effects import BUILTIN_EFFECTS, Catalog
from ph_explorer.figures.diagnosis_text import report_text
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
