"""Trilinear interpolation + Monte Carlo, after Gaska, Gaska and Gruza 2016 (Appl. Sci. 6, 144).

The paper's baseline: two tables over the measured lattice, (A, B, theta) -> the repetitions'
mean deviation and their standard deviation. A prediction is the trilinear interpolation of the
mean table (B and theta periodic, A linear and clamped); a simulated measurement adds a Gaussian
draw with the interpolated spread. Nodes without data are filled first along B, then along A;
orientations off the lattice do not enter the tables.

Method: docs/methods/trilinear.md.
"""

from __future__ import annotations

from pathlib import Path
from typing import Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import ORIENTATION_TOLERANCE_DEG, Campaign, b_free_rings, lattice_axes, orientation_keys
from ph_explorer.geometry import point_angles_deg, wrap_deg
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.models.deviation_model import DeviationModel, as_orientations, pooled_repetition_variance, save_arrays, training_mask

FILE_NAME = "trilinear.npz"


def linear_weights(x: ArrayLike, nodes: NDArray[np.float64]) -> tuple[NDArray, NDArray, NDArray]:
    """Bracketing node indices (i0, i1) and weight w of i1 for linear interpolation, clamped at the ends."""
    x = np.asarray(x, dtype=float)
    if nodes.size == 1:
        zero = np.zeros(x.shape, dtype=int)
        return zero, zero, np.zeros(x.shape)
    xc = np.clip(x, nodes[0], nodes[-1])
    i1 = np.clip(np.searchsorted(nodes, xc, side="right"), 1, nodes.size - 1)
    i0 = i1 - 1
    w = (xc - nodes[i0]) / (nodes[i1] - nodes[i0])
    return i0, i1, w


def periodic_weights(x: ArrayLike, nodes: NDArray[np.float64], period: float = 360.0) -> tuple[NDArray, NDArray, NDArray]:
    """Like linear_weights on a circle: nodes sorted in [start, start + period), x any angle."""
    x = np.asarray(x, dtype=float)
    if nodes.size == 1:
        zero = np.zeros(x.shape, dtype=int)
        return zero, zero, np.zeros(x.shape)
    # Map x into [nodes[0], nodes[0] + period); the last interval wraps to node 0.
    xr = nodes[0] + np.mod(x - nodes[0], period)
    extended = np.append(nodes, nodes[0] + period)
    i1 = np.clip(np.searchsorted(extended, xr, side="right"), 1, nodes.size)
    i0 = i1 - 1
    w = (xr - extended[i0]) / (extended[i1] - extended[i0])
    return i0, i1 % nodes.size, w


