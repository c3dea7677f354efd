"""The closed loop of an adaptive campaign on the twin: plan (planning.adaptive), the twin measures,
diagnose, plan the next, until a plan stops. The benchmarks and the explorer run it on a scenario's
head. Method: docs/planning.md.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects import DEFAULT_CATALOG, Catalog
from ph_explorer.planning.adaptive import TP20_SIGMA_UM, first_rings, next_rings, plan_diagnosis
from ph_explorer.planning.plans import Cadence, Plan
from ph_explorer.twin import Scenario, simulate


@dataclass(frozen=True)
class AdaptiveRun:
    """A closed loop on the twin: each plan, the campaign measured so far and its diagnosis."""

    plans: tuple[Plan, ...]
    results: tuple[Diagnosis, ...]  # results[k] diagnosed campaigns[k], measured by plans[: k + 1]
    campaigns: tuple[Campaign, ...]

    @property
    def campaign(self) -> Campaign:
        """The campaign at the stop."""
        return self.campaigns[-1]

    @property
    def stopped(self) -> bool:
        return self.plans[-1].stop


def cadence_of(scenario: Scenario) -> Cadence:
    """The twin's time at the machine: its seconds per touch and per move."""
    return Cadence(scenario.touch_s, scenario.move_s)


def measured_plan(scenario: Scenario, plan: Plan, after: Scenario | None = None) -> tuple[Scenario, Campaign]:
    """The twin's head measured at the plan's rings, after the last touch of `after` (a scenario
    measured before), its check rings named as check orientations: (its scenario, its campaign)."""
    rings = np.array([[r.a_deg, r.b_deg] for r in plan.rings])
    checks = np.array([[r.a_deg, r.b_deg] for r in plan.rings if r.check]).reshape(-1, 2)
    measured = replace((after or scenario).at_rings(rings), repetitions=plan.repetitions, check_orientations=checks)
    if after is None:
        measured = replace(measured, start_s=0.0)
    return measured, simulate(measured)


def adaptive_campaign(
    scenario: Scenario,
    budget_minutes: float | None = None,
    catalog: Catalog = DEFAULT_CATALOG,
    max_plans: int = 12,
    sigma_um: float = TP20_SIGMA_UM,
    tolerance_um: float | None = None,
    diagnose: Callable[[Campaign], Diagnosis] | None = None,
    progress: Callable[[Plan, Diagnosis], None] | None = None,
) -> AdaptiveRun:
    """Plan, measure on the twin, diagnose, plan the next, until a plan stops (or max_plans)."""
    from ph_explorer.io.merge import merged_campaign

    judge = diagnose or (lambda campaign: plan_diagnosis(campaign, catalog))
    cadence = cadence_of(scenario)
    plan = first_rings(budget_minutes, scenario.geometry, sigma_um, cadence, catalog, tolerance_um)
    last, campaign = measured_plan(scenario, plan)
    plans: list[Plan] = [plan]
    results: list[Diagnosis] = []
    campaigns: list[Campaign] = []
    while True:
        result = judge(campaign)
        results.append(result)
        campaigns.append(campaign)
        plan = next_rings(campaign, result, budget_minutes, catalog, cadence, plans[-1].questions, tolerance_um, plans[-1].answer)
        plans.append(plan)
        if progress is not None:
            progress(plan, result)
        if plan.stop or len(plans) > max_plans:
            break
        last, more = measured_plan(scenario, plan, last)
        campaign = merged_campaign(campaign, more, replace=True)[0]  # a ring measured again replaces the old one
    return AdaptiveRun(tuple(plans), tuple(results), tuple(campaigns))
