"""A model's curves predicted once on a dense (A, B) lattice, then read by bilinear interpolation.

The explorer draws a curve per model on every slider move; reading four lattice rows costs
microseconds where a model's prediction costs far more. `PredictionLattice.build` predicts the
lattice in batches when a model loads, then `predict` answers any orientation. A band of A is
trusted only where its checked cell centres are within TOLERANCE_UM of the model; `covers` says
False elsewhere and the caller predicts exactly there. Curves are float32, under MAX_BYTES.

Method: docs/methods/lattice.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.models.deviation_model import DeviationModel, as_orientations

STEP_DEG = 0.5
# A lattice's curves stay under this many bytes: a campaign of 256 points per ring (or A from -115)
# gets a coarser step (1 or 2 deg), where fewer bands pass the check and more is predicted exactly.
MAX_BYTES = 64 * 2**20
COARSER_STEPS_DEG = (1.0, 2.0, 2.5, 5.0)
TOLERANCE_UM = 0.002  # a trusted band's largest error at its checked cell centres, um
CHECK_EVERY = 8  # the cell centres checked: every 8th column of B (90 per band at 0.5 deg)
BATCH = 8192  # orientations predicted per call while building (bounds the temporary arrays)


class BuildStopped(Exception):
    """`PredictionLattice.build` stopped between two batches because its `stop()` said so."""


def _never() -> bool:
    return False


@dataclass(frozen=True)
class PredictionLattice:
    """curves[i, j] = model.predict at (a_low + i step, -180 + j step), B periodic (j wraps)."""

    a_low: float
    step_deg: float
    curves: NDArray[np.float32]  # (n_a, n_b, n_points) um
    trusted: NDArray[np.bool_]  # (n_a - 1,): the band between rows i and i + 1 interpolates the model

    @classmethod
    def build(
        cls,
        model: DeviationModel,
        n_points: int,
        a_range: tuple[float, float],
        step_deg: float | None = None,
        stop: Callable[[], bool] = _never,
    ) -> PredictionLattice:
        """Predict the model at every node of the lattice over a_range (deg) and all of B (the step:
        `step_for` unless given). `stop` is asked before each batch; when it says True the build
        raises BuildStopped (a process that exits must not leave a model's prediction running)."""
        step_deg = step_for(n_points, a_range) if step_deg is None else float(step_deg)
        a_low = float(a_range[0])
        n_a, n_b = cls.shape(a_range, step_deg)
        a = a_low + step_deg * np.arange(n_a)
        b = -180.0 + step_deg * np.arange(n_b)
        grid = np.stack(np.meshgrid(a, b, indexing="ij"), axis=-1).reshape(-1, 2)
        curves = _predict(model, grid, n_points, stop).reshape(n_a, n_b, int(n_points))
        lattice = cls(a_low, float(step_deg), curves, np.ones(max(n_a - 1, 0), dtype=bool))
        # Cell centres of every band, a sample of columns: where the interpolation is checked.
        centres = np.stack(np.meshgrid(a[:-1] + 0.5 * step_deg, b[::CHECK_EVERY] + 0.5 * step_deg, indexing="ij"), axis=-1)
        exact = _predict(model, centres.reshape(-1, 2), n_points, stop)
        error = np.abs(lattice.predict(centres.reshape(-1, 2)) - exact).max(axis=1).reshape(centres.shape[:2])
        lattice.trusted[:] = error.max(axis=1, initial=0.0) <= TOLERANCE_UM
        return lattice

    @staticmethod
    def shape(a_range: tuple[float, float], step_deg: float = STEP_DEG) -> tuple[int, int]:
        """(rows of A, columns of B) of the lattice over a_range."""
        return int(np.ceil((float(a_range[1]) - float(a_range[0])) / step_deg - 1e-9)) + 1, int(round(360.0 / step_deg))

    @classmethod
    def node_count(cls, a_range: tuple[float, float], step_deg: float = STEP_DEG) -> int:
        """How many orientations `build` predicts (the nodes and the checked cell centres)."""
        n_a, n_b = cls.shape(a_range, step_deg)
        return n_a * n_b + (n_a - 1) * len(range(0, n_b, CHECK_EVERY))

    @property
    def a_high(self) -> float:
        return self.a_low + self.step_deg * (self.curves.shape[0] - 1)

    @property
    def n_points(self) -> int:
        return int(self.curves.shape[2])

    def covers(self, a_deg: float) -> bool:
        """Whether the lattice answers at this A (any B): within its range, in a trusted band."""
        x = (float(a_deg) - self.a_low) / self.step_deg
        n_bands = self.trusted.size
        if not -1e-9 <= x <= n_bands + 1e-9:
            return False
        return bool(self.trusted[min(int(max(x, 0.0)), n_bands - 1)]) if n_bands else True

    def predict(self, orientations: ArrayLike) -> NDArray[np.float64]:
        """(m, n_points) um: the bilinear interpolation of the four nodes around each orientation.
        A outside the lattice is clamped to its edge (callers check `covers`)."""
        o = as_orientations(orientations)
        n_a, n_b, _ = self.curves.shape
        x = np.clip((o[:, 0] - self.a_low) / self.step_deg, 0.0, n_a - 1)
        i0 = np.minimum(np.floor(x).astype(int), max(n_a - 2, 0))
        wa = (x - i0)[:, None]
        i1 = np.minimum(i0 + 1, n_a - 1)
        y = np.mod(o[:, 1] + 180.0, 360.0) / self.step_deg
        j0 = np.floor(y).astype(int) % n_b
        wb = (y - np.floor(y))[:, None]
        j1 = (j0 + 1) % n_b
        c = self.curves
        low = (1.0 - wb) * c[i0, j0] + wb * c[i0, j1]
        high = (1.0 - wb) * c[i1, j0] + wb * c[i1, j1]
        return (1.0 - wa) * low + wa * high

    def curve(self, a_deg: float, b_deg: float) -> NDArray[np.float64]:
        """(n_points,) um at one orientation: `predict` in scalar arithmetic (a slider move's few microseconds)."""
        n_a, n_b, _ = self.curves.shape
        x = min(max((float(a_deg) - self.a_low) / self.step_deg, 0.0), n_a - 1.0)
        i0 = min(int(x), max(n_a - 2, 0))
        i1 = min(i0 + 1, n_a - 1)
        y = ((float(b_deg) + 180.0) % 360.0) / self.step_deg
        j0 = int(y)
        wa, wb = x - i0, y - j0
        j0 %= n_b
        j1 = (j0 + 1) % n_b
        c = self.curves
        low = c[i0, j0] * (1.0 - wb) + c[i0, j1] * wb
        high = c[i1, j0] * (1.0 - wb) + c[i1, j1] * wb
        return (low * (1.0 - wa) + high * wa).astype(np.float64)

    @property
    def nbytes(self) -> int:
        return int(self.curves.nbytes)


def _predict(model: DeviationModel, orientations: NDArray[np.float64], n_points: int, stop: Callable[[], bool]) -> NDArray[np.float32]:
    """model.predict in batches of BATCH orientations, as float32 (m, n_points); BuildStopped when stop() says so."""
    curves = np.empty((orientations.shape[0], int(n_points)), dtype=np.float32)
    for start in range(0, orientations.shape[0], BATCH):
        if stop():
            raise BuildStopped
        curves[start : start + BATCH] = model.predict(orientations[start : start + BATCH], n_points=n_points)
    return curves


def step_for(n_points: int, a_range: tuple[float, float], max_bytes: int = MAX_BYTES) -> float:
    """STEP_DEG, or the first coarser step whose lattice of n_points curves fits in max_bytes."""
    for step in (STEP_DEG, *COARSER_STEPS_DEG):
        n_a, n_b = PredictionLattice.shape(a_range, step)
        if n_a * n_b * int(n_points) * 4 <= max_bytes:
            return step
    return COARSER_STEPS_DEG[-1]


def build_cpu_s(model: DeviationModel, n_points: int, a_range: tuple[float, float], sample: int = 512) -> float:
    """The CPU seconds (this thread's) `PredictionLattice.build` would take, from one batch of `sample` orientations."""
    o = np.column_stack([np.linspace(a_range[0], a_range[1], sample), np.linspace(-180.0, 180.0, sample)])
    start = time.thread_time()
    model.predict(o, n_points=n_points)
    return (time.thread_time() - start) * PredictionLattice.node_count(a_range, step_for(n_points, a_range)) / sample
