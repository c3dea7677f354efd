"""The benchmarks page's `## Peers` section (`peers`): scipy's and scikit-learn's first tries beside the models."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import Plots, get, holds, image, joined, num, pct, table

PEERS_INTRO = """\
## Peers

`peers`: what a data scientist would try first, beside the project's models, on the same split
(every model learns from the training rings and predicts the check rings it never saw):
scipy's `RBFInterpolator` (thin-plate spline, no smoothing) and scikit-learn's
`GaussianProcessRegressor` (constant x Matern 5/2 with a length scale per feature + white noise,
hyperparameters by the log marginal likelihood), both fitted on the feature map ({feature_map}) to
{targets}. The hybrid "before" starts from the scenario's known effects (none on a random head);
"after" adds the effects the diagnosis chose, fitted on the training rings only as the peers are
(an effect that only the check rings identify, because the lattice interpolates it, then gets no
weight). Beside it, the diagnosis's own "after" (each check ring predicted with that ring left out
of the physical fit but the other check rings in: what the loop shows) and its nested
cross-validation's "after" (each fold choosing its effects without its rings). Each
figure is the check-ring MAE against the repetitions' mean over its noise floor; the ratio is the
best of the project's models over the best peer (goal: at most 1.00). The project's models include
its own GP data part ("gaussian process": the axis angles (A, cos B, sin B) as features,
every point of the curve; [its method](methods/gaussian_process.md)) and the hybrid after the
diagnosis with it ("hybrid after gp"), and the "hybrid stacked": the diagnosis's effects kept per
data part and the data part chosen among the trilinear tables, the mean curve and the GP by the
training rings' own cross-validation (the data-efficiency benchmark's rule with the GP as a third
part, its fit time including that choice; the data-efficiency benchmark's rule keeps to the
trilinear tables and the mean curve, `benchmarks/stacking.py` says why). The peer
GP's own 95 % band (coefficients' predictive
variance through the Fourier basis, plus the repetition variance for single touches) stands beside
the project's calibrated Monte Carlo bands of the trilinear model and of the GP data part (whose
model component is its posterior variance); the coverage goal is the GP data part's.
"""


def peers(results: Mapping[str, Any], plots: Plots) -> str:
    p = results.get("peers", {})
    campaigns = p.get("campaigns", [])
    names = list(campaigns[0].get("models", {})) if campaigns else []  # the project's models, then the peers, as stored
    rows = []
    for r in p.get("campaigns", []):
        models = r.get("models", {})
        ratio = r.get("ratio_best_project_to_best_peer")
        rows.append(
            [r.get("campaign"), *(num(get(models, m, "over_floor", "mean")) for m in names)]
            + [
                f"{num(ratio)}: {holds(ratio is not None and ratio <= 1.0)}",
                num(get(r, "diagnosis_after", "over_floor", "mean")),
                num(get(r, "nested_after_mae_um", "mean"), "um"),
            ]
        )
    bands = [
        [
            r.get("campaign"),
            f"{pct(get(r, 'gp_band', 'coverage', 'mean'))} / {pct(get(r, 'gp_band', 'coverage', 'single'))}",
            f"{num(get(r, 'gp_band', 'mean_half_width_um', 'mean'))} / {num(get(r, 'gp_band', 'mean_half_width_um', 'single'))}",
            f"{pct(get(r, 'monte_carlo_band', 'coverage', 'mean'))} / {pct(get(r, 'monte_carlo_band', 'coverage', 'single'))}",
            f"{num(get(r, 'monte_carlo_band', 'mean_half_width_um', 'mean'))} / "
            f"{num(get(r, 'monte_carlo_band', 'mean_half_width_um', 'single'))}",
            f"{pct(get(r, 'gaussian_process_band', 'coverage', 'mean'))} / {pct(get(r, 'gaussian_process_band', 'coverage', 'single'))}",
            f"{num(get(r, 'gaussian_process_band', 'mean_half_width_um', 'mean'))} / "
            f"{num(get(r, 'gaussian_process_band', 'mean_half_width_um', 'single'))}",
        ]
        for r in p.get("campaigns", [])
    ]
    timing = [
        [
            m,
            *(
                f"{num(get(r, 'models', m, 'fit_s'), 's')} / {num(get(r, 'models', m, 'predict_s'), 's')}"
                for r in p.get("campaigns", [])[:1]
            ),
        ]
        for m in names
    ]
    goals = [
        [
            name.replace("1_25", "1.25").replace("_", " "),
            f"{g.get('holds')} of {g.get('of')}",
            joined(g["missed"]) if "missed" in g else "-",
        ]
        for name, g in (p.get("goals") or {}).items()
    ]
    return (
        PEERS_INTRO.format(feature_map=p.get("feature_map"), targets=p.get("targets_fitted"))
        + "\n"
        + image(plots, "peers.png", "check-ring MAE over the floor, each model and peer, per campaign")
        + "\n"
        + table(["goal", "holds", "missed on"], goals)
        + "\n"
        + table(
            ["campaign", *(n.replace("_", " ") for n in names), "ratio best project / best peer", "diagnosis's after", "nested after"], rows
        )
        + "\n**95 % bands on the check rings** (mean curves / single touches):\n\n"
        + table(
            [
                "campaign",
                "peer GP coverage",
                "peer GP mean half-width (um)",
                "trilinear Monte Carlo coverage",
                "its mean half-width (um)",
                "GP data part Monte Carlo coverage",
                "its mean half-width (um)",
            ],
            bands,
        )
        + "\n**Fit / predict seconds** (first campaign):\n\n"
        + table(["model", "fit / predict"], timing)
        + "\n"
    )
