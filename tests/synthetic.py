"""A small synthetic campaign for the tests of the models (not the digital twin).

Smooth lobing-like systematic curves that vary with the orientation the way the head's do
(physics.md): a 3-lobe pattern whose phase turns with B0 at A0 = 0 and less as A0 grows, whose
amplitude grows with the lateral share of gravity (sin A0), a 2-lobe term and a 6-lobe term,
plus Gaussian touch noise; every repetition goes through its own least-squares circle fit.
Beside it, what the hybrid's tests share: `training_columns` (training subsets), `designed_rings`
and `check_ring_mae`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer import metrics
from ph_explorer.campaign import Campaign
from ph_explorer.geometry import point_angles_deg
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models.deviation_model import DeviationModel

PAPER_A_DEG = np.arange(0.0, 91.0, 15.0)
PAPER_B_DEG = np.arange(-160.0, 181.0, 20.0)


def systematic_curves(orientations: ArrayLike, n_points: int = 64) -> NDArray[np.float64]:
    """The noise-free deviation curves (m, n_points) in um, after the circle fit."""
    o = np.asarray(orientations, dtype=float).reshape(-1, 2)
    a, b = np.radians(o[:, :1]), np.radians(o[:, 1:])
    theta = np.radians(point_angles_deg(n_points))[None, :]
    phase = theta - b * np.cos(a)  # the probe's azimuth turns with B0 less as A0 grows
    curve = (
        (0.15 + 0.20 * np.sin(a)) * np.cos(3 * phase + 0.4)
        + 0.08 * np.cos(2 * theta + 0.5 * b + a)
        + 0.04 * (1 + np.cos(a)) * np.sin(6 * phase)
    )
    return remove_size_and_centre(curve)


def lobing_campaign(
    seed: int = 0,
    sigma_um: float = 0.175,
    n_repetitions: int = 10,
    n_points: int = 64,
    extra_orientations: ArrayLike = ((43.0, 91.0),),
    check_orientations: ArrayLike | None = None,
) -> Campaign:
    """The paper's lattice (A 0..90 step 15, B -160..180 step 20) + extra (off-grid) orientations."""
    a, b = np.meshgrid(PAPER_A_DEG, PAPER_B_DEG, indexing="ij")
    grid = np.column_stack([a.ravel(), b.ravel()])
    extra = np.asarray(extra_orientations, dtype=float).reshape(-1, 2)
    orientations = np.vstack([grid, extra])
    rng = np.random.default_rng(seed)
    noise = rng.normal(0.0, sigma_um, (len(orientations), n_repetitions, n_points))
    deviations = remove_size_and_centre(systematic_curves(orientations, n_points)[:, None, :] + noise)
    return Campaign(
        orientations=orientations,
        deviations=deviations,
        check_orientations=check_orientations,
        source="synthetic lobing campaign",
    )


def training_columns(campaign: Campaign, k: int) -> Campaign:
    """The campaign's training rings on every A row x k B columns (the data-efficiency benchmark's subset)."""
    from benchmarks.data_efficiency import lattice_subsets

    return campaign.subset(lattice_subsets(campaign, ~campaign.holdout_mask(), (k,))[0])


def designed_rings(campaign: Campaign, budget: int) -> Campaign:
    """The campaign's training rings `ph-explorer design --budget N` proposes (the benchmark's designed subset)."""
    from benchmarks.data_efficiency import designed_subsets

    return campaign.subset(designed_subsets(campaign, ~campaign.holdout_mask(), (budget,))[0][0])


def check_ring_mae(model: DeviationModel, campaign: Campaign) -> float:
    """A fitted model's MAE (um) against the repetition mean over every touch of the campaign's check rings."""
    check = campaign.holdout_mask()
    return metrics.mae(model.predict_touches(campaign_touches(campaign.subset(check))), campaign.deviations[check])["mean"]
