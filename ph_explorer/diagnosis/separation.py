"""What measurement would separate two candidates this campaign cannot tell apart.

Two confounded effects (partners.confounding) split the signal between them. Each MEASUREMENTS entry
adds touches to the campaign's own, and the two effects' shared variance after the circle fit (no
smoother) is computed over the union; the measurement that lowers it most is named, with the share
it would leave. Nothing is simulated: the columns are the effects' bases at the touches.

Method: docs/methods/separation.md.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign, lattice_axes
from ph_explorer.diagnosis.fitted_bases import settings_key
from ph_explorer.effects import Effect
from ph_explorer.kinematics import Touches, campaign_touches, touch_kinematics
from ph_explorer.models.hybrid import fitted_basis
from ph_explorer.models.least_squares import Design

LONGER_STYLUS_MM = 20.0  # a second stylus this much longer than the campaign's
NEAR_VERTICAL_A_DEG = (5.0, 10.0)  # rings between A0 = 0 and the first lattice row
SEPARATES = 0.02  # a measurement that lowers the shared variance by less separates nothing


Blocks = list[NDArray[np.float64] | None]  # rows in blocks (touch_blocks'), None: rows of zeros


def _blocks(effect: Effect, touches: Touches) -> Blocks:
    """An effect's fitted columns at the touches as Design.touch_blocks: the same products as over
    single touches, in n_rep times fewer rows when nothing changes between repetitions."""
    return list(Design(fitted_basis(effect, touches)[0], None).touch_blocks())


def orthonormal_span(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """An orthonormal basis of the columns of m (rows, columns), numerically null directions left out."""
    u, singular, _ = np.linalg.svd(m, full_matrices=False)
    return u[:, singular > 1e-9 * max(singular.max(initial=0.0), 1e-300)]


def block_span(blocks: Sequence[NDArray[np.float64] | None]) -> Blocks:
    """orthonormal_span of the blocks stacked (None: rows of zeros), given back in the same blocks."""
    present = [b for b in blocks if b is not None]
    q = orthonormal_span(np.concatenate(present) if len(present) > 1 else present[0])
    edges = np.cumsum([0, *(b.shape[0] for b in present)])
    parts = iter(q[start:stop] for start, stop in zip(edges[:-1], edges[1:]))
    return [None if b is None else next(parts) for b in blocks]


def span_share(qx: Sequence[NDArray[np.float64] | None], qy: Sequence[NDArray[np.float64] | None]) -> float:
    """The largest squared canonical correlation of two orthonormal bases, each given in blocks of
    rows (e.g. (mean rows, within rows)); a None block is rows of zeros."""
    if not qx[0].shape[1] or not qy[0].shape[1]:
        return 0.0
    product = sum(a.T @ b for a, b in zip(qx, qy) if a is not None and b is not None)
    return float(np.linalg.svd(product, compute_uv=False).max() ** 2)


# Two candidates whose columns share more than this (squared canonical correlation over every
# touch, through the smoother) cannot be told apart by this campaign.
CONFOUNDED = 0.8


def touch_span(design: Design) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
    """An orthonormal basis of the design's columns over every touch: (mean rows, within rows or None)."""
    mean, within = block_span(design.touch_blocks())
    return mean, within


def shared_variance(a: Design, b: Design) -> float:
    """The largest squared canonical correlation between two designs' columns over all touches."""
    return span_share(touch_span(a), touch_span(b))


def shared_over(a: Effect, b: Effect, touch_sets: Sequence[Touches]) -> float:
    """The largest squared canonical correlation of two effects' fitted columns over the touch sets."""
    spans = [block_span([block for touches in touch_sets for block in _blocks(e, touches)]) for e in (a, b)]
    return span_share(*spans)


def _near_vertical(campaign: Campaign) -> Touches | None:
    _, b_grid = lattice_axes(campaign.orientations)
    rows = [(a, b) for a in NEAR_VERTICAL_A_DEG for b in b_grid]
    return touch_kinematics(rows, campaign.geometry, 1) if rows else None


def _half_steps(campaign: Campaign) -> Touches | None:
    a_grid, b_grid = lattice_axes(campaign.orientations)
    if a_grid.size < 2 or b_grid.size < 2:
        return None
    a_mid = 0.5 * (a_grid[1:] + a_grid[:-1])
    b_mid = 0.5 * (b_grid + np.roll(b_grid, -1) + np.where(np.roll(b_grid, -1) < b_grid, 360.0, 0.0))
    rows = [(a, (b + 180.0) % 360.0 - 180.0) for a in a_mid for b in b_mid]
    return touch_kinematics(rows, campaign.geometry, 1)


