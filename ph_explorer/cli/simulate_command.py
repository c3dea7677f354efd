"""`ph-explorer simulate`: write a scenario's campaign CSV and sidecar, or list the shipped scenarios."""

from __future__ import annotations

from pathlib import Path

from ph_explorer import twin
from ph_explorer.errors import InputError
from ph_explorer.io import write_campaign


def simulate_command(
    scenario: str | None = None,
    out: Path | None = None,
    seed: int | None = None,
    list_scenarios: bool = False,
) -> int:
    """Simulate the scenario (seed: default the scenario's) into out, or list the scenarios, one per line."""
    if list_scenarios:
        for line in scenario_lines():
            print(line)
        return 0
    if scenario is None:
        raise InputError("give --scenario NAME|PATH (see --list)", option="--scenario")
    if out is None:
        raise InputError("give --out FILE.csv", option="--out")
    loaded = twin.load_scenario(scenario)
    campaign = twin.simulate(loaded, seed)
    path = write_campaign(campaign, out)
    # Spoiler-free: a student may run this; the sidecar's [scenario] hidden list holds the answer.
    n_hidden = len(loaded.hidden_ids)
    hidden = f"{n_hidden} (listed under [scenario] hidden in {path.with_suffix('.toml').name})" if n_hidden else "none"
    print(
        f"{path}: scenario {loaded.name}, seed {campaign.scenario['seed']}, {campaign.n_orientations} orientations x "
        f"{campaign.n_repetitions} repetitions x {campaign.n_points} points, {len(loaded.check_orientations)} check "
        f"orientations, hidden effects: {hidden}"
    )
    return 0


def scenario_lines() -> list[str]:
    """The shipped scenarios, 'name  description' with the names aligned."""
    shipped = twin.list_scenarios()
    width = max((len(name) for name, _ in shipped), default=0)
    return [f"{name:<{width}}  {description}" for name, description in shipped]
