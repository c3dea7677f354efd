"""A Gaussian-process data part: scikit-learn's GaussianProcessRegressor over the head's orientations.

Features: the head's axis angles, A in radians and B on the circle (cos B, sin B): a rotary
axis's errors are functions of its angle (ISO 230-7), and the rings at A = 0 stay apart, since the
probe, and its lobing, is turned there (the stylus direction as features tied them, and predicted
worse). Kernel: constant x Matern 5/2 with a length scale per feature + white noise, shared by
every point; its hyperparameters maximise the log marginal likelihood of the standardised mean
curves (RESTARTS restarts, random_state 0). With them fixed the posterior mean is linear in the
training curves (`interpolate`), so the hybrid and the diagnosis use it as the trilinear tables;
its posterior variance is the model's own error (`variance`).

Method: docs/methods/gaussian_process.md.
"""

from __future__ import annotations

import hashlib
import threading
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.models.deviation_model import DeviationModel, as_orientations, pooled_repetition_variance, save_arrays, training_mask

if TYPE_CHECKING:  # scikit-learn is imported where a GP is made: the explorer and the CLI start without it
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import Kernel

FILE_NAME = "gp.npz"
N_FEATURES = 3
RESTARTS = 3


def features(orientations: ArrayLike) -> NDArray[np.float64]:
    """(m, 3): the axis angles (A in radians, cos B, sin B)."""
    o = np.radians(as_orientations(orientations))
    return np.column_stack([o[:, 0], np.cos(o[:, 1]), np.sin(o[:, 1])])


def default_kernel() -> Kernel:
    """Constant x Matern 5/2 (one length scale per feature) + white noise, before its fit."""
    from sklearn.gaussian_process.kernels import ConstantKernel, Matern, WhiteKernel

    return ConstantKernel(1.0, (1e-4, 1e4)) * Matern(np.ones(N_FEATURES), (1e-2, 1e3), nu=2.5) + WhiteKernel(0.1, (1e-6, 1e2))


