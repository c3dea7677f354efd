"""The least squares of basis columns through the smoother (ph_explorer.models.least_squares)."""

from __future__ import annotations

import numpy as np
import pytest

from ph_explorer.models import least_squares
from ph_explorer.models.least_squares import Design


@pytest.mark.parametrize("within", [False, True])
def test_every_scanned_design_explains_at_once_what_each_explains_beyond_the_fixed_columns(within):
    """least_squares.explained_beyond is fit(fixed + design) - fit(fixed), for many designs at once."""
    rng = np.random.default_rng(3)
    n_o, n_rep, n_pt = 12, 4, 16

    def columns(c: int, changing: bool) -> np.ndarray:
        base = rng.normal(size=(n_o, 1, n_pt, c))
        return base + rng.normal(size=(n_o, n_rep, n_pt, c)) if changing else np.broadcast_to(base, (n_o, n_rep, n_pt, c))

    targets = Design(rng.normal(size=(n_o, n_rep, n_pt, 5)), None)
    fixed_columns = columns(3, within)
    fixed = Design(fixed_columns, None)
    designs = [Design(columns(2, within and k % 2 == 0), None) for k in range(6)]
    designs.append(Design(fixed_columns[..., :2], None))  # inside fixed's span: explains nothing more
    together = least_squares.explained_beyond(fixed, designs, targets)
    base = least_squares.fit(fixed, targets)[1]
    one_by_one = np.array([least_squares.fit(fixed.stacked(d), targets)[1] - base for d in designs])
    assert np.allclose(together, one_by_one, rtol=1e-8, atol=1e-8 * base.max())
    assert np.allclose(together[-1], 0.0, atol=1e-8 * base.max())
    alone = least_squares.explained_beyond(None, designs[:3], targets)
    assert np.allclose(alone, [least_squares.fit(d, targets)[1] for d in designs[:3]])


@pytest.mark.parametrize("within", [False, True])
@pytest.mark.parametrize("with_fixed", [False, True])
def test_designs_gathered_from_one_library_explain_what_each_design_explains(within, with_fixed):
    """explained_by_library (each column made once, Effect.scan_library) gives explained_beyond's
    figures for the designs that are column subsets of the library."""
    rng = np.random.default_rng(5)
    n_o, n_rep, n_pt = 10, 3, 12
    shape = (n_o, n_rep, n_pt, 7)
    library = rng.normal(size=shape) if within else np.broadcast_to(rng.normal(size=(n_o, 1, n_pt, 7)), shape)
    targets = Design(rng.normal(size=(n_o, n_rep, n_pt, 4)), None)
    fixed = Design(rng.normal(size=(n_o, n_rep, n_pt, 2)), None) if with_fixed else None
    indices = [np.array([0, 1, 4]), np.array([0, 2, 5]), np.array([3, 6, 1])]
    gathered = least_squares.explained_by_library(fixed, Design(library, None), indices, targets)
    each = least_squares.explained_beyond(fixed, [Design(library[..., index], None) for index in indices], targets)
    assert gathered.shape == (3, 4)
    assert np.allclose(gathered, each, rtol=1e-10, atol=1e-12 * np.abs(each).max())


@pytest.mark.parametrize("within", [False, True])
def test_a_designs_gram_is_made_once_and_cannot_be_changed_by_a_caller(within):
    """Design.gram is X'X over single touches (the within part's products added), made once: a fit,
    its ridge and its jackknife share it, so no caller may change it in place."""
    rng = np.random.default_rng(5)
    columns = rng.normal(size=(6, 3, 8, 2)) if within else np.broadcast_to(rng.normal(size=(6, 1, 8, 2)), (6, 3, 8, 2))
    design = Design(columns, None)
    touches = np.asarray(columns).reshape(-1, 2)
    assert np.allclose(design.gram(), touches.T @ touches) and design.gram() is design.gram()
    with pytest.raises(ValueError):
        design.gram()[0, 0] = 0.0
    assert design.stacked(design).gram().shape == (4, 4) and design.first_column().gram().shape == (1, 1)