def fill_missing_nodes(
    table: NDArray[np.float64], measured: NDArray[np.bool_], a_axis: NDArray[np.float64], b_axis: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Fill lattice nodes without data: along B within each A row, then whole rows along A.

    table (n_a, n_b, n_pt), measured (n_a, n_b). Loops run over the few A rows only.
    """
    filled = table.copy()
    row_has_data = measured.any(axis=1)
    if not row_has_data.any():
        raise ValueError("no lattice node has data")
    for i in np.flatnonzero(row_has_data):
        known = np.flatnonzero(measured[i])
        missing = np.flatnonzero(~measured[i])
        if missing.size == 0:
            continue
        j0, j1, w = periodic_weights(b_axis[missing], b_axis[known])
        filled[i, missing] = (1 - w)[:, None] * table[i, known[j0]] + w[:, None] * table[i, known[j1]]
    rows = np.flatnonzero(row_has_data)
    empty = np.flatnonzero(~row_has_data)
    if empty.size:
        i0, i1, w = linear_weights(a_axis[empty], a_axis[rows])
        filled[empty] = (1 - w)[:, None, None] * filled[rows[i0]] + w[:, None, None] * filled[rows[i1]]
    return filled


class TrilinearModel(DeviationModel):
    """Mean and spread tables over (A, B, theta), trilinearly interpolated (Gaska et al. 2016)."""

    name = "trilinear"
    file_name = FILE_NAME

    def __init__(self) -> None:
        self.a_axis: NDArray[np.float64] | None = None  # (n_a,) deg, ascending
        self.b_axis: NDArray[np.float64] | None = None  # (n_b,) deg, ascending in [-180, 180)
        self.mean_table: NDArray[np.float64] | None = None  # (n_a, n_b, n_pt) um, gaps filled
        self._sigma_table: NDArray[np.float64] | None = None  # (n_a, n_b, n_pt) um, gaps filled (sigma_table)
        self._node_sigma: NDArray[np.float64] | None = None  # the measured nodes' sigma, its gaps filled when asked
        self.measured: NDArray[np.bool_] | None = None  # (n_a, n_b) node had training data
        self.n_points = 64

    # -- learning --------------------------------------------------------------------------------
    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        mask = training_mask(campaign, train)
        if not mask.any():
            raise ValueError("the trilinear model needs at least one training orientation")
        orientations = campaign.orientations[mask]
        a_axis, b_values = lattice_axes(orientations)
        zero_row = a0_row_rings(orientations, a_axis)
        a_axis = np.r_[0.0, a_axis] if zero_row.any() else a_axis
        b_axis = np.unique(orientation_keys(wrap_deg(b_values)))
        # Node index of each training orientation, or -1 off the lattice.
        ia = _node_index(orientations[:, 0], a_axis)
        ib = _node_index(wrap_deg(orientations[:, 1]), b_axis)
        on = (ia >= 0) & (ib >= 0) & ~zero_row
        if not (on.any() or zero_row.any()):
            raise ValueError("no training orientation lies on the campaign's lattice")
        n_pt = campaign.n_points
        deviations = campaign.deviations[mask]  # (n_train, n_rep, n_pt)
        # Pool the repetitions of every orientation on each node (a node measured twice pools both).
        shape = (a_axis.size, b_axis.size)
        node = np.ravel_multi_index((ia[on], ib[on]), shape)
        total = _node_sums(node, deviations[on].sum(axis=1), shape)
        total_sq = _node_sums(node, (deviations[on] ** 2).sum(axis=1), shape)
        count = _node_sums(node, np.full(node.size, float(deviations.shape[1])), shape)
        # The A0 = 0 rings pooled at every node of their row (a0_row_rings).
        total[0] += deviations[zero_row].sum(axis=(0, 1))
        total_sq[0] += (deviations[zero_row] ** 2).sum(axis=(0, 1))
        count[0] += float(zero_row.sum() * deviations.shape[1])
        measured = count > 0
        c = np.where(measured, count, 1.0)[..., None]
        mean = total / c
        # Repetition variance with ddof=1 (zero when a node has a single repetition).
        variance = np.where(c > 1, (total_sq - c * mean**2) / np.maximum(c - 1, 1), 0.0)
        self.a_axis, self.b_axis, self.measured = a_axis, b_axis, measured
        self.mean_table = fill_missing_nodes(mean, measured, a_axis, b_axis)
        self._sigma_table, self._node_sigma = None, np.sqrt(np.maximum(variance, 0.0))
        self.n_points = n_pt
        return self

    @property
    def sigma_table(self) -> NDArray[np.float64] | None:
        """(n_a, n_b, n_pt) um, gaps filled: made when first asked (out-of-sample weights fit a
        model per ring and ask only for its means)."""
        node_sigma = self._node_sigma  # read once: the explorer's sessions may ask at the same time
        if self._sigma_table is None and node_sigma is not None:
            self._sigma_table = fill_missing_nodes(node_sigma, self.measured, self.a_axis, self.b_axis)
            self._node_sigma = None
        return self._sigma_table

    @sigma_table.setter
    def sigma_table(self, table: NDArray[np.float64] | None) -> None:
        self._sigma_table, self._node_sigma = table, None

    # -- interpolation -------------------------------------------------------------------------
    def _interpolate(self, table: NDArray[np.float64], orientations: ArrayLike, n_points: int | None) -> NDArray[np.float64]:
        if table is None or self.a_axis is None or self.b_axis is None:
            raise RuntimeError("the trilinear model is not fitted")
        o = as_orientations(orientations)
        ia0, ia1, wa = linear_weights(o[:, 0], self.a_axis)
        ib0, ib1, wb = periodic_weights(o[:, 1], self.b_axis)
        wa, wb = wa[:, None], wb[:, None]
        curves = (
            (1 - wa) * (1 - wb) * table[ia0, ib0]
            + (1 - wa) * wb * table[ia0, ib1]
            + wa * (1 - wb) * table[ia1, ib0]
            + wa * wb * table[ia1, ib1]
        )  # (m, n_pt_table)
        n = self.n_points if n_points is None else int(n_points)
        if n == self.n_points:
            return curves
        it0, it1, wt = periodic_weights(point_angles_deg(n), point_angles_deg(self.n_points))
        return (1 - wt) * curves[:, it0] + wt * curves[:, it1]

    def interpolate(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """The mean table interpolated at orientations, on the table's own points, with no circle fit.

        Linear in the data the model was fitted on, whatever the last axis holds: the diagnosis
        fits it on unit vectors to obtain its interpolation weights.
        """
        return self._interpolate(self.mean_table, orientations, None)

    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        # The tables hold post-fit curves; interpolation in theta to another N can leak a little of
        # harmonics 0 and 1 back in, so the circle fit is applied again.
        return remove_size_and_centre(self._interpolate(self.mean_table, orientations, n_points))

    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        return self._interpolate(self.sigma_table, orientations, n_points)

    # -- files ---------------------------------------------------------------------------------
    def save(self, directory: str | Path) -> Path:
        if self.mean_table is None:
            raise RuntimeError("the trilinear model is not fitted")
        return save_arrays(
            directory,
            self.file_name,
            a_axis=self.a_axis,
            b_axis=self.b_axis,
            mean_table=self.mean_table,
            sigma_table=self.sigma_table,
            measured=self.measured,
            n_points=np.array(self.n_points),
        )

    @classmethod
    def load(cls, directory: str | Path) -> Self:
        path = Path(directory) / cls.file_name
        model = cls()
        with np.load(path, allow_pickle=False) as data:
            model.a_axis = data["a_axis"].astype(float)
            model.b_axis = data["b_axis"].astype(float)
            model.mean_table = data["mean_table"].astype(float)
            model.sigma_table = data["sigma_table"].astype(float)
            model.measured = data["measured"].astype(bool)
            model.n_points = int(data["n_points"])
        return model


class MeanCurveModel(TrilinearModel):
    """The mean deviation curve of the training rings, the same at every orientation.

    The trilinear model on a single node: the least flexible data-driven part. Beside physical
    terms that carry the orientation dependence, it predicts a ring with the noise of every
    training ring averaged, where the interpolation carries the noise of the few rings around it
    (MAE against the mean: the floor times sqrt(1 + sum of squared weights)). The data-efficiency
    benchmark's stacked hybrid weighs it by its own cross-validation (benchmarks/stacking.py,
    experiment code).
    """

    name = "mean_curve"
    file_name = "mean_curve.npz"

    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        mask = training_mask(campaign, train)
        if not mask.any():
            raise ValueError("the mean curve needs at least one training orientation")
        deviations = campaign.deviations[mask]  # (n_train, n_rep, n_pt)
        # The spread of single touches about their ring's mean, pooled over the rings (ddof=1).
        variance = pooled_repetition_variance(deviations)
        self.a_axis, self.b_axis = np.zeros(1), np.zeros(1)
        self.measured = np.ones((1, 1), dtype=bool)
        self.mean_table = deviations.mean(axis=(0, 1))[None, None]
        self.sigma_table = np.sqrt(variance)[None, None]
        self.n_points = campaign.n_points
        return self


def a0_row_rings(orientations: NDArray[np.float64], a_axis: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The rings at A0 = 0 when the lattice's rule leaves their row out (fewer of them than its rows
    hold): every A0 = 0 ring is the same ring whatever B0 (the stylus along the B axis, its B joint
    sweeping the full turn), so they are pooled into the whole row, and the model interpolates from
    it below the lowest row instead of holding that row's curves there (docs/methods/trilinear.md)."""
    held = (np.abs(a_axis) <= ORIENTATION_TOLERANCE_DEG).any()
    return b_free_rings(orientations) & ~held


