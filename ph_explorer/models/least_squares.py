"""The least squares of physical terms on out-of-sample residuals.

A physical effect's basis columns go through the out-of-sample smoother W of the data-driven part
(ph_explorer.models.crossval), so that a term is only credited with what that part does not
already capture; its coefficients are then the least squares of the residual on the residualised
columns (Frisch-Waugh-Lovell: the joint fit of the physical terms with the data-driven part).
Sums over single touches split into the repetition mean and the part that changes between
repetitions (sum over reps |x|^2 = n_rep |mean|^2 + |within|^2), so every product is taken on the
small mean part, and on the within part only for effects that change between repetitions.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ph_explorer.models.crossval import OutOfSampleSmoother

# Columns the smoother predicts exactly at more than this share of the training rings (an error of
# the A joint on a lattice: each ring's B neighbours in its row carry it) are read with whole A
# rows left out too (crossval.LeaveOut "row"), where those rings can show them: a shape's search
# (diagnosis.shapes.view_of), and a hybrid's fit when fewer rings show them than they have columns.
UNSEEN_SHARE = 0.5


def unseen_at_most(seen: NDArray[np.bool_], train: NDArray[np.bool_]) -> bool:
    """Whether the rings that see some columns (Design.seen_rings) are fewer than 1 - UNSEEN_SHARE of
    the training rings."""
    return bool(train.any()) and 1.0 - float(seen[train].mean()) > UNSEEN_SHARE


def _ring_products(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """(n_o, c, k): each ring's a^T b over its touches, for a (n_o, ..., c) and b (n_o, ..., k) (a
    batched matrix product: einsum's loop is ten times slower on these shapes)."""
    n_o = a.shape[0]
    a, b = a.reshape(n_o, -1, a.shape[-1]), b.reshape(n_o, -1, b.shape[-1])
    return np.matmul(a.transpose(0, 2, 1), b)


