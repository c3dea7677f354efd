"""The interface every deviation model shares (scikit-learn spirit).

A model learns, from a campaign, the systematic deviation curve of the ring at any head
orientation (A0, B0): `predict` returns it after the circle fit (harmonics 0 and 1 removed), in um.
`simulate` is the Monte Carlo of a measurement: the systematic curve plus a draw from the
repetition spread, each simulated repetition put through its own least-squares circle fit as a
real one is.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from pathlib import Path
from typing import ClassVar, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import Touches, campaign_touches


def as_orientations(orientations: ArrayLike) -> NDArray[np.float64]:
    """Orientations as an (m, 2) float array of (A0, B0) in degrees."""
    o = np.asarray(orientations, dtype=float)
    if o.size % 2:
        raise ValueError("orientations must be (A0, B0) pairs")
    return o.reshape(-1, 2)


def training_mask(campaign: Campaign, train: ArrayLike | None) -> NDArray[np.bool_]:
    """The orientations a model may learn from: `train` (bool mask or indices), default all."""
    if train is None:
        return np.ones(campaign.n_orientations, dtype=bool)
    t = np.asarray(train)
    if t.dtype == bool:
        if t.shape != (campaign.n_orientations,):
            raise ValueError("train mask must have one entry per orientation")
        return t.copy()
    mask = np.zeros(campaign.n_orientations, dtype=bool)
    mask[t.astype(int)] = True
    return mask


def save_arrays(directory: str | Path, file_name: str, **arrays: NDArray) -> Path:
    """Write named arrays to directory/file_name (compressed .npz, no pickle); return the path."""
    path = Path(directory) / file_name
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as handle:
        np.savez_compressed(handle, **arrays)
    return path


def pooled_repetition_variance(deviations: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n_pt,) the spread of single touches about their ring's mean (ddof=1), pooled over the rings
    of deviations (n_o, n_rep, n_pt); zeros when there is a single repetition."""
    if deviations.shape[1] < 2:
        return np.zeros(deviations.shape[-1])
    return deviations.var(axis=1, ddof=1).mean(axis=0)


DRAW_CHUNK_VALUES = 2**21  # values drawn per block by draw_repetitions (16 MiB)


def draw_repetitions(
    systematic: NDArray[np.float64],
    sigma: ArrayLike,
    n_repetitions: int,
    rng: np.random.Generator | None,
) -> NDArray[np.float64]:
    """Simulated repetitions (m, n_rep, n_pt): systematic (m, n_pt) + Gaussian touch noise.

    sigma (broadcastable to (m, n_pt)) is the spread of deviations *after* the circle fit, as a
    campaign's repetition table holds it. The fit of each simulated repetition removes 3 of N
    degrees of freedom, shrinking the variance of every point by (N - 3) / N for equally spaced
    points; the touch noise is scaled up by sqrt(N / (N - 3)) so that the simulated repetitions
    reproduce the measured post-fit spread.
    """
    rng = np.random.default_rng() if rng is None else rng
    m, n_pt = systematic.shape
    s = np.broadcast_to(np.asarray(sigma, dtype=float), (m, n_pt))
    inflate = np.sqrt(n_pt / (n_pt - 3.0)) if n_pt > 3 else 1.0
    out = np.empty((m, n_repetitions, n_pt))
    # A few orientations at a time: the same draws as one call (the generator's stream runs on in
    # the same order), without the full-size temporaries of the circle fit (a diagnosis draws
    # hundreds of repetitions of a large campaign).
    rows = max(1, DRAW_CHUNK_VALUES // max(1, n_repetitions * n_pt))
    for start in range(0, m, rows):
        part = slice(start, min(m, start + rows))
        noise = rng.standard_normal((part.stop - part.start, n_repetitions, n_pt))
        noise *= (inflate * s[part])[:, None, :]  # in place: the draws are the largest array here
        np.add(systematic[part, None, :], remove_size_and_centre(noise), out=out[part])
    return out


class DeviationModel(ABC):
    """A model of the systematic deviation curve over the head's orientations.

    Subclasses implement fit, predict, repetition_sigma, save and load; predict_touches and
    simulate follow from them.
    """

    name: ClassVar[str] = "model"
    # Points per circle of the campaign the model learnt from: the default of n_points.
    n_points: int = 64

    @abstractmethod
    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        """Learn from the campaign's orientations selected by `train` (bool mask or indices)."""

    @abstractmethod
    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        """Systematic deviation curve (m, n_points) in um after the circle fit."""

    @abstractmethod
    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        """Repetition standard deviation of single touches (m, n_points) in um, after the circle fit."""

    @abstractmethod
    def save(self, directory: str | Path) -> Path:
        """Write the model's file into directory; return the file's path."""

    @classmethod
    @abstractmethod
    def load(cls, directory: str | Path) -> Self:
        """Read a model written by save."""

    def predict_touches(self, touches: Touches) -> NDArray[np.float64]:
        """(n_o, n_rep, n_pt): the systematic curve of each orientation, the same for every repetition."""
        n_o, n_rep, n_pt = touches.shape
        curve = self.predict(touches.orientations, n_points=n_pt)
        return np.broadcast_to(curve[:, None, :], (n_o, n_rep, n_pt)).copy()

    def predict_held_out(self, campaign: Campaign, rings: NDArray[np.int64]) -> NDArray[np.float64]:
        """(m, n_rep, n_pt): every touch of the given rings of the campaign this model was fitted on,
        each as out of sample as the model can make it (a hybrid leaves each ring out of its
        physical fit); by default the model's predictions, which never saw the held-out rings."""
        return self.predict_touches(campaign_touches(campaign.subset(rings)))

    def simulate(
        self,
        orientations: ArrayLike,
        n_repetitions: int = 1,
        rng: np.random.Generator | None = None,
        n_points: int | None = None,
    ) -> NDArray[np.float64]:
        """Monte Carlo measurements (m, n_repetitions, n_points) in um: systematic curve + touch noise."""
        o = as_orientations(orientations)
        systematic = self.predict(o, n_points=n_points)
        sigma = self.repetition_sigma(o, n_points=n_points)
        return draw_repetitions(systematic, sigma, n_repetitions, rng)
