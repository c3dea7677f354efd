"""A hybrid model: chosen physical effects (fitted on their bases) + a data-driven part.

The physical coefficients are fitted jointly with the data-driven part (Frisch-Waugh-Lovell, see
ph_explorer.models.least_squares): what the out-of-sample smoother cannot predict of the deviations
is fitted on what it cannot predict of the basis columns, over every ring. The data-driven part
(the trilinear model or the network) then learns the deviations minus the physical terms from the
training rings only. The physical fit is linear least squares: a change of effects refits in about
a second on a paper-size campaign.

Method: docs/methods/hybrid.md.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Self

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect
from ph_explorer.effects.error_functions import ErrorFunction
from ph_explorer.errors import InputError
from ph_explorer.geometry import DEFAULT_GEOMETRY, Geometry
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.kinematics import Touches, campaign_touches, touch_kinematics
from ph_explorer.models import least_squares
from ph_explorer.models.crossval import ModelFactory, OutOfSampleSmoother, inner_rows
from ph_explorer.models.deviation_model import DeviationModel, as_orientations, training_mask
from ph_explorer.models.folder import MODEL_TYPES, model_class
from ph_explorer.models.least_squares import Design
from ph_explorer.models.trilinear import TrilinearModel

# A basis column whose part left by the circle fit is below this fraction of its size is absorbed.
ABSORBED_RTOL = 1e-9


def fitted_basis(effect: Effect, touches: Touches) -> tuple[NDArray, list[str]]:
    """An effect's basis columns as they appear in deviations: after each repetition's circle fit.

    Returns (n_o, n_rep, n_pt, n_cols) and the column names. Columns that are the same in every
    repetition (most effects: they depend on the orientation and the point only) come back as a
    read-only view broadcast over the repetitions: the circle fit is made once per ring.
    """
    columns, names = effect.basis(touches)
    return fitted_columns(columns, touches), list(names)


def fitted_columns(columns: NDArray[np.float64], touches: Touches, overwrite: bool = False) -> NDArray[np.float64]:
    """Basis columns (n_o, n_rep, n_pt, n_cols) after each repetition's circle fit (fitted_basis);
    overwrite: the caller gives the columns up, and a writable float64 array is fitted in place."""
    given = columns
    columns = np.asarray(columns, dtype=float)
    # A view broadcast over the repetitions (full_shape) is the same in every one by construction;
    # columns that change with time (drift) differ already between the first two.
    if columns.shape[1] != 1 and (
        columns.strides[1] == 0
        or (np.array_equal(columns[:, 1], columns[:, 0]) and np.array_equal(columns, np.broadcast_to(columns[:, :1], columns.shape)))
    ):
        columns = columns[:, :1]
    # A column the fit removes entirely (harmonics 0 and 1 at every ring: a stylus's sag, a
    # constant offset) leaves rounding noise ~1e-16 of its size; a least squares would fit that
    # noise with absurd coefficients. It is zero in the deviations: make it exactly zero.
    before = np.sqrt(np.einsum("orpc,orpc->c", columns, columns))
    in_place = overwrite and columns is given and columns.flags.writeable
    fitted = remove_size_and_centre(columns, axis=-2, in_place=in_place)  # the circle fit acts along the points
    after = np.sqrt(np.einsum("orpc,orpc->c", fitted, fitted))
    absorbed = after <= ABSORBED_RTOL * before
    fitted[..., absorbed] = 0.0  # in place: a new array, or the columns given up
    shape = touches.shape + fitted.shape[3:]
    return fitted if fitted.shape == shape else np.broadcast_to(fitted, shape)  # a new array, or a view of one


SUBFOLDER = "hybrid"
DataPart = str | DeviationModel | Callable[[], DeviationModel]


class HybridModel(DeviationModel):
    """Physical effects fitted on their bases + a data-driven part for what remains."""

    name = "hybrid"

    def __init__(
        self,
        effects: Sequence[Effect] = (),
        data_part: DataPart = "trilinear",
        progress: Callable[[str, float], None] | None = None,
    ) -> None:
        self.effects = list(effects)  # each at its own settings (e.g. cycles per revolution)
        self.data_part: DeviationModel = make_data_part(data_part)
        self.coefficients_: NDArray[np.float64] = np.zeros(0)
        self.geometry: Geometry = DEFAULT_GEOMETRY
        self.progress = progress
        # What fit leaves for the held-out evaluation (predict_held_out); None after load.
        self.smoother_: OutOfSampleSmoother | None = None
        self.fit_design_: Design | None = None
        self.fit_targets_: Design | None = None
        self.ridge_ = 0.0  # penalty chosen by leave-one-ring-out (least_squares.choose_ridge)
        self.widths_: list[int | None] = [None] * len(self.effects)  # basis columns per effect, set by fit
        self.n_points = 64

    # -- physical part ---------------------------------------------------------------------------
    def physical_basis(self, touches: Touches) -> NDArray[np.float64]:
        """All effects' fitted basis columns side by side, (n_o, n_rep, n_pt, n_cols).

        At touches that lack what an effect needs (no touch times at an orientation nobody
        measured) a fitted effect contributes nothing: when it will be measured is unknown.
        """
        blocks = []
        for index, effect in enumerate(self.effects):
            unmet = effect.unmet_needs(touches)
            if unmet:
                if self.widths_[index] is None:
                    raise InputError(f"effect {effect.id!r} {'; '.join(unmet)}")
                blocks.append(np.zeros(touches.shape + (self.widths_[index],)))
                continue
            cols, _ = fitted_basis(effect, touches)
            self.widths_[index] = cols.shape[-1]
            blocks.append(cols)
        if not blocks:
            return np.zeros(touches.shape + (0,))
        return np.concatenate(blocks, axis=-1)

    def physical_part(self, touches: Touches) -> NDArray[np.float64]:
        """The physical terms' deviations at every touch, (n_o, n_rep, n_pt) um."""
        if not self.effects:
            return np.zeros(touches.shape)
        return self.physical_basis(touches) @ self.coefficients_

    def coefficient_blocks(self) -> list[slice]:
        """Each effect's columns in coefficients_ (widths_ side by side)."""
        ends = np.cumsum(self.widths_).tolist()
        return [slice(end - width, end) for end, width in zip(ends, self.widths_)]

    def effect_parameters(self) -> list[dict[str, Any]]:
        """Each effect's fitted physical parameters (units of its Parameter list)."""
        return [
            {"effect": effect.id, "params": effect.from_coefficients(self.coefficients_[block])}
            for effect, block in zip(self.effects, self.coefficient_blocks())
        ]

    # -- DeviationModel --------------------------------------------------------------------------
    def fit(self, campaign: Campaign, train: ArrayLike | None = None) -> Self:
        mask = training_mask(campaign, train)
        self.geometry = campaign.geometry
        self.n_points = campaign.n_points
        touches = campaign_touches(campaign)
        linear = smoother_type(self.data_part, campaign, mask)
        self.smoother_ = OutOfSampleSmoother(campaign.orientations, mask, linear)
        self.fit_targets_ = Design(self.smoother_.residual(campaign.deviations)[..., None], None)
        if self.effects:
            self._report("physical terms", 0.0)
            basis = self.physical_basis(touches)
            self.fit_design_ = Design(basis, self.smoother_)
            if self._rows_needed(mask):
                # Each inner A row's rings also predicted without their row, where they show such terms.
                rows = OutOfSampleSmoother(campaign.orientations, mask, linear, leave_out="row")
                inner = np.zeros(campaign.n_orientations, dtype=bool)
                for row in inner_rows(campaign.orientations, mask):
                    inner[row] = True
                self.fit_design_ = self.fit_design_.beside(Design(basis, rows), inner)
                self.fit_targets_ = self.fit_targets_.beside(Design(rows.residual(campaign.deviations)[..., None], None), inner)
            del basis
            self.ridge_ = least_squares.choose_ridge(self.fit_design_, self.fit_targets_)
            self.coefficients_ = least_squares.fit(self.fit_design_, self.fit_targets_, self.ridge_)[0][:, 0]
            remainder = campaign.deviations - self.physical_part(touches)
        else:
            self.fit_design_ = None
            self.coefficients_ = np.zeros(0)
            remainder = campaign.deviations
        self._report("data-driven part", 0.3)
        residual_campaign = Campaign(campaign.orientations, remainder, campaign.times_s, campaign.geometry, campaign.check_orientations)
        self.data_part.fit(residual_campaign, mask)
        self._report("done", 1.0)
        return self

    def _rows_needed(self, train: NDArray[np.bool_]) -> bool:
        """An effect that the data part's neighbours in an A row carry at most training rings
        (least_squares.UNSEEN_SHARE), and that fewer rings show than it has columns (a shape's
        knots): the rings by themselves leave it undetermined (docs/methods/shapes.md)."""
        for block in self.coefficient_blocks():
            seen = self.fit_design_.seen_rings(block)  # once a block: the energy of its columns at every ring
            if least_squares.unseen_at_most(seen, train) and seen.sum() < block.stop - block.start:
                return True
        return False

    def predict_held_out(self, campaign: Campaign, rings: NDArray[np.int64]) -> NDArray[np.float64]:
        """Predictions (m, n_rep, n_pt) of the given rings with each ring left out of the physical fit.

        The data-driven part is the one fitted (on the training rings); its dependence on the
        physical coefficients is corrected through the smoother, exact for the trilinear part.
        """
        touches = campaign_touches(campaign.subset(rings))
        data = self.data_part.predict(touches.orientations, n_points=touches.shape[2])[:, None, :]
        fitted_here = self.smoother_ is not None and self.smoother_.weights.shape[0] == campaign.n_orientations
        if not fitted_here:
            raise ValueError("predict_held_out needs the hybrid fitted on this campaign (fit, not load)")
        if not self.effects:
            return np.broadcast_to(data, touches.shape).copy()
        coef = least_squares.jackknife(self.fit_design_, self.fit_targets_, rings, self.ridge_)  # (m, c)
        basis = self.physical_basis(touches)  # (m, n_rep, n_pt, c)
        own = np.einsum("orpc,oc->orp", basis, coef)
        full = self.physical_basis(campaign_touches(campaign)).mean(axis=1)
        predicted_basis = self.smoother_.predict(full)[rings]  # (m, n_pt, c)
        correction = np.einsum("opc,oc->op", predicted_basis, self.coefficients_[None, :] - coef)
        return own + data + correction[:, None, :]

    def _report(self, stage: str, fraction: float) -> None:
        if self.progress is not None:
            self.progress(stage, fraction)

    def predict_touches(self, touches: Touches) -> NDArray[np.float64]:
        data = self.data_part.predict(touches.orientations, n_points=touches.shape[2])
        return self.physical_part(touches) + data[:, None, :]

    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        """The systematic curve in the default scan order (points 0..N-1, no drift in time)."""
        o = as_orientations(orientations)
        n = self.n_points if n_points is None else int(n_points)
        geometry = Geometry(self.geometry.pivot_to_ball_mm, self.geometry.ball_diameter_mm, self.geometry.bore_diameter_mm, n)
        return self.predict_touches(touch_kinematics(o, geometry))[:, 0, :]

    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        return self.data_part.repetition_sigma(orientations, n_points)

    # -- files -----------------------------------------------------------------------------------
    def save(self, directory: str | Path) -> Path:
        # Its own subfolder, so that a hybrid saved beside trained models never overwrites their files.
        directory = Path(directory) / SUBFOLDER
        directory.mkdir(parents=True, exist_ok=True)
        self.data_part.save(directory)
        path = directory / "hybrid.json"
        record = {
            "data_part": self.data_part.name,
            "geometry": self.geometry.as_dict(),
            "effects": [
                {"id": e.id, "settings": e.settings(), "params": p["params"]} for e, p in zip(self.effects, self.effect_parameters())
            ],
            "coefficients": self.coefficients_.tolist(),
            "widths": self.widths_,
            "ridge": self.ridge_,
        }
        path.write_text(json.dumps(record, indent=2))
        return path

    @classmethod
    def load(cls, directory: str | Path, catalog: Catalog = DEFAULT_CATALOG) -> Self:
        """Read a hybrid written by save; its effects come from `catalog` (with the user's file, if any)."""
        directory = Path(directory) / SUBFOLDER
        record = json.loads((directory / "hybrid.json").read_text())
        unknown = [e["id"] for e in record["effects"] if e["id"] not in catalog]
        if unknown:
            raise InputError(f"effect {unknown[0]!r} is not in the catalog (give its --effects file)", file=str(directory))
        effects = [catalog[e["id"]](**e["settings"]) for e in record["effects"]]
        model = cls(effects, record.get("data_part", record.get("data_model")))  # "data_model": a folder saved before 2026-11-29
        model.data_part = type(model.data_part).load(directory)
        model.geometry = Geometry(**record["geometry"])
        model.n_points = model.geometry.points_per_circle
        model.coefficients_ = np.asarray(record["coefficients"], dtype=float)
        model.widths_ = list(record["widths"])
        # A shape's coefficients come from its saved knot values: a folder written before the
        # P-spline coordinates (2026-12-01) stored the values themselves as its coefficients.
        for effect, saved, block in zip(effects, record["effects"], model.coefficient_blocks()):
            if isinstance(effect, ErrorFunction):
                model.coefficients_[block] = type(effect)(**saved["params"]).coefficients()
        model.ridge_ = float(record["ridge"])
        return model


def smoother_type(data_part: DeviationModel, campaign: Campaign, train: NDArray[np.bool_]) -> ModelFactory:
    """The linear model whose out-of-sample weights stand for the data part in the physical fit: the
    data part itself when it is linear in its data (trilinear, mean curve), or its linear smoother
    when it has one (a Gaussian process with its kernel fixed, learnt now on the campaign), else the
    trilinear model (for the network, its nearest linear stand-in)."""
    if isinstance(data_part, TrilinearModel):
        return type(data_part)
    linear = getattr(data_part, "linear_smoother", None)
    return linear(campaign, train) if linear is not None else TrilinearModel


def make_data_part(data_part: DataPart) -> DeviationModel:
    """The data-driven part: a model, a factory of one (e.g. a network with a progress bar), or its name."""
    if isinstance(data_part, DeviationModel):
        return data_part
    if callable(data_part):
        return data_part()
    if data_part not in MODEL_TYPES:
        raise ValueError(f"unknown data-driven model {data_part!r} ({' or '.join(MODEL_TYPES)})")
    return model_class(data_part)()
