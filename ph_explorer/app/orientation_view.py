"""What the explorer draws at one orientation (`OrientationView`), and the key its views are cached
by: a record of the core's figures, no viser (docs/explorer.md)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import orientation_keys
from ph_explorer.harmonics import harmonic_spectrum


def view_key(a_deg: float, b_deg: float) -> tuple[float, float]:
    """Views of the same orientation (campaign.ORIENTATION_TOLERANCE_DEG, B modulo 360) share a key."""
    a, b = orientation_keys([float(a_deg), float(b_deg) % 360.0])
    return float(a), float(b)


@dataclass
class OrientationView:
    """Everything drawn for one orientation: curves (um); its tables and spectra, which only what
    follows the sliders shows, computed when first asked for (a slider move draws the curves)."""

    a_deg: float
    b_deg: float
    measured_index: int | None  # index in the campaign, None when it was not measured
    held_out: bool  # measured but not used to train the models (a check ring)
    curves: dict[str, NDArray[np.float64]]  # "measured" and model names -> (n_pt,) um
    repetitions: NDArray[np.float64] | None  # (n_rep, n_pt) um when measured
    tables_of: Callable[[], dict[str, Any]]  # Tables 1-3 here (paper.tables.tables_at)

    @cached_property
    def tables(self) -> dict[str, Any]:  # range_um, max_abs_um, mae_um like evaluation.orientation_tables rows
        return self.tables_of()

    @cached_property
    def spectra(self) -> dict[str, NDArray[np.float64]]:  # name -> amplitude per UPR (um), UPR 0..N//2
        return dict(zip(self.curves, harmonic_spectrum(np.stack(list(self.curves.values())))[0]))

    @property
    def measured(self) -> bool:
        return self.measured_index is not None
