"""`ph-explorer simulate`: write a scenario's (or a random head's) campaign CSV and sidecar, or list
the shipped scenarios; with --adaptive, the campaign an adaptive campaign measures on the head's
twin until its stop (planning.closed_loop), each plan printed as `design --next` words it."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from ph_explorer import twin
from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.io import checked_output_file, write_campaign
from ph_explorer.twin.random_heads import design_of, random_campaign, random_head

if TYPE_CHECKING:
    from ph_explorer.diagnosis.results import Diagnosis
    from ph_explorer.effects import Effect
    from ph_explorer.planning.plans import Plan


def simulate_command(
    scenario: str | None = None,
    out: Path | None = None,
    seed: int | None = None,
    list_scenarios: bool = False,
    random_head: str | None = None,
    design: str | None = None,
    hidden_effect: str | None = None,
    strength: str | None = None,
    rings: Path | None = None,
    adaptive: bool = False,
    budget_minutes: float | None = None,
) -> int:
    """Simulate the scenario (seed: default the scenario's), or a random head, into out; or list the scenarios."""
    if list_scenarios:
        for line in scenario_lines():
            print(line)
        return 0
    if rings is not None and scenario is None:
        raise InputError("measures a scenario's head at other rings: give --scenario NAME|PATH", option="--rings")
    if random_head is None:
        for value, option in ((design, "--design"), (hidden_effect, "--hidden-effect"), (strength, "--strength")):
            if value is not None:
                raise InputError("is for a random head: give --random-head SEED", option=option)
    elif scenario is not None:
        raise InputError("give either --scenario or --random-head, not both", option="--random-head")
    if scenario is None and random_head is None:
        raise InputError("give --scenario NAME|PATH (see --list) or --random-head SEED", option="--scenario")
    if out is None:
        raise InputError("give --out FILE.csv", option="--out")
    out = checked_output_file(out, "--out", "the campaign", "campaign.csv")  # as every command's output: no folder made
    if adaptive:
        if rings is not None:
            raise InputError("measures the rings its plans choose: give --adaptive or --rings, not both", option="--rings")
        head = random_head_of(random_head, design, hidden_effect, strength) if random_head is not None else scenario_of(scenario)
        return adaptive_command(head if seed is None else replace(head, seed=int(seed)), out, budget_minutes)
    if budget_minutes is not None:
        raise InputError("is the time an adaptive campaign may take: give --adaptive", option="--budget-minutes")
    if random_head is not None:
        campaign = random_campaign_of(random_head, design, hidden_effect, strength)
        hidden = len(campaign.scenario["hidden"])
        name, checks = campaign.scenario["name"], len(campaign.check_orientations)
    else:
        loaded = scenario_of(scenario)
        if rings is not None:
            loaded, seed = rings_of(loaded, rings, seed)
        campaign = twin.simulate(loaded, seed)
        hidden, name, checks = len(loaded.hidden_ids), loaded.name, len(loaded.check_orientations)
    path = write_campaign(campaign, out)
    # Spoiler-free: a student may run this; the sidecar's [scenario] hidden list holds the answer.
    hidden_text = f"{hidden} (listed under [scenario] hidden in {path.with_suffix('.toml').name})" if hidden else "none"
    print(
        f"{path}: scenario {name}, seed {campaign.scenario['seed']}, {campaign.n_orientations} orientations x "
        f"{campaign.n_repetitions} repetitions x {campaign.n_points} points, {checks} check "
        f"orientations, hidden effects: {hidden_text}"
    )
    return 0


def random_campaign_of(seed: str, design: str | None, hidden_effect: str | None, strength: str | None) -> Campaign:
    """The random head's campaign from the options as given (each checked, one line naming it)."""
    number, design, hidden = random_head_options(seed, design, hidden_effect, strength)
    return random_campaign(number, design, hidden)


def random_head_of(seed: str, design: str | None, hidden_effect: str | None, strength: str | None) -> twin.Scenario:
    """The random head's scenario from the options as given (random_campaign_of's head)."""
    return random_head(*random_head_options(seed, design, hidden_effect, strength))


def random_head_options(seed: str, design: str | None, hidden_effect: str | None, strength: str | None) -> tuple[int, str, list[Effect]]:
    """(seed, design, hidden effects) of a random head from the options as given (each checked, one line naming it)."""
    try:
        number = int(seed)
    except ValueError:
        raise InputError(f"must be an integer seed, got {seed!r}", option="--random-head") from None
    design = design_of(number, design)
    if hidden_effect is None:
        if strength is not None:
            raise InputError("sets the size of a hidden effect: give --hidden-effect ID", option="--strength")
        return number, design, []
    # The diagnosis's machinery only when a hidden effect is asked for: the command stays light.
    from ph_explorer.diagnosis.detection import hidden_effect_of

    size = None
    if strength is not None:
        try:
            size = float(strength)
        except ValueError:
            raise InputError(f"must be a number, got {strength!r}", option="--strength") from None
    return number, design, [hidden_effect_of(number, hidden_effect, size, design)[0]]


def adaptive_command(head: twin.Scenario, out: Path, budget_minutes: float | None) -> int:
    """simulate --adaptive: the head measured plan by plan on its twin until a plan stops; each
    plan's words as it comes, the campaign at the stop written to out."""
    if budget_minutes is not None and not (math.isfinite(budget_minutes) and budget_minutes > 0):
        raise InputError(f"must be a positive number, got {budget_minutes:g}", option="--budget-minutes")
    from ph_explorer.planning.closed_loop import adaptive_campaign

    def show(plan: Plan, result: Diagnosis) -> None:
        print(f"verdict {result.verdict}; " + "\n".join(plan.lines()), flush=True)

    run = adaptive_campaign(head, budget_minutes, progress=show)
    campaign = run.campaign
    path = write_campaign(campaign, out)
    state = "stopped" if run.stopped else f"not stopped after {len(run.plans) - 1} plans"
    print(
        f"{path}: scenario {head.name} measured adaptively, {state}: {campaign.n_orientations} orientations "
        f"({int(campaign.holdout_mask().sum())} check) x {campaign.n_repetitions} repetitions x {campaign.n_points} points, "
        f"{run.plans[-1].spent_minutes:.0f} minutes at the machine"
    )
    return 0


def scenario_of(name_or_path: str) -> twin.Scenario:
    """--scenario's head (twin.load_scenario), its error naming the option where no file does."""
    try:
        return twin.load_scenario(name_or_path)
    except InputError as error:
        if error.file is None and error.option is None:
            raise InputError(error.message, option="--scenario") from None
        raise


def scenario_lines() -> list[str]:
    """The shipped scenarios, 'name  purpose' with the names aligned (the description: --scenario's run)."""
    shipped = twin.list_scenarios()
    width = max((len(s.name) for s in shipped), default=0)
    return [f"{s.name:<{width}}  {s.purpose or s.description}" for s in shipped]


def rings_of(scenario: twin.Scenario, rings: Path, seed: int | None) -> tuple[twin.Scenario, int | None]:
    """The scenario's head at the file's rings, after its campaign (Scenario.at_rings), from the
    campaign of `seed` (default: the scenario's); every ring a check ring unless the file's check
    column says which are."""
    from ph_explorer.io.rings import read_planned_rings

    orientations, check = read_planned_rings(rings)
    base = scenario if seed is None else replace(scenario, seed=int(seed))
    measured = base.at_rings(orientations)
    if check is not None:  # a plan's file (design --start, --next) says which rings are check rings
        measured = replace(measured, check_orientations=orientations[check])
    return measured, None