def _node_sums(node: NDArray[np.intp], values: NDArray[np.float64], shape: tuple[int, int]) -> NDArray[np.float64]:
    """Sums of values (n, ...) over rows with the same flat node index, on the lattice shape: each
    node's first row assigned, the few repeats then added in order (np.add.at's sums bit for bit;
    np.add.at alone scatters slowly, and most nodes are measured once)."""
    out = np.zeros((shape[0] * shape[1],) + values.shape[1:])
    if not node.size:  # every ring in the pooled A0 row (a0_row_rings)
        return out.reshape(shape + values.shape[1:])
    order = np.argsort(node, kind="stable")
    nodes = node[order]
    first = np.r_[True, nodes[1:] != nodes[:-1]]
    out[nodes[first]] = values[order[first]]
    if not first.all():
        np.add.at(out, nodes[~first], values[order[~first]])
    return out.reshape(shape + values.shape[1:])


def _node_index(values: NDArray[np.float64], axis: NDArray[np.float64]) -> NDArray[np.int64]:
    """Index of each value on the axis, -1 when it is not a node."""
    hit = np.abs(values[:, None] - axis[None, :]) <= ORIENTATION_TOLERANCE_DEG
    return np.where(hit.any(axis=1), hit.argmax(axis=1), -1)


def leave_one_ring_out_weights(unit: Campaign, train: NDArray[np.bool_]) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """The trilinear model's out-of-sample weights W (models.crossval.out_of_sample_weights) from one
    fit, not one per ring: where a training ring alone on its node, at the node itself, leaves the
    lattice as it was, the model without it differs only at that node, filled from the others (the
    same arithmetic as fill_missing_nodes). `unit`: crossval.unit_campaign of the orientations.
    Returns W and the training rings left to a refit each (docs/methods/crossval.md)."""
    orientations, n = unit.orientations, unit.n_orientations
    full = TrilinearModel().fit(unit, train)
    weights = np.zeros((n, n))
    if (~train).any():
        weights[~train] = full.interpolate(orientations[~train])
    rings = np.flatnonzero(train)
    o = orientations[rings]
    ia, ib = _node_index(o[:, 0], full.a_axis), _node_index(wrap_deg(o[:, 1]), full.b_axis)
    node = np.where((ia >= 0) & (ib >= 0), ia * full.b_axis.size + ib, -1)
    alone = (node >= 0) & (np.bincount(node[node >= 0], minlength=full.measured.size)[np.maximum(node, 0)] == 1)
    # Interpolated at its node exactly: weight 1 on that node, 0 on the other corners.
    a0, a1, wa = linear_weights(o[:, 0], full.a_axis)
    b0, b1, wb = periodic_weights(o[:, 1], full.b_axis)
    exact = (((wa == 0) & (a0 == ia)) | ((wa == 1) & (a1 == ia))) & (((wb == 0) & (b0 == ib)) | ((wb == 1) & (b1 == ib)))
    b_kept, b_free = np.ones(len(o), dtype=bool), b_free_rings(o)
    b_kept[~b_free] = _axis_kept_without_each(o[~b_free, 1])  # as lattice_axes: an A0 = 0 ring's B0 counts for none
    fast = alone & exact & _axis_kept_without_each(o[:, 0]) & b_kept
    fast &= ~a0_row_rings(o, lattice_axes(o)[0])  # its row pooled: without it, the row may be gone
    rows_with_data = full.measured.any(axis=1)
    for k in np.flatnonzero(fast):  # a few small arrays per ring: the fill at one node
        ra, rb = ia[k], ib[k]
        known = np.flatnonzero(full.measured[ra] & (np.arange(full.b_axis.size) != rb))
        if known.size:  # along B within its row, as fill_missing_nodes
            j0, j1, w = periodic_weights(full.b_axis[[rb]], full.b_axis[known])
            weights[rings[k]] = ((1 - w)[:, None] * full.mean_table[ra, known[j0]] + w[:, None] * full.mean_table[ra, known[j1]])[0]
            continue
        rows = np.flatnonzero(rows_with_data & (np.arange(full.a_axis.size) != ra))
        if not rows.size:
            fast[k] = False  # no data left: the refit says so
            continue
        i0, i1, w = linear_weights(full.a_axis[[ra]], full.a_axis[rows])  # its row emptied: along A
        weights[rings[k]] = ((1 - w)[:, None] * full.mean_table[rows[i0], rb] + w[:, None] * full.mean_table[rows[i1], rb])[0]
    return weights, rings[~fast]


def _axis_kept_without_each(angles: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Per orientation: would lattice_axes keep the same values of this angle without it?"""
    values, inverse, counts = np.unique(orientation_keys(angles), return_inverse=True, return_counts=True)

    def kept(c: NDArray[np.int64]) -> NDArray[np.bool_]:  # lattice_axes's rule, a value of count 0 gone
        return (c > 0) & (c >= max(2, 0.5 * c.max())) if c.max() >= 2 else c > 0

    base = kept(counts)
    same = np.array([np.array_equal(kept(counts - (np.arange(values.size) == j)), base) for j in range(values.size)], dtype=bool)
    return same[inverse]
