"""The spread of a hybrid's fitted physical parameters, as deviation curves at any orientation.

The hybrid's physical coefficients come from a least squares over rings; their covariance C is the
jackknife's over the training rings (`uncertainty.jackknife_covariance` of `least_squares.jackknife`'s
delete-one-ring fits: the ring, not the touch, is the independent unit). A change d of the
coefficients moves the hybrid's prediction at orientation o by G(o) d, where G(o) is the
effects' basis at o minus what the data-driven part learns of it: the data part is fitted on the
deviations minus the physical terms, so with a trilinear data part (linear in its data)
G(o) = basis(o) - trilinear interpolation of the training rings' basis at o. With another data
part G is the basis itself (conservative: nothing of the change is taken up). Draws d ~ N(0, C)
give the parameters' component of the band (JCGM 101: propagation of distributions).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.geometry import Geometry
from ph_explorer.kinematics import campaign_touches, touch_kinematics
from ph_explorer.models import least_squares
from ph_explorer.models.deviation_model import as_orientations
from ph_explorer.models.hybrid import HybridModel
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.uncertainty.jackknife import jackknife_covariance
from ph_explorer.uncertainty.model_error import harmonic_power


@dataclass(frozen=True)
class ParameterSpread:
    """The hybrid, the jackknife covariance of its coefficients and the data part's share of its basis."""

    hybrid: HybridModel
    covariance: NDArray[np.float64]  # (c, c)
    absorbed: list[TrilinearModel]  # per column, the data part's interpolation of the basis (empty: none)

    def curves(self, orientations: ArrayLike, n_points: int) -> NDArray[np.float64]:
        """G (m, n_points, c): the prediction's change per unit change of each coefficient."""
        o = as_orientations(orientations)
        g = self.hybrid.geometry
        touches = touch_kinematics(o, Geometry(g.pivot_to_ball_mm, g.ball_diameter_mm, g.bore_diameter_mm, n_points))
        basis = self.hybrid.physical_basis(touches)[:, 0]
        if self.absorbed:
            basis = basis - np.stack([t.predict(o, n_points=n_points) for t in self.absorbed], axis=-1)
        return basis

    def root(self, orientation: ArrayLike, n_points: int) -> NDArray[np.float64]:
        """(n_points, c) R with R R^T the covariance of the component's curve at one orientation:
        a draw is R z, z ~ N(0, I) (an eigen-root: C may be singular, no Cholesky)."""
        values, vectors = np.linalg.eigh(self.covariance)
        return self.curves(orientation, n_points)[0] @ (vectors * np.sqrt(np.maximum(values, 0.0)))

    def draw(self, orientation: ArrayLike, n_trials: int, n_points: int, rng: np.random.Generator) -> NDArray[np.float64]:
        """(n_trials, n_points) draws of the parameters' component at one orientation."""
        root = self.root(orientation, n_points)
        return rng.standard_normal((n_trials, root.shape[1])) @ root.T

    def power(self, orientation: ArrayLike, n_points: int) -> NDArray[np.float64]:
        """(N//2 + 1,) expected power per harmonic of the component at one orientation, um^2."""
        return harmonic_power(self.root(orientation, n_points).T).sum(axis=0)


def parameter_spread(hybrid: HybridModel, campaign: Campaign) -> ParameterSpread | None:
    """The spread of a hybrid fitted (fit, not load) on campaign; None when it has no physical term."""
    if not hybrid.effects or hybrid.fit_design_ is None or hybrid.smoother_ is None:
        return None
    rings = np.flatnonzero(hybrid.smoother_.train)
    without = least_squares.jackknife(hybrid.fit_design_, hybrid.fit_targets_, rings, hybrid.ridge_)
    absorbed: list[TrilinearModel] = []
    if isinstance(hybrid.data_part, TrilinearModel):
        train = campaign.subset(rings)
        basis = hybrid.physical_basis(campaign_touches(train)).mean(axis=1)  # (n, N, c)
        absorbed = [TrilinearModel().fit(Campaign(train.orientations, basis[:, None, :, j])) for j in range(basis.shape[-1])]
    return ParameterSpread(hybrid, jackknife_covariance(without), absorbed)
