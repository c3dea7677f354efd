"""What a data scientist would try first, as models beside the project's: scipy's RBFInterpolator
and scikit-learn's GaussianProcessRegressor, in ten lines each (docs/methods/off_the_shelf.md).

Both learn the map from (A in radians, cos B, sin B) to the training rings' mean-curve Fourier
coefficients of harmonics 2..20 (cos and sin; 0 and 1 are what the circle fit removes) and draw
the curve those coefficients give. The RBF is a thin-plate spline through the rings; the GP has a
constant x Matern 5/2 kernel with one length scale per feature + white noise, targets normalised,
hyperparameters by the log marginal likelihood (3 restarts, random_state 0). They are yardsticks,
not data parts: the explorer's Map and the peers benchmark score them on the check rings.
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.harmonics import fourier_basis, paper_fourier_fit
from ph_explorer.models.deviation_model import DeviationModel, as_orientations, pooled_repetition_variance, save_arrays, training_mask
from ph_explorer.models.gaussian_process import features

HARMONICS = (2, 20)  # the coefficients learnt: harmonics 2..20, cos and sin
COLUMNS = slice(1 + 2 * (HARMONICS[0] - 1), None)  # their columns in the basis (1, cos, sin, ..., cos K, sin K)
RESTARTS = 3


def coefficient_basis(n_points: int) -> NDArray[np.float64]:
    """(n_points, 2 (K - 1)): the Fourier basis columns of harmonics 2..K (cos, sin)."""
    return fourier_basis(n_points, HARMONICS[1])[:, COLUMNS]


class OffTheShelfModel(DeviationModel):
    """A regressor of the mean curves' coefficients on the peers' features (module docstring)."""

    file_name: ClassVar[str] = "peer.npz"

    def __init__(self) -> None:
        self.features_ = np.zeros((0, 3))
        self.coefficients_ = np.zeros((0, 2 * (HARMONICS[1] - 1)))
        self.sigma_curve = np.zeros(0)  # (n_pt,) pooled repetition spread of the training rings
        self.regressor_: Any = None

    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        mask = training_mask(campaign, train)
        if mask.sum() < 2:
            raise ValueError(f"the {self.name} peer needs at least two training orientations")
        deviations = campaign.deviations[mask]
        coefficients = paper_fourier_fit(deviations.mean(axis=1), HARMONICS[1])[:, COLUMNS]
        spread = pooled_repetition_variance(deviations)
        self.n_points = campaign.n_points
        self._set(features(campaign.orientations[mask]), coefficients, np.sqrt(spread))
        return self

    def _set(self, x: NDArray[np.float64], y: NDArray[np.float64], sigma: NDArray[np.float64]) -> None:
        self.features_, self.coefficients_, self.sigma_curve = x, y, sigma
        self.regressor_ = self._regressor(x, y)

    def _regressor(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> Any:
        raise NotImplementedError

    def predicted_coefficients(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.regressor_.predict(x)

    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        return self.predicted_coefficients(features(orientations)) @ coefficient_basis(n_points or self.n_points).T

    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        n = n_points or self.n_points
        sigma = self.sigma_curve if n == self.sigma_curve.size else np.full(n, float(np.sqrt(np.mean(self.sigma_curve**2))))
        return np.broadcast_to(sigma, (len(as_orientations(orientations)), n)).copy()

    def _arrays(self) -> dict[str, NDArray]:
        return {"features": self.features_, "coefficients": self.coefficients_, "sigma": self.sigma_curve}

    def save(self, directory: str | Path) -> Path:
        return save_arrays(directory, self.file_name, **self._arrays())

    @classmethod
    def load(cls, directory: str | Path) -> Self:
        with np.load(Path(directory) / cls.file_name, allow_pickle=False) as data:
            model = cls()
            model._restore({k: data[k] for k in data.files})
        return model

    def _restore(self, arrays: dict[str, NDArray]) -> None:
        self.n_points = arrays["sigma"].size
        self._set(arrays["features"], arrays["coefficients"], arrays["sigma"])


class RBFPeer(OffTheShelfModel):
    """scipy.interpolate.RBFInterpolator, thin-plate spline, no smoothing: through every ring."""

    name = "rbf"
    file_name = "rbf.npz"

    def _regressor(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> Any:
        from scipy.interpolate import RBFInterpolator

        return RBFInterpolator(x, y, kernel="thin_plate_spline")

    def predicted_coefficients(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        return self.regressor_(x)


class CoefficientGPPeer(OffTheShelfModel):
    """sklearn's GaussianProcessRegressor on each coefficient (normalised), the kernel learnt."""

    name = "peer_gp"
    file_name = "peer_gp.npz"

    def __init__(self) -> None:
        super().__init__()
        self.theta: NDArray[np.float64] | None = None  # the kernel's log hyperparameters, once learnt

    def _regressor(self, x: NDArray[np.float64], y: NDArray[np.float64]) -> Any:
        from sklearn.exceptions import ConvergenceWarning
        from sklearn.gaussian_process import GaussianProcessRegressor
        from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

        kernel = ConstantKernel() * Matern(length_scale=np.ones(3), nu=2.5) + WhiteKernel()
        if self.theta is not None:  # read back: the learnt kernel, not learnt again
            kernel = kernel.clone_with_theta(self.theta)
        options = {"optimizer": None} if self.theta is not None else {"n_restarts_optimizer": RESTARTS, "random_state": 0}
        with warnings.catch_warnings():  # a bound reached says a feature does not matter: an answer
            warnings.simplefilter("ignore", ConvergenceWarning)
            regressor = GaussianProcessRegressor(kernel, normalize_y=True, **options).fit(x, y)
        self.theta = regressor.kernel_.theta
        return regressor

    def coefficient_variance(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, 2 (K - 1)): each predicted coefficient's posterior variance."""
        return self.regressor_.predict(features(orientations), return_std=True)[1] ** 2

    def curve_variance(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        """(m, n_points): each point's predictive variance, the coefficients' taken as independent."""
        return self.coefficient_variance(orientations) @ (coefficient_basis(n_points or self.n_points) ** 2).T

    def _arrays(self) -> dict[str, NDArray]:
        return {**super()._arrays(), "theta": np.asarray(self.theta)}

    def _restore(self, arrays: dict[str, NDArray]) -> None:
        self.theta = arrays["theta"]
        super()._restore(arrays)


PEER_MODELS: dict[str, type[OffTheShelfModel]] = {"rbf": RBFPeer, "peer_gp": CoefficientGPPeer}
