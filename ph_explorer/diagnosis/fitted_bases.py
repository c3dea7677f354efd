"""Effects' fitted basis columns over one campaign's touches, each made once and shared by the
searches on subsets of its rings (the nested folds'), and the scan libraries of effects whose
settings share columns (Effect.scan_library).

Method: docs/diagnosis.md.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ph_explorer.effects import Effect
from ph_explorer.kinematics import Touches
from ph_explorer.models.hybrid import fitted_basis, fitted_columns

# The columns that change between repetitions a shared FittedBases keeps (the nested folds'):
# head_3's drift scan is 36 settings x 5.5 MB; a dense campaign's would not fit, and is made again.
WITHIN_BUDGET_BYTES = 256 * 2**20


def settings_key(effect: Effect) -> tuple[str, tuple]:
    """An effect at its settings, as a dictionary key (the same columns for the same key)."""
    return effect.id, tuple(sorted(effect.settings().items()))


class FittedBases:
    """Effects' fitted basis columns (fitted_basis) over one campaign's touches, each made once.

    The nested folds' scans run on the campaign without some rings: their columns are the
    whole campaign's, sliced (`subset`). That is also the touches as they were measured: the
    approach of a fold's first touch at a ring comes from the touch before it in the campaign.
    Columns that change between repetitions (drift) are n_rep times larger: kept while they fit in
    WITHIN_BUDGET_BYTES (every fold asks for each again), made again when asked beyond it.
    """

    def __init__(self, touches: Touches, keep: bool = True) -> None:
        self.touches = touches
        # keep: False for a search of its own, whose designs are kept instead (CandidateSearch).
        self.keep = keep
        self._columns: dict[tuple[str, tuple], NDArray[np.float64]] = {}
        self._libraries: dict[tuple[str, tuple], tuple[NDArray[np.float64], list[NDArray[np.intp]]]] = {}
        self._rings: NDArray[np.intp] | None = None
        self._within_bytes = [0]  # shared with the subsets: one budget for the whole campaign

    def subset(self, rings: NDArray[np.intp]) -> FittedBases:
        """The same columns at some rings only (indices into the campaign's orientations)."""
        out = object.__new__(FittedBases)
        out.touches, out.keep, out._columns, out._rings = self.touches, self.keep, self._columns, np.asarray(rings)
        out._libraries = self._libraries
        out._within_bytes = self._within_bytes
        return out

    def _reserve(self, nbytes: int) -> bool:
        """Whether an array that changes between repetitions may be kept: then counted in the budget."""
        if not (self.keep and self._within_bytes[0] + nbytes <= WITHIN_BUDGET_BYTES):
            return False
        self._within_bytes[0] += nbytes
        return True

    def __call__(self, effect: Effect) -> NDArray[np.float64]:
        key = settings_key(effect)
        columns = self._columns.get(key)
        if columns is None:
            columns = fitted_basis(effect, self.touches)[0]
            if columns.strides[1] == 0:  # the same in every repetition: kept once, (n_o, 1, n_pt, c)
                columns = columns[:, :1]
                if self.keep:
                    self._columns[key] = columns
            elif self._reserve(columns.nbytes):
                self._columns[key] = columns
        if self._rings is not None:
            columns = columns[self._rings]
        # Broadcast over the repetitions again (a view: Design sees that it has no within part).
        return np.broadcast_to(columns, columns.shape[:1] + self.touches.shape[1:2] + columns.shape[2:])

    def library(self, effect: Effect) -> tuple[NDArray[np.float64], list[NDArray[np.intp]]] | None:
        """The effect's scan library (Effect.scan_library) fitted as __call__ fits columns, at
        these rings; kept within the same budget as the columns (every fold scans it again; a dense
        campaign's drift library is hundreds of MB and is made again). None: it has none."""
        key = settings_key(effect)
        library = self._libraries.get(key)
        if library is None:
            made = effect.scan_library(self.touches)
            if made is None:
                return None
            library = fitted_columns(made[0], self.touches, overwrite=True), made[1]  # made for it: fitted in place
            if self._reserve(library[0].nbytes):
                library[0].flags.writeable = False  # a search makes its design from a copy (a fold's rings), never this
                self._libraries[key] = library
        columns, indices = library
        return (columns if self._rings is None else columns[self._rings]), indices
