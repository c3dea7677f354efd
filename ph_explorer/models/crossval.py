"""Out-of-sample predictions for any DeviationModel: the one cross-validation of the project.

Every training ring is predicted by the model fitted on the other training rings
(leave-one-orientation-out, or `folds` groups), every held-out ring by the model fitted on all
training rings; with `strict` a model sees only the rings it may learn from. A model linear in its
data also gives its out-of-sample weights W (n_o x n_o), through which the diagnosis and the
hybrid put an effect's basis columns (Frisch-Waugh-Lovell).

Method: docs/methods/crossval.md.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Sequence
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse

from ph_explorer import metrics
from ph_explorer.campaign import ORIENTATION_DECIMALS, ORIENTATION_TOLERANCE_DEG, Campaign
from ph_explorer.models.deviation_model import DeviationModel, as_orientations
from ph_explorer.models.trilinear import TrilinearModel, leave_one_ring_out_weights

ModelFactory = Callable[[], DeviationModel]
# What a training ring is predicted without: itself ("ring"), or its whole A row ("row": the
# training rings of its nominal A0, when training rows lie on both sides of it; the others by ring).
LeaveOut = Literal["ring", "row"]


def _out_of_sample(
    make_model: ModelFactory,
    campaign: Campaign,
    train: ArrayLike,
    predict: Callable[[DeviationModel, NDArray[np.float64]], NDArray[np.float64]],
    folds: int | None = None,
    strict: bool = False,
    groups: Sequence[NDArray[np.int64]] | None = None,
    held_out: bool = True,
) -> NDArray[np.float64]:
    """predict(model, orientations) at every ring, the model fitted without it (docs/methods/crossval.md).

    `groups` (ring indices left out together) replaces the folds; only the rings in a group are then
    predicted. Without `held_out` the rings outside `train` are not predicted (one fit fewer).
    A ring with no other training ring to learn from, or not predicted, is zero.
    """
    train = np.asarray(train, dtype=bool)
    o = campaign.orientations

    def fitted(mask: NDArray[np.bool_]) -> DeviationModel:
        if strict:
            return make_model().fit(campaign.subset(mask))
        return make_model().fit(campaign, mask)

    parts: list[tuple[NDArray[np.int64], NDArray[np.float64]]] = []
    outside = np.flatnonzero(~train)
    if held_out and outside.size and train.any():
        parts.append((outside, predict(fitted(train), o[outside])))
    rings = np.flatnonzero(train)
    if groups is None:
        groups = (
            [rings[i : i + 1] for i in range(rings.size)] if folds is None else [rings[f::folds] for f in range(min(folds, rings.size))]
        )
    for group in groups:  # one fit per group: a loop over rings, never over touches
        others = train.copy()
        others[group] = False
        if others.any():
            parts.append((group, predict(fitted(others), o[group])))
    width = parts[0][1].shape[1] if parts else campaign.n_points
    out = np.zeros((campaign.n_orientations, width))
    for rows, values in parts:
        out[rows] = values
    return out


def cross_val_predict(
    make_model: ModelFactory,
    campaign: Campaign,
    train: ArrayLike,
    folds: int | None = None,
    strict: bool = False,
    groups: Sequence[NDArray[np.int64]] | None = None,
    held_out: bool = True,
) -> NDArray[np.float64]:
    """Each ring's out-of-sample systematic curve (n_o, n_points) in um (docs/methods/crossval.md; see
    `_out_of_sample` for `groups` and `held_out`)."""
    return _out_of_sample(
        make_model, campaign, train, lambda model, o: model.predict(o, n_points=campaign.n_points), folds, strict, groups, held_out
    )


def held_out_mae(model: DeviationModel, campaign: Campaign, mask: ArrayLike) -> dict[str, float]:
    """A fitted model's MAE (um) over the held-out rings (mask), against the repetition mean and single
    repetitions, every touch predicted (physical terms may depend on the touch order and time)."""
    rings = np.flatnonzero(np.asarray(mask, dtype=bool))
    return metrics.mae(model.predict_held_out(campaign, rings), campaign.deviations[rings])


def held_out_ring_mae(model: DeviationModel, campaign: Campaign, mask: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """Each held-out ring's MAE (um) of a fitted model, against the repetition mean and single
    repetitions ({"mean", "single"}: arrays over the rings of mask, in their order)."""
    rings = np.flatnonzero(np.asarray(mask, dtype=bool))
    return metrics.ring_mae(model.predict_held_out(campaign, rings), campaign.deviations[rings])


def unit_campaign(orientations: ArrayLike) -> Campaign:
    """One ring per orientation holding a unit vector in place of its points: a model linear in its
    data (the trilinear tables, the mean curve), fitted on it, interpolates its own weights."""
    o = as_orientations(orientations)
    return Campaign(o, np.eye(len(o))[:, None, :])


# The last few W made (read-only): a diagnosis asks for the same rings' W in its search, its
# within-noise tests and its hybrid fits; each is n_o^2 floats (146 kB for 135 rings).
_WEIGHTS: dict[tuple, NDArray[np.float64]] = {}
WEIGHTS_KEPT = 16
SPARSE_SHARE = 0.1  # a W with at most this share of nonzero weights is applied as a sparse matrix
_WEIGHTS_LOCK = threading.Lock()  # the explorer's sessions diagnose in threads


def _interpolate(model: DeviationModel, at: NDArray[np.float64]) -> NDArray[np.float64]:
    return model.interpolate(at)


def out_of_sample_weights(
    orientations: ArrayLike, train: ArrayLike, model_type: ModelFactory = TrilinearModel, leave_out: LeaveOut = "ring"
) -> NDArray[np.float64]:
    """W (n_o x n_o) of a model linear in its data: row i predicts orientation i out of sample
    (its interpolation of unit vectors, before any circle fit: unit_campaign). Read-only.
    model_type: a model class, or a hashable factory (a GP with its kernel fixed). leave_out: what
    a training ring is predicted without (LeaveOut; docs/methods/crossval.md)."""
    o, mask = as_orientations(orientations), np.asarray(train, dtype=bool)
    key = (model_type, o.shape, o.tobytes(), mask.tobytes(), leave_out)
    weights = _WEIGHTS.get(key)
    if weights is None:
        if leave_out == "row":
            weights = _row_weights(o, mask, model_type)
        elif model_type is TrilinearModel and mask.any():
            weights = _trilinear_weights(o, mask)
        else:
            weights = _out_of_sample(model_type, unit_campaign(o), mask, _interpolate)
        weights.flags.writeable = False
        with _WEIGHTS_LOCK:
            while len(_WEIGHTS) >= WEIGHTS_KEPT:
                _WEIGHTS.pop(next(iter(_WEIGHTS)))  # the oldest first
            _WEIGHTS[key] = weights
    return weights


def _trilinear_weights(orientations: NDArray[np.float64], train: NDArray[np.bool_]) -> NDArray[np.float64]:
    """The trilinear model's W from one fit (trilinear.leave_one_ring_out_weights), with a refit for
    each ring it cannot read off that fit: the same W as a refit for every ring, several times faster."""
    unit = unit_campaign(orientations)
    try:
        weights, refit = leave_one_ring_out_weights(unit, train)
    except ValueError:  # the training rings together put none on a node: each refit says what it can
        return _out_of_sample(TrilinearModel, unit, train, _interpolate)
    if refit.size:
        groups = [refit[i : i + 1] for i in range(refit.size)]
        weights[refit] = _out_of_sample(TrilinearModel, unit, train, _interpolate, groups=groups, held_out=False)[refit]
    return weights


def inner_rows(orientations: NDArray[np.float64], train: NDArray[np.bool_]) -> list[NDArray[np.int64]]:
    """The training rings of each nominal A0 with training rings at a lower and a higher A0 (an A row
    the data part interpolates from the rows on both sides), as index arrays."""
    a = orientations[:, 0]
    levels = np.unique(np.round(a[train], ORIENTATION_DECIMALS))
    return [np.flatnonzero(train & np.isclose(a, level, rtol=0.0, atol=ORIENTATION_TOLERANCE_DEG)) for level in levels[1:-1]]


def _row_weights(orientations: NDArray[np.float64], train: NDArray[np.bool_], model_type: ModelFactory) -> NDArray[np.float64]:
    """W with each inner A row's training rings predicted without their whole row (inner_rows),
    every other ring as out_of_sample_weights predicts it: an error of the A joint, the same along
    its row, is carried exactly by a lattice ring's B neighbours and shows only without them."""
    weights = np.array(out_of_sample_weights(orientations, train, model_type))
    rows = inner_rows(orientations, train)
    if rows:
        by_row = _out_of_sample(model_type, unit_campaign(orientations), train, _interpolate, groups=rows, held_out=False)
        every = np.concatenate(rows)
        weights[every] = by_row[every]
    return weights


