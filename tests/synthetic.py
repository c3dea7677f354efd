"""A small synthetic campaign for the tests of the models (not the digital twin).

Smooth lobing-like systematic curves that vary with the orientation the way the head's do
(physics.md): a 3-lobe pattern whose phase turns with B0 at A0 = 0 and less as A0 grows, whose
amplitude grows with the lateral share of gravity (sin A0), a 2-lobe term and a 6-lobe term,
plus Gaussian touch noise; every repetition goes through its own least-squares circle fit.
Beside it, `scenario_with`: the paper scenario's rings with only the effects a test names (the
twin), which the data-part tests share; and `mirrored_campaign`: the same rings in space labelled
on the other side of A0, which the planning tests share.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.effects import DEFAULT_CATALOG
from ph_explorer.geometry import point_angles_deg
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.twin import Scenario, load_scenario

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
    dof: float = 0.0,
) -> Campaign:
    """The paper's lattice (A 0..90 step 15, B -160..180 step 20) + extra (off-grid) orientations;
    dof: a Student-t touch noise of these degrees of freedom, of the same sigma (0: Gaussian)."""
    a, b = np.meshgrid(PAPER_A_DEG, PAPER_B_DEG, indexing="ij")
    grid = np.column_stack([a.ravel(), b.ravel()])
    extra = np.asarray(extra_orientations, dtype=float).reshape(-1, 2)
    orientations = np.vstack([grid, extra])
    rng = np.random.default_rng(seed)
    shape = (len(orientations), n_repetitions, n_points)
    noise = rng.normal(0.0, sigma_um, shape) if not dof else rng.standard_t(dof, shape) * sigma_um * np.sqrt((dof - 2.0) / dof)
    deviations = remove_size_and_centre(systematic_curves(orientations, n_points)[:, None, :] + noise)
    return Campaign(
        orientations=orientations,
        deviations=deviations,
        check_orientations=check_orientations,
        source="synthetic lobing campaign",
    )


def scenario_with(*effects) -> Scenario:
    """The paper's rings, repetitions and noise with only these effects (and the ring's form)."""
    paper = load_scenario("paper")
    kept = [DEFAULT_CATALOG["noise"](sigma_um=0.175), DEFAULT_CATALOG["ring_form"](form_um=0.2, shape_seed=7), *effects]
    return dataclasses.replace(paper, effects=kept, hidden=[False] * len(kept))


def mirrored(orientations: ArrayLike) -> NDArray[np.float64]:
    """The same rings in space labelled at (-A0, B0 + 180), B0 in [-180, 180)."""
    o = np.asarray(orientations, dtype=float).reshape(-1, 2)
    return np.column_stack([-o[:, 0], (o[:, 1] + 360.0) % 360.0 - 180.0])


def mirrored_campaign(campaign: Campaign) -> Campaign:
    """The same touches labelled at (-A0, B0 + 180): point k of a ring is its point k + N/2 there
    (the ring frame turns half a turn with the labels)."""
    half = campaign.n_points // 2
    return dataclasses.replace(
        campaign,
        orientations=mirrored(campaign.orientations),
        check_orientations=mirrored(campaign.check_orientations),
        deviations=np.roll(campaign.deviations, -half, axis=2),
        times_s=np.roll(campaign.times_s, -half, axis=2),
    )