def _alternating(campaign: Campaign) -> Touches:
    """The campaign's rings scanned twice, the second time backwards, two seconds a touch."""
    n_o, n_pt = campaign.n_orientations, campaign.n_points
    step = np.arange(n_pt, dtype=float)
    forward = np.arange(n_o)[:, None] * 4.0 * n_pt + step[None, :]
    backward = forward + n_pt + step[::-1][None, :] - step[None, :]
    times = 2.0 * np.stack([forward, backward], axis=1)
    return touch_kinematics(campaign.orientations, campaign.geometry, 2, times)


def _longer_stylus(campaign: Campaign) -> Touches:
    geometry = replace(campaign.geometry, pivot_to_ball_mm=campaign.geometry.pivot_to_ball_mm + LONGER_STYLUS_MM)
    return touch_kinematics(campaign.orientations, geometry, 1)


# Each: (what a user would measure, the touches it adds); None where it adds nothing new.
MEASUREMENTS: tuple[tuple[str, Callable[[Campaign], Touches | None]], ...] = (
    (f"rings between A0 = 0 and the first lattice row (A0 = {NEAR_VERTICAL_A_DEG[0]:g}, {NEAR_VERTICAL_A_DEG[1]:g} deg)", _near_vertical),
    ("off-grid rings at the half steps of the lattice", _half_steps),
    ("the rings again with the scan direction reversed", _alternating),
    (f"the rings again with a stylus {LONGER_STYLUS_MM:g} mm longer", _longer_stylus),
)


class Separations:
    """What would separate pairs of effects on one campaign (separating_measurements), each
    measurement's touches, each effect's columns and each span made once for all the pairs asked:
    a candidate and its closest partners share effects between their pairs."""

    def __init__(self, campaign: Campaign) -> None:
        self.texts = [""] + [text for text, _ in MEASUREMENTS]
        # Set 0: the campaign's own touches; set i: what MEASUREMENTS[i - 1] adds (None: nothing new).
        self.touch_sets = [campaign_touches(campaign)] + [make(campaign) for _, make in MEASUREMENTS]
        self._fitted: dict[tuple, Blocks] = {}  # each effect's columns at each set
        self._spans: dict[tuple, Blocks] = {}

    def _blocks_at(self, effect: Effect, i: int) -> Blocks:
        key = (settings_key(effect), i)
        if key not in self._fitted:
            self._fitted[key] = _blocks(effect, self.touch_sets[i])
        return self._fitted[key]

    def _span(self, effect: Effect, i: int) -> Blocks:
        """The effect's orthonormal span over the own touches and, for i > 0, set i's."""
        key = (settings_key(effect), i)
        if key not in self._spans:
            own = self._blocks_at(effect, 0)
            self._spans[key] = block_span(own if i == 0 else own + self._blocks_at(effect, i))
        return self._spans[key]

    def shared(self, a: Effect, b: Effect, i: int) -> float:
        """shared_over(a, b, own touches + set i's), from the spans made once."""
        return span_share(self._span(a, i), self._span(b, i))

    def __call__(self, pairs: Sequence[tuple[Effect, Effect]]) -> list[dict[str, float | str]]:
        out = []
        for a, b in pairs:
            now = self.shared(a, b, 0)
            best: tuple[float, str] = (now, "")
            for i in range(1, len(self.touch_sets)):
                touches = self.touch_sets[i]
                if touches is None or a.unmet_needs(touches) or b.unmet_needs(touches):  # e.g. drift without touch times
                    continue
                shared = self.shared(a, b, i)
                if shared <= best[0] - SEPARATES:
                    best = (shared, self.texts[i])
            out.append({"measurement": best[1], "shared": round(best[0], 3), "shared_now": round(now, 3)})
        return out


def separating_measurements(pairs: Sequence[tuple[Effect, Effect]], campaign: Campaign) -> list[dict[str, float | str]]:
    """For each pair, {"measurement": what to measure best, "shared": the share it would leave,
    "shared_now": the share over this campaign's touches}, both over the touches alone ("measurement"
    is "" when none of MEASUREMENTS lowers it by SEPARATES or more)."""
    return Separations(campaign)(pairs)
