"""A measuring campaign: a ring gauge measured by head touches at many head orientations.

Deviations are stored as an array shaped [orientation, repetition, point] in um: the signed
radial distance of each touch from the least-squares circle of its own repetition, positive
outward. Touch times (s since the campaign start), when known, share that shape.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry
from ph_explorer.metrics import noise_floor, noise_law, pooled_sigma

# Two orientations whose A and B agree to this (deg) are the same orientation: the reader groups
# rows by it, orientation_match, the lattice and the off-grid test compare with it. Grouping needs
# keys, so angles are rounded to the matching number of decimals (orientation_keys).
ORIENTATION_DECIMALS = 6
ORIENTATION_TOLERANCE_DEG = 10.0**-ORIENTATION_DECIMALS


def place_in_order(order: NDArray[np.int64]) -> NDArray[np.float64]:
    """Each touch's place in time, 0 (the first touch) to 1 (the last), from its rank in time."""
    return order / max(int(order.max()), 1)


@dataclass
class Campaign:
    """Deviations of a ring measured at many head orientations.

    orientations: (n_orientations, 2) nominal (A0, B0) in degrees.
    deviations: (n_orientations, n_repetitions, n_points) in um.
    times_s: same shape as deviations, or None when the file had no t_s.
    check_orientations: (m, 2) orientations the scenario holds out of training (from a sidecar),
        or None when nothing says so (then the off-grid orientations are used).
    scenario: what a simulate sidecar recorded (name, seed, effects, hidden effects), or {}.
    places: each touch's place in the time order of the campaign this one was taken from (subset),
        0 to 1, or None: its own order's (touch_place).
    """

    orientations: NDArray[np.float64]
    deviations: NDArray[np.float64]
    times_s: NDArray[np.float64] | None = None
    geometry: Geometry = DEFAULT_GEOMETRY
    check_orientations: NDArray[np.float64] | None = None
    scenario: dict[str, Any] = field(default_factory=dict)
    source: str | None = None
    places: NDArray[np.float64] | None = None
    _noise: dict[str, Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.orientations = np.asarray(self.orientations, dtype=float).reshape(-1, 2)
        self.deviations = np.asarray(self.deviations, dtype=float)
        if self.deviations.ndim != 3 or self.deviations.shape[0] != len(self.orientations):
            raise ValueError("deviations must be shaped [orientation, repetition, point]")
        if self.deviations.shape[2] != self.geometry.points_per_circle:
            self.geometry = replace(self.geometry, points_per_circle=self.deviations.shape[2])
        if self.times_s is not None:
            self.times_s = np.asarray(self.times_s, dtype=float)
            if self.times_s.shape != self.deviations.shape:
                raise ValueError("times_s must have the shape of deviations")
        if self.check_orientations is not None:
            self.check_orientations = np.asarray(self.check_orientations, dtype=float).reshape(-1, 2)

    # -- sizes ---------------------------------------------------------------------------------
    @property
    def n_orientations(self) -> int:
        return self.deviations.shape[0]

    @property
    def n_repetitions(self) -> int:
        return self.deviations.shape[1]

    @property
    def n_points(self) -> int:
        return self.deviations.shape[2]

    @property
    def n_touches(self) -> int:
        return int(self.deviations.size)

    # -- simple statistics ---------------------------------------------------------------------
    def mean_curves(self) -> NDArray[np.float64]:
        """Mean deviation curve of each orientation over its repetitions, (n_orientations, n_points)."""
        return self.deviations.mean(axis=1)

    def repetition_sigma(self) -> NDArray[np.float64]:
        """Repetition standard deviation per touch (ddof=1), (n_orientations, n_points)."""
        if self.n_repetitions < 2:
            return np.zeros((self.n_orientations, self.n_points))
        return self.deviations.std(axis=1, ddof=1)

    def noise_sigma_um(self) -> float:
        """Pooled repetition standard deviation per touch (um); NaN for a single repetition."""
        return pooled_sigma(self.deviations)

    def noise_law(self) -> NDArray[np.float64] | None:
        """The touch noise's law, read from the repetitions (metrics.noise_law; None for one repetition)."""
        return self._noise_read()["law"]

    def noise_floor_um(self) -> dict[str, float]:
        """The floors of a perfect model's MAE against the repetition mean and single repetitions (metrics.noise_floor)."""
        return dict(self._noise_read()["floor"])

    def _noise_read(self) -> dict[str, Any]:
        # The law sorts every touch and the floor draws 20 000 means: a diagnosis asks for both at
        # every step, so they are kept, keyed on the deviations' bytes (an edit in place recomputes).
        key = hashlib.blake2b(np.ascontiguousarray(self.deviations).data, digest_size=16).digest()
        if self._noise.get("key") != key:
            law = noise_law(self.deviations)
            if law is not None:
                law.flags.writeable = False
            floor = noise_floor(self.noise_sigma_um(), self.n_repetitions, law=law)
            self._noise = {"key": key, "law": law, "floor": floor}
        return self._noise

    # -- orientations --------------------------------------------------------------------------
    def index_of(self, a_deg: float, b_deg: float) -> int | None:
        """Index of the orientation (A, B), or None when it was not measured."""
        hit = np.flatnonzero(orientation_match(self.orientations, np.array([[a_deg, b_deg]]))[:, 0])
        return int(hit[0]) if hit.size else None

    def grid(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The regular lattice (A values, B values) the orientations lie on."""
        return lattice_axes(self.orientations)

    def off_grid_mask(self) -> NDArray[np.bool_]:
        """True for orientations off the campaign's regular lattice."""
        a_grid, b_grid = self.grid()
        on_a = (np.abs(self.orientations[:, :1] - a_grid[None, :]) <= ORIENTATION_TOLERANCE_DEG).any(axis=1)
        on_b = (np.abs(self.orientations[:, 1:] - b_grid[None, :]) <= ORIENTATION_TOLERANCE_DEG).any(axis=1)
        return ~(on_a & on_b)

    def holdout_mask(self) -> NDArray[np.bool_]:
        """The default held-out orientations: the sidecar's check orientations, else the off-grid ones."""
        if self.check_orientations is not None and len(self.check_orientations):
            return orientation_match(self.orientations, self.check_orientations).any(axis=1)
        return self.off_grid_mask()

    def subset(self, mask: ArrayLike) -> Campaign:
        """The campaign restricted to some orientations (boolean mask or indices)."""
        idx = np.arange(self.n_orientations)[np.asarray(mask)]
        return replace(
            self,
            orientations=self.orientations[idx],
            deviations=self.deviations[idx],
            times_s=None if self.times_s is None else self.times_s[idx],
            places=self.touch_place()[idx],  # rings taken out of a campaign keep their place in its time
        )

    def touch_place(self) -> NDArray[np.float64]:
        """Each touch's place in the campaign's time order, 0 to 1, shaped like deviations: a subset's
        rings keep the place they had (a fit on some rings predicts the others where they were measured)."""
        if self.places is not None:
            return self.places
        return place_in_order(self.touch_order())

    def touch_order(self) -> NDArray[np.int64]:
        """Rank of every touch in time, shaped like deviations.

        From t_s when the file had it; otherwise the scan order of the file: orientation by
        orientation, repetition by repetition, point 0..N-1.
        """
        if self.times_s is None:
            return np.arange(self.n_touches).reshape(self.deviations.shape)
        flat = self.times_s.ravel()
        order = np.empty(flat.size, dtype=np.int64)
        order[np.argsort(flat, kind="stable")] = np.arange(flat.size)
        return order.reshape(self.deviations.shape)


def orientation_label(a_deg: float, b_deg: float) -> str:
    """'A15 B-20': an orientation as the explorer, its lists and a report name it."""
    return f"A{a_deg:g} B{b_deg:g}"


def orientation_keys(angles_deg: ArrayLike) -> NDArray[np.float64]:
    """Angles rounded to the orientation tolerance: rows with equal keys are the same orientation."""
    return np.round(np.asarray(angles_deg, dtype=float), ORIENTATION_DECIMALS)


def orientation_match(orientations: ArrayLike, targets: ArrayLike, atol: float = ORIENTATION_TOLERANCE_DEG) -> NDArray[np.bool_]:
    """(n, m) boolean: orientation i equals target j (A equal, B equal modulo 360)."""
    o = np.asarray(orientations, dtype=float).reshape(-1, 2)
    t = np.asarray(targets, dtype=float).reshape(-1, 2)
    da = np.abs(o[:, None, 0] - t[None, :, 0])
    db = np.abs((o[:, None, 1] - t[None, :, 1] + 180.0) % 360.0 - 180.0)
    return (da <= atol) & (db <= atol)


def b_free_rings(orientations: NDArray[np.float64]) -> NDArray[np.bool_]:
    """The rings at A0 = 0, where B0 means nothing (unless every ring is one): the stylus lies along
    the B axis and the B joint sweeps the full turn over the ring, so every A0 = 0 ring is the same
    ring whatever B0 (docs/methods/trilinear.md#the-a0-0-row)."""
    at_zero = np.abs(orientations[:, 0]) <= ORIENTATION_TOLERANCE_DEG
    return at_zero & (~at_zero).any()


def lattice_axes(orientations: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The A and B values of the regular lattice the orientations lie on.

    A value belongs to the lattice when it is shared by at least half as many orientations as the
    most common value of that angle; a few off-grid rings then never pull in their own angles. An
    A0 = 0 ring's B0 counts for no B value (b_free_rings).
    """
    o = np.asarray(orientations, dtype=float).reshape(-1, 2)
    axes = []
    b_free = b_free_rings(o)
    for column in (0, 1):
        values, counts = np.unique(orientation_keys(o[~b_free, 1] if column else o[:, 0]), return_counts=True)
        if values.size == 0:
            axes.append(values)
            continue
        keep = counts >= max(2, 0.5 * counts.max()) if counts.max() >= 2 else np.ones_like(counts, bool)
        axes.append(values[keep])
    return axes[0], axes[1]
