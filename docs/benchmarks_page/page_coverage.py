"""The benchmarks page's `## Uncertainty coverage` section (`uncertainty_coverage`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import get, interval, num, table

COVERAGE_INTRO = """\
## Uncertainty coverage

`uncertainty_coverage`: do the Monte Carlo bands hold what they say ([Uncertainty](uncertainty.md))?
Every model is trained without the check rings (the paper: the shipped `assets/models/paper/` on
`assets/data/paper.csv`, its network's cross-validation retrained with the card's settings; the
teaching scenarios: simulated with their own seed, both models trained as `train` does; the
hybrid: the scenario's known, not hidden, effects and a trilinear data part, fitted on the
training rings only). **Each check ring's band is calibrated on the other held-out rings** (leave
one ring out), so no ring is covered by a band calibrated on itself. The fractions are of the
held-out single touches inside the touch band and of the held-out mean-curve points inside the
mean band; beside them, the same run's band of the cross-validation alone (scale 1) and the
noise-only band (the repeatability component alone). The model variance scale is the one each
check ring's band used (local in A): median (min-max) over the check rings.
"""


def within(u: Mapping[str, Any], band: str) -> int:
    """How many (campaign, model) pairs hold both fractions of this band inside the target."""
    low, high = u.get("target") or (0.0, 1.0)
    return sum(
        all(low <= (get(x, band, k) if get(x, band, k) is not None else -1) <= high for k in ("touch", "mean"))
        for models in (u.get("campaigns") or {}).values()
        for x in models.values()
    )


def coverage(results: Mapping[str, Any]) -> str:
    u = results.get("uncertainty_coverage", {})
    rows = []
    for campaign, models in (u.get("campaigns") or {}).items():
        for model, x in models.items():
            scale_ = x.get("model_error_scale") or {}
            rows.append(
                [
                    campaign,
                    model,
                    get(x, "full_band", "touch"),
                    get(x, "full_band", "mean"),
                    f"{num(get(x, 'cross_validation_only_band', 'touch'))} / {num(get(x, 'cross_validation_only_band', 'mean'))}",
                    f"{num(get(x, 'noise_only_band', 'touch'))} / {num(get(x, 'noise_only_band', 'mean'))}",
                    f"{num(scale_.get('median'))} ({num(scale_.get('min'))}-{num(scale_.get('max'))})",
                    num(scale_.get("calibration_rings")),
                    x.get("in_target"),
                ]
            )
    target = interval(u.get("target"))
    out = [
        COVERAGE_INTRO,
        f"Method as run: {u.get('method', '')}.",
        "",
        table(
            [
                "campaign",
                "model",
                "touches in band",
                "mean-curve points in band",
                "cross-validation only: touches / mean",
                "noise only: touches / mean",
                "model variance scale",
                "calibration rings",
                f"in {target}",
            ],
            rows,
        ),
        f"Both fractions in {target}: {num(u.get('in_target_count'))} of {num(u.get('of'))} pairs; with the band of the "
        f"cross-validation alone {within(u, 'cross_validation_only_band')} of {len(rows)}, with the noise-only band "
        f"{within(u, 'noise_only_band')} of {len(rows)}. Section time {num(u.get('seconds'), 's')}.",
        "",
    ]
    budget_rows = [
        [
            campaign,
            model,
            *[
                get(x, "budget_um_mean_over_check_rings", k)
                for k in ("repeatability", "repeatability_mean", "model", "parameters", "combined_touch", "combined_mean")
            ],
        ]
        for campaign, models in (u.get("campaigns") or {}).items()
        for model, x in models.items()
    ]
    if budget_rows:
        out += [
            "The budget, mean over the check rings (standard uncertainties, um):",
            "",
            table(
                [
                    "campaign",
                    "model",
                    "repeatability",
                    "repeatability of the mean",
                    "model",
                    "parameters",
                    "combined, one touch",
                    "combined, the mean",
                ],
                budget_rows,
            ),
        ]
    task = u.get("task_paper_check_rings") or {}
    if task:
        rows = []
        for model, x in task.items():
            rings = x.get("rings") or []
            largest = max((r.get("E_n") or 0 for r in rings), default=None)
            u_sim = [r.get("U_sim_um") for r in rings if r.get("U_sim_um") is not None]
            rows.append(
                [
                    model,
                    f"{num(x.get('ront_E_n_at_most_1'))} of {num(x.get('of_rings'))}",
                    largest,
                    f"{num(x.get('harmonics_E_n_at_most_1'))} of {num(x.get('harmonics_compared'))}",
                    interval([min(u_sim), max(u_sim)]) if u_sim else "-",
                    x.get("single_ront_inside_95_interval"),
                ]
            )
        out += [
            "**The measurement task** on the paper campaign's check rings (one circle of head touches, one measurement; each "
            "ring's sources calibrated on the other rings): the measured value is the mean over the repetitions with "
            "U_meas = 2 s / sqrt(R), and E_n = |sim - measured| / sqrt(U_sim^2 + U_meas^2). U_sim is mostly the touch noise, "
            "so E_n <= 1 is a weak check; the stricter one is the share of the single measured RONt values inside the "
            "simulated 95 % interval.",
            "",
            table(
                [
                    "model",
                    "RONt E_n <= 1",
                    "largest RONt E_n",
                    "harmonics 2..15 E_n <= 1",
                    "U_sim of RONt, k = 2 (um)",
                    "single RONt inside the 95 % interval",
                ],
                rows,
            ),
        ]
    return "\n".join(out)