def standardised(curves: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """(targets, mean curve, scale): the curves minus their mean, over their overall standard deviation."""
    mean = curves.mean(axis=0)
    scale = float(np.std(curves - mean))
    scale = scale if scale > 0 else 1.0
    return (curves - mean) / scale, mean, scale


# The last few kernels learnt, by their data: a diagnosis fits its baseline and each step's hybrid
# on the same training rings, and the likelihood's restarts take a second or more each time.
_THETAS: dict[bytes, NDArray[np.float64]] = {}
THETAS_KEPT = 16
_THETAS_LOCK = threading.Lock()  # the explorer's sessions fit in threads


def learnt_theta(x: NDArray[np.float64], curves: NDArray[np.float64]) -> NDArray[np.float64]:
    """The kernel's log hyperparameters by the marginal likelihood of the standardised curves
    (the same data gives the same hyperparameters: learnt once, then read back)."""
    key = hashlib.sha256(np.ascontiguousarray(x).tobytes() + np.ascontiguousarray(curves).tobytes()).digest()
    with _THETAS_LOCK:
        if key in _THETAS:
            return _THETAS[key].copy()
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor

    learner = GaussianProcessRegressor(default_kernel(), n_restarts_optimizer=RESTARTS, random_state=0)
    with warnings.catch_warnings():
        # A length scale at its upper bound says that feature does not matter: an answer, not a failure.
        warnings.simplefilter("ignore", ConvergenceWarning)
        theta = learner.fit(x, standardised(curves)[0]).kernel_.theta
    with _THETAS_LOCK:
        while len(_THETAS) >= THETAS_KEPT:
            _THETAS.pop(next(iter(_THETAS)))  # the oldest first
        _THETAS[key] = theta.copy()
    return theta


@dataclass(frozen=True)
class FixedKernel:
    """A factory of GP models whose kernel is fixed (its log hyperparameters `theta`): the linear
    smoother whose out-of-sample weights stand for a fitted GP (models.crossval)."""

    theta: tuple[float, ...]
    name: ClassVar[str] = "gp"

    def __call__(self) -> GaussianProcessModel:
        return GaussianProcessModel(theta=np.asarray(self.theta))


class GaussianProcessModel(DeviationModel):
    """The posterior mean of a GP over the orientations (see the module docstring)."""

    name = "gp"
    file_name = FILE_NAME

    def __init__(self, theta: NDArray[np.float64] | None = None) -> None:
        self.theta = theta  # log hyperparameters; None: by the marginal likelihood in fit
        self.train_features: NDArray[np.float64] | None = None  # (n, 3) features of the training rings
        self.train_curves: NDArray[np.float64] | None = None  # (n, n_pt) the rings' mean curves
        self.sigma_curve: NDArray[np.float64] | None = None  # (n_pt,) pooled repetition spread
        self.regressor_: GaussianProcessRegressor | None = None
        self.mean_curve_, self.scale_ = np.zeros(0), 1.0  # the targets' standardisation
        self.n_repetitions = 1  # of the training rings: their mean curves' own noise is sigma_curve^2 / n
        self.n_points = 64

    # -- learning --------------------------------------------------------------------------------
    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        mask = training_mask(campaign, train)
        if mask.sum() < 2:
            raise ValueError("the Gaussian process needs at least two training orientations")
        deviations = campaign.deviations[mask]
        x, curves = features(campaign.orientations[mask]), deviations.mean(axis=1)
        if self.theta is None:
            self.theta = learnt_theta(x, curves)
        spread = pooled_repetition_variance(deviations)
        self.n_repetitions = deviations.shape[1]
        self._set(x, curves, np.sqrt(spread))
        return self

    def _set(self, x: NDArray[np.float64], curves: NDArray[np.float64], sigma: NDArray[np.float64]) -> None:
        """The posterior with the kernel fixed at theta: linear in the curves."""
        self.train_features, self.train_curves, self.sigma_curve = x, curves, sigma
        self.n_points = curves.shape[-1]
        targets, self.mean_curve_, self.scale_ = standardised(curves)
        from sklearn.gaussian_process import GaussianProcessRegressor

        kernel = default_kernel().clone_with_theta(np.asarray(self.theta, dtype=float))
        self.regressor_ = GaussianProcessRegressor(kernel, optimizer=None).fit(x, targets)

    def linear_smoother(self, campaign: Campaign, train: ArrayLike | None = None) -> FixedKernel:
        """The factory of this GP with its kernel fixed (learnt now from the campaign's training
        rings if it is not yet): a linear smoother, whose out-of-sample weights are this GP's."""
        if self.theta is None:
            mask = training_mask(campaign, train)
            self.theta = learnt_theta(features(campaign.orientations[mask]), campaign.deviations[mask].mean(axis=1))
        return FixedKernel(tuple(float(t) for t in self.theta))

    # -- prediction ------------------------------------------------------------------------------
    def interpolate(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """The posterior mean at orientations on the training curves' own points, no circle fit:
        linear in the curves the model was fitted on, whatever they hold (crossval.unit_campaign)."""
        if self.regressor_ is None:
            raise RuntimeError("the Gaussian process is not fitted")
        predicted = self.regressor_.predict(features(orientations)).reshape(len(as_orientations(orientations)), -1)
        return self.mean_curve_ + self.scale_ * predicted

    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        curves = remove_size_and_centre(self.interpolate(orientations))
        return _resampled(curves, self.n_points if n_points is None else int(n_points))

    def variance(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        """(m, n_points) um^2: the variance of the model's error at each point of the systematic curve."""
        if self.regressor_ is None or self.sigma_curve is None:
            raise RuntimeError("the Gaussian process is not fitted")
        m = len(as_orientations(orientations))
        _, std = self.regressor_.predict(features(orientations), return_std=True)
        std = np.asarray(std, dtype=float).reshape(m, -1)[:, :1]  # the kernel is shared: the same at every point
        white = self.regressor_.kernel_.k2.noise_level
        latent = self.scale_**2 * np.maximum(std**2 - white, 0.0)  # the posterior's, a new measurement's noise excluded
        # The white noise the likelihood found beyond the repetitions' own noise of a mean curve is
        # systematic: what changes from ring to ring faster than the kernel follows (an effect the
        # lattice does not resolve). It is in the model's error too.
        unresolved = np.maximum(self.scale_**2 * white - self.sigma_curve**2 / self.n_repetitions, 0.0)
        return _resampled(latent + unresolved[None, :], self.n_points if n_points is None else int(n_points))

    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        if self.sigma_curve is None:
            raise RuntimeError("the Gaussian process is not fitted")
        n = self.n_points if n_points is None else int(n_points)
        return np.repeat(_resampled(self.sigma_curve[None], n), len(as_orientations(orientations)), axis=0)

    # -- files (no pickle: the hyperparameters and the training data; the posterior is refitted) -
    def save(self, directory: str | Path) -> Path:
        if self.train_curves is None:
            raise RuntimeError("the Gaussian process is not fitted")
        return save_arrays(
            directory,
            self.file_name,
            theta=np.asarray(self.theta),
            train_features=self.train_features,
            train_curves=self.train_curves,
            sigma_curve=self.sigma_curve,
            n_repetitions=np.array(self.n_repetitions),
        )

    @classmethod
    def load(cls, directory: str | Path) -> Self:
        path = Path(directory) / cls.file_name
        with np.load(path, allow_pickle=False) as data:
            if data["train_features"].shape[-1] != N_FEATURES:
                raise ValueError(
                    f"{path}: a GP of an earlier feature map ({data['train_features'].shape[-1]} features, not {N_FEATURES}): fit it again"
                )
            model = cls(theta=data["theta"].astype(float))
            model.n_repetitions = int(data["n_repetitions"])
            model._set(data["train_features"].astype(float), data["train_curves"].astype(float), data["sigma_curve"].astype(float))
        return model


def _resampled(curves: NDArray[np.float64], n_points: int) -> NDArray[np.float64]:
    """Periodic curves (m, N) at n_points equally spaced points, through their Fourier series."""
    n = curves.shape[-1]
    if n == n_points:
        return curves
    spectrum = np.fft.rfft(curves, axis=-1)
    return np.fft.irfft(spectrum, n=n_points, axis=-1) * (n_points / n)