def weights_operator(weights: NDArray[np.float64]) -> NDArray[np.float64] | sparse.csr_array:
    """W as weighted() applies it: an interpolator's W has a few neighbours a row (2-8 of hundreds
    of rings), and as a sparse matrix its product costs that many multiplications a value, not n_o."""
    return sparse.csr_array(weights) if np.count_nonzero(weights) <= SPARSE_SHARE * weights.size else weights


def weighted(operator: NDArray[np.float64] | sparse.csr_array, values: NDArray[np.float64]) -> NDArray[np.float64]:
    """W @ values over the first axis of values (n_o, ...), W from weights_operator."""
    values = np.asarray(values)
    if isinstance(operator, np.ndarray):
        return np.tensordot(operator, values, axes=(1, 0))
    return (operator @ values.reshape(values.shape[0], -1)).reshape((operator.shape[0],) + values.shape[1:])


class OutOfSampleSmoother:
    """W (n_o x n_o) and what it does to arrays over orientations (see out_of_sample_weights)."""

    def __init__(
        self, orientations: ArrayLike, train: ArrayLike, model_type: ModelFactory = TrilinearModel, leave_out: LeaveOut = "ring"
    ) -> None:
        self.train = np.asarray(train, dtype=bool)
        self.model_name = model_type.name  # the model whose out-of-sample predictions W makes
        self.leave_out = leave_out
        self.weights = out_of_sample_weights(orientations, self.train, model_type, leave_out)
        self._operator = weights_operator(self.weights)

    def predict(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """Out-of-sample prediction of values shaped (n_o, ...)."""
        return weighted(self._operator, values)

    def noise_floor(self, sigma_um: float, n_repetitions: int, law: NDArray[np.float64] | None = None) -> dict[str, NDArray[np.float64]]:
        """Each ring's floor of its out-of-sample MAE: its own noise and that of the rings predicting it
        (law: the touch noise's, metrics.noise_law)."""
        return metrics.noise_floor(sigma_um, n_repetitions, neighbour_weights_sq=(self.weights**2).sum(axis=1), law=law)

    def residual(self, values: NDArray[np.float64]) -> NDArray[np.float64]:
        """values (n_o, n_rep, n_pt, ...) minus the out-of-sample prediction of their repetition mean."""
        return values - self.predict(values.mean(axis=1))[:, None]