class Design:
    """Columns (n_o, n_rep, n_pt, c) put through the smoother, split into mean and within parts."""

    def __init__(self, columns: NDArray[np.float64], smoother: OutOfSampleSmoother | None, owned: bool = False) -> None:
        """owned: the caller gives up `columns`, which become the within part in place (no copy as large)."""
        columns = np.asarray(columns, dtype=float)
        self.n_rep = columns.shape[1]
        # Columns broadcast over the repetitions (fitted_basis) are the same in every one: no within part.
        broadcast = self.n_rep == 1 or columns.strides[1] == 0
        mean = columns[:, 0] if broadcast else columns.mean(axis=1)
        self.mean = mean - smoother.predict(mean) if smoother is not None else mean  # (n_o, n_pt, c)
        self.scale = _largest_magnitude(mean if broadcast else columns)
        if broadcast:
            within = None
        elif owned:
            within = columns
            within -= mean[:, None]
        else:
            within = columns - mean[:, None]  # a new array: columns are the caller's
        changes = within is not None and _largest_magnitude(within) > 1e-9 * max(self.scale, 1e-300)
        self.within = within if changes else None  # (n_o, n_rep, n_pt, c) or None
        self._flat: tuple[NDArray[np.float64], NDArray[np.float64] | None] | None = None
        self._ring_gram: NDArray[np.float64] | None = None
        self._gram: NDArray[np.float64] | None = None

    @property
    def n_columns(self) -> int:
        return self.mean.shape[-1]

    def ring_gram(self) -> NDArray[np.float64]:
        """(n_o, c, c): each ring's share of X^T X over single touches, made once (read-only)."""
        if getattr(self, "_ring_gram", None) is None:
            g = self.n_rep * _ring_products(self.mean, self.mean)
            if self.within is not None:
                g = g + _ring_products(self.within, self.within)
            g.flags.writeable = False
            self._ring_gram = g
        return self._ring_gram

    def ring_dot(self, targets: Design) -> NDArray[np.float64]:
        """(n_o, c, k): each ring's share of X^T y for the k target columns."""
        b = self.n_rep * _ring_products(self.mean, targets.mean)
        if self.within is not None and targets.within is not None:
            b = b + _ring_products(self.within, targets.within)
        return b

    def flat(self) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """The mean and within parts as contiguous (rows, c) matrices, made once."""
        if getattr(self, "_flat", None) is None:
            c = self.n_columns
            within = None if self.within is None else np.ascontiguousarray(self.within.reshape(-1, c))
            self._flat = (np.ascontiguousarray(self.mean.reshape(-1, c)), within)
        return self._flat

    def touch_blocks(self) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Rows whose products are those over single touches: (sqrt(n_rep) * mean rows, within rows
        or None), n_rep times fewer rows than the touches when nothing changes between repetitions."""
        mean, within = self.flat()
        return np.sqrt(self.n_rep) * mean, within

    def gram(self) -> NDArray[np.float64]:
        """(c, c): X^T X over single touches, made once (read-only: a fit, its ridge and its jackknife each ask)."""
        if getattr(self, "_gram", None) is None:
            mean, within = self.flat()
            g = self.n_rep * (mean.T @ mean)  # the small product scaled: no scaled copy of the columns
            self._gram = g if within is None else g + within.T @ within
            self._gram.flags.writeable = False
        return self._gram

    def dot(self, targets: Design) -> NDArray[np.float64]:
        mean, within = self.flat()
        t_mean, t_within = targets.flat()
        b = self.n_rep * (mean.T @ t_mean)
        return b if within is None or t_within is None else b + within.T @ t_within

    def total(self) -> NDArray[np.float64]:
        """(c,): each column's sum of squares over single touches."""
        t = self.n_rep * (self.mean**2).sum(axis=(0, 1))
        return t if self.within is None else t + (self.within**2).sum(axis=(0, 1, 2))

    def apply(self, coef: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """The fitted terms X coef: (mean part (n_o, n_pt, ...), within part or None)."""
        within = None if self.within is None else self.within @ coef
        return self.mean @ coef, within

    def apply_each(self, coef: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """The fitted terms with each ring's own coefficients coef (n_o, c), e.g. a jackknife's:
        (mean part (n_o, n_pt), within part (n_o, n_rep, n_pt) or None)."""
        within = None if self.within is None else np.einsum("orpc,oc->orp", self.within, coef)
        return np.einsum("opc,oc->op", self.mean, coef), within

    def seen_rings(self, columns: slice = slice(None)) -> NDArray[np.bool_]:
        """(n_o,): the rings at which the smoother does not predict the columns exactly (where a
        ring's out-of-sample residual can show them)."""
        energy = (self.mean[..., columns] ** 2).reshape(self.mean.shape[0], -1).sum(axis=1)
        if self.within is not None:
            energy = energy + (self.within[..., columns] ** 2).reshape(self.within.shape[0], -1).sum(axis=1)
        return energy > 1e-12 * max(float(energy.max(initial=0.0)), 1e-300)

    def unseen_at_most(self, train: NDArray[np.bool_], columns: slice = slice(None)) -> bool:
        """Whether the smoother predicts the columns exactly at more than UNSEEN_SHARE of the
        training rings (their out-of-sample residual cannot show them there)."""
        return unseen_at_most(self.seen_rings(columns), train)

    def beside(self, other: Design, rings: NDArray[np.bool_]) -> Design:
        """For fits (fit, jackknife, choose_ridge): this design with another view's mean part at the
        given rings appended as further points of each ring (zeros elsewhere), so that a fit
        minimises both views' sums of squares and a ring's two parts are left out together."""
        out = object.__new__(Design)
        out._flat = out._ring_gram = out._gram = None
        out.n_rep, out.scale, out.within = self.n_rep, max(self.scale, other.scale), self.within
        out.mean = np.concatenate([self.mean, other.mean * np.asarray(rings, dtype=bool)[:, None, None]], axis=1)
        return out

    def first_column(self) -> Design:
        """A view of column 0 only (the data, where the other columns are noise draws)."""
        out = object.__new__(Design)
        out._flat = out._ring_gram = out._gram = None
        out.n_rep, out.scale = self.n_rep, self.scale
        out.mean = self.mean[..., :1]
        out.within = None if self.within is None else self.within[..., :1]
        return out

    def stacked(self, other: Design) -> Design:
        """The columns of self then other."""
        out = object.__new__(Design)
        out._flat = out._ring_gram = out._gram = None
        out.n_rep, out.scale = self.n_rep, max(self.scale, other.scale)
        out.mean = np.concatenate([self.mean, other.mean], axis=-1)
        if self.within is None and other.within is None:
            out.within = None
        else:
            parts = [
                d.within if d.within is not None else np.zeros(d.mean.shape[:1] + (self.n_rep,) + d.mean.shape[1:]) for d in (self, other)
            ]
            out.within = np.concatenate(parts, axis=-1)
        return out


def _largest_magnitude(x: NDArray[np.float64]) -> float:
    """max |x| (0 when empty) without an |x| array as large as x."""
    return float(max(x.max(), -x.min())) if x.size else 0.0


def _kept(values: NDArray[np.float64], scale: float, n_rows: int) -> NDArray[np.bool_]:
    """The eigen-directions solve() keeps: eigenvalues above 1e-12 of the columns' scale squared
    times the rows (below it the smoother already predicts them: nothing out of sample)."""
    return values > 1e-12 * max(scale**2 * n_rows, 1e-300)


def solve(gram: NDArray[np.float64], dot: NDArray[np.float64], scale: float, n_rows: int, ridge: float = 0.0) -> tuple[NDArray, NDArray]:
    """Least squares from the normal equations: (coefficients (c, k), explained sum of squares (k,)).

    Directions the smoother already predicts (eigenvalues below 1e-12 of the columns' scale
    squared times the rows) carry nothing out of sample and are dropped. `ridge` adds a penalty
    ridge * |coef|^2 (see choose_ridge).
    """
    values, vectors = np.linalg.eigh(gram)
    keep = _kept(values, scale, n_rows)
    if not keep.any():
        return np.zeros(dot.shape), np.zeros(dot.shape[1])
    projected = vectors[:, keep].T @ dot
    shrunk = projected / (values[keep, None] + ridge)
    coef = vectors[:, keep] @ shrunk
    return coef, (projected * shrunk).sum(axis=0) if ridge else (projected**2 / values[keep, None]).sum(axis=0)


def _rows(design: Design) -> int:
    return design.mean.shape[0] * design.mean.shape[1]


def fit(design: Design, targets: Design, ridge: float = 0.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Coefficients (c, k) and explained sums of squares (k,) of every target column on the design."""
    return solve(design.gram(), design.dot(targets), design.scale, _rows(design), ridge)


def _pseudo_inverse(gram: NDArray[np.float64], scale: float, n_rows: int) -> NDArray[np.float64]:
    """gram's pseudo-inverse over the directions solve() keeps, for a stack (..., c, c)."""
    values, vectors = np.linalg.eigh(gram)
    keep = _kept(values, scale, n_rows)
    inverse = np.where(keep, 1.0 / np.where(keep, values, 1.0), 0.0)
    return np.einsum("...ij,...j,...kj->...ik", vectors, inverse, vectors)


def _side_by_side(parts: list[NDArray[np.float64]], c: int) -> NDArray[np.float64]:
    """(S, c, rows): each design's columns (..., c) as the rows of one contiguous matrix, so that
    every product below is one batched BLAS call."""
    return np.stack([part.reshape(-1, c).T for part in parts])


def _each_times(parts: NDArray[np.float64], other: NDArray[np.float64]) -> NDArray[np.float64]:
    """(S, c, k): parts (S, c, rows) @ other (rows, k) as one matrix product (numpy's batched matmul
    calls BLAS once per design: 3-7x slower on these shapes)."""
    s, c, rows = parts.shape
    return (parts.reshape(s * c, rows) @ other).reshape(s, c, -1)


def explained_beyond(fixed: Design | None, designs: list[Design], targets: Design) -> NDArray[np.float64]:
    """(len(designs), k): what each design explains of every target column beyond `fixed`, all at once.

    The same figure as fit(fixed.stacked(d), targets)[1] - fit(fixed, targets)[1] for each design d,
    by Frisch-Waugh-Lovell: each design's columns are residualised on fixed's through their
    ring-level products, so fixed's own products are made once. The designs share a column count.
    """
    c = designs[0].n_columns
    n_rep = targets.n_rep
    means = _side_by_side([d.mean for d in designs], c)  # (S, c, rows)
    t_mean, t_within = targets.flat()
    u = n_rep * _each_times(means, t_mean)  # (S, c, k)
    gram = n_rep * (means @ np.swapaxes(means, 1, 2))  # (S, c, c)
    withins = [d.within for d in designs]
    changing = any(w is not None for w in withins)
    if changing:
        shape = targets.mean.shape[:1] + (n_rep,) + targets.mean.shape[1:2] + (c,)
        w_all = _side_by_side([w if w is not None else np.zeros(shape) for w in withins], c)
        if t_within is not None:
            u = u + _each_times(w_all, t_within)
        gram = gram + w_all @ np.swapaxes(w_all, 1, 2)
    cross = None
    if fixed is not None and fixed.n_columns:
        f_mean, f_within = fixed.flat()
        cross = n_rep * _each_times(means, f_mean)  # (S, c, f): X_s' F
        if f_within is not None and changing:
            cross = cross + _each_times(w_all, f_within)
    return _explained(u, gram, cross, fixed, targets, max(d.scale for d in designs), _rows(designs[0]))


def explained_by_library(fixed: Design | None, library: Design, indices: list[NDArray[np.intp]], targets: Design) -> NDArray[np.float64]:
    """explained_beyond for designs that are column subsets of one library (indices: each design's
    columns in it, one count for all): the library's products are made once and each design's are
    gathered from them (Effect.scan_library)."""
    index = np.stack(indices)  # (S, c)
    gram = library.gram()[index[:, :, None], index[:, None, :]]
    u = library.dot(targets)[index]
    cross = library.dot(fixed)[index] if fixed is not None and fixed.n_columns else None
    return _explained(u, gram, cross, fixed, targets, library.scale, _rows(library))


def _explained(
    u: NDArray[np.float64],
    gram: NDArray[np.float64],
    cross: NDArray[np.float64] | None,
    fixed: Design | None,
    targets: Design,
    scale: float,
    rows: int,
) -> NDArray[np.float64]:
    """(S, k) from each design's products X'y (S, c, k), X'X (S, c, c) and X'F (S, c, f)."""
    if cross is not None and fixed is not None:
        a_inverse = _pseudo_inverse(fixed.gram(), fixed.scale, rows)
        v = fixed.dot(targets)  # (f, k)
        u = u - cross @ (a_inverse @ v)
        gram = gram - cross @ a_inverse @ np.swapaxes(cross, 1, 2)
        scale = max(scale, fixed.scale)
    values, vectors = np.linalg.eigh(gram)  # (S, c), (S, c, c)
    keep = _kept(values, scale, rows)
    projected = np.swapaxes(vectors, 1, 2) @ u  # (S, c, k)
    inverse = np.where(keep, 1.0 / np.where(keep, values, 1.0), 0.0)
    return np.einsum("sck,sc->sk", projected**2, inverse)


def _without_rings(design: Design, target: Design, rings: NDArray[np.intp]) -> tuple[NDArray, NDArray, NDArray, NDArray]:
    """Every given ring's normal equations without it, at once, eigendecomposed as solve() does:
    (eigenvalues (m, c), eigenvectors (m, c, c), projected X'y (m, c), kept directions (m, c))."""
    gram = design.gram()[None] - design.ring_gram()[rings]
    dot = design.dot(target)[None, :, 0] - design.ring_dot(target)[rings, :, 0]
    values, vectors = np.linalg.eigh(gram)
    return values, vectors, np.einsum("mcj,mc->mj", vectors, dot), _kept(values, design.scale, _rows(design))


def _ridge_coefficients(left_out: tuple[NDArray, NDArray, NDArray, NDArray], ridge: float) -> NDArray[np.float64]:
    """(m, c): the coefficients of _without_rings's equations with the penalty ridge * |coef|^2."""
    values, vectors, projected, keep = left_out
    shrunk = np.where(keep, projected / np.where(keep, values + ridge, 1.0), 0.0)
    return np.einsum("mcj,mj->mc", vectors, shrunk)


def jackknife(design: Design, targets: Design, rings: NDArray[np.int64], ridge: float = 0.0) -> NDArray[np.float64]:
    """(len(rings), c): the coefficients fitted without each of the given rings (first target column)."""
    return _ridge_coefficients(_without_rings(design, targets.first_column(), np.asarray(rings, dtype=np.intp)), ridge)


def ridge_grid(typical: float) -> list[float]:
    """The penalties tried, from none to strong: 1e-6 to 1 times a typical diagonal of X'X."""
    return [0.0] + [typical * 10.0**k for k in range(-6, 1)]


def choose_ridge(design: Design, targets: Design) -> float:
    """The ridge penalty with the least leave-one-ring-out error, from none to strong.

    With few rings, physical terms can alias (two cyclic orders seen at two B values only) and
    plain least squares trades huge opposite coefficients; the rings left out tell how much
    shrinkage predicts best. Each ring's error comes from ring-level sums, never the raw arrays:
    |y_j - X_j b|^2 = y_j'y_j - 2 b'X_j'y_j + b'X_j'X_j b.
    """
    target = targets.first_column()
    gram = design.gram()
    ring_gram, ring_dot = design.ring_gram(), design.ring_dot(target)[:, :, 0]
    ring_total = target.n_rep * (target.mean[..., 0] ** 2).sum(axis=1)
    if target.within is not None:
        ring_total = ring_total + (target.within[..., 0] ** 2).sum(axis=(1, 2))
    used = np.flatnonzero(np.abs(ring_gram).sum(axis=(1, 2)) > 0)
    typical = float(np.trace(gram)) / max(gram.shape[0], 1)
    left_out = _without_rings(design, target, used)  # one eigendecomposition per ring serves every penalty
    best, best_error = 0.0, np.inf
    for ridge in ridge_grid(typical):
        coef = _ridge_coefficients(left_out, ridge)
        fitted = np.einsum("ui,uij,uj->u", coef, ring_gram[used], coef)
        error = float(np.sum(ring_total[used] - 2.0 * np.einsum("ui,ui->u", coef, ring_dot[used]) + fitted))
        if error < best_error * (1.0 - 1e-9):
            best, best_error = ridge, error
    return best


class RingDeletion:
    """Ridge fits of a design with many columns, each ring left out by the hat-matrix identity.

    For columns that are the same in every repetition (no within part), deleting ring j's rows X_j
    from the normal equations (X'X + ridge I) b = X'y changes its residual to (I - H_jj)^-1 e_j,
    H_jj = X_j (X'X + ridge I)^-1 X_j': one eigendecomposition of X'X serves every ring and every
    penalty, where `jackknife` decomposes each ring's own (a shape's hundreds of columns:
    docs/methods/shapes.md). Rows are weighted by the repetitions as everywhere here.
    """

    def __init__(self, design: Design, targets: Design) -> None:
        if design.within is not None:
            raise ValueError("RingDeletion needs columns that are the same in every repetition")
        self.n_rep = design.n_rep
        values, vectors = np.linalg.eigh(design.gram())
        keep = _kept(values, design.scale, _rows(design))
        self.values, self.vectors = values[keep], vectors[:, keep]
        self.z = design.mean @ self.vectors  # (n_o, n_pt, k): each ring's columns in eigen coordinates
        self.y = targets.mean  # (n_o, n_pt, t)
        n_o, n_pt, k = self.z.shape
        self.u = self.n_rep * self.z.reshape(n_o * n_pt, k).T @ self.y.reshape(n_o * n_pt, -1)  # V' X'y (k = 0: nothing the rings can see)
        within = 0.0 if targets.within is None else (targets.within**2).sum(axis=(1, 2))
        self.within_squares = np.broadcast_to(within, (self.z.shape[0], self.y.shape[-1]))  # (n_o, t)
        self._at: dict[float, tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]] = {}

    def at(self, ridge: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """(coefficients (c, t), coefficients without each ring (n_o, c) of the first target,
        each ring's left-out sum of squares over single touches (n_o, t)) at this penalty; each
        penalty's once (best_ridge tries those that are asked for again)."""
        if ridge not in self._at:
            self._at[ridge] = self._solved(ridge)
        return self._at[ridge]

    def _solved(self, ridge: float) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        d = 1.0 / (self.values + ridge)
        b = d[:, None] * self.u  # (k, t)
        e = self.y - self.z @ b  # (n_o, n_pt, t)
        hat = self.n_rep * np.matmul(self.z * d, self.z.transpose(0, 2, 1))  # (n_o, n_pt, n_pt): batched BLAS
        left_out = np.linalg.solve(np.eye(hat.shape[-1])[None] - hat, e)  # (n_o, n_pt, t)
        squares = self.n_rep * (left_out**2).sum(axis=1) + self.within_squares
        without = b[:, 0][None] - self.n_rep * d[None] * np.matmul(self.z.transpose(0, 2, 1), left_out[..., :1])[..., 0]
        return self.vectors @ b, without @ self.vectors.T, squares

    def best_ridge(self, typical: float | None = None) -> float:
        """The penalty of least left-out sum of squares of the first target met walking ridge_grid
        down from its strongest: each weaker penalty tried only while the last one lowered it (the
        smoothest local minimum; a shape's hundreds of columns make each try the costliest step of
        its fit, and most groups stop at the strongest two: docs/methods/shapes.md)."""
        typical = float(self.values.sum()) / max(self.vectors.shape[0], 1) if typical is None else typical
        best, best_error = 0.0, np.inf
        for ridge in reversed(ridge_grid(typical)):
            try:
                error = float(self.at(ridge)[2][:, 0].sum())
            except np.linalg.LinAlgError:  # a ring that alone determines a direction: unpredictable without a penalty
                break
            if error >= best_error * (1.0 - 1e-9):
                break
            best, best_error = ridge, error
        return best
