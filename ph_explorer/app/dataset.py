"""What one explorer session looks at: a campaign, the models fitted to it, and what follows from them.

Only calls the core; holds no physics. Views and figures are computed on demand and cached. Once
prepared (`prepare`, on the background thread), a view reads each model's curve from its
PredictionLattice (models.lattice): a slider move never calls a model. See docs/explorer.md.
"""

from __future__ import annotations

import atexit
import tempfile
import threading
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ph_explorer import paths, twin
from ph_explorer.app.background import LatestFirst
from ph_explorer.app.orientation_view import OrientationView, view_key
from ph_explorer.campaign import Campaign
from ph_explorer.errors import InputError
from ph_explorer.figures.orientation_map import MapFigure, ranked_rings
from ph_explorer.figures.polar import campaign_bounds
from ph_explorer.geometry import A_LIMIT_DEG
from ph_explorer.harmonics import ron_t
from ph_explorer.io import read_campaign
from ph_explorer.io.sidecar import sidecar_path
from ph_explorer.metrics import ring_mae
from ph_explorer.models.crossval import OutOfSampleSmoother, cross_val_predict, held_out_ring_mae
from ph_explorer.models.deviation_model import DeviationModel
from ph_explorer.models.folder import campaign_models
from ph_explorer.models.lattice import BuildStopped, PredictionLattice, build_cpu_s
from ph_explorer.models.lattice_need import read_lattice_campaign, require_lattice
from ph_explorer.models.off_the_shelf import PEER_MODELS
from ph_explorer.models.trilinear import TrilinearModel
from ph_explorer.paper.tables import tables_at
from ph_explorer.uncertainty.bands import Sources, calibrated_model_error, gaussian_band
from ph_explorer.uncertainty.model_error import FILE_NAME as ERRORS_FILE, FOLDS, OutOfSampleError, has_posterior, load_errors
from ph_explorer.uncertainty.task import COVERAGE_FACTOR, measured_task, task_uncertainty

MODEL_ORDER = ("network", "trilinear", "gp", "hybrid")
# The map's own figures (a model's are named after it); the first is where the map starts.
LOO_FIGURE = "trilinear MAE, leave-one-out"
LOO_RATIO_FIGURE = "trilinear MAE / noise floor, leave-one-out"
RONT_FIGURE = "measured RONt"
VIEW_CACHE = 512  # orientations whose views a dataset keeps (a slider sweep revisits them)


@dataclass
class Dataset:
    """A campaign and its models; every derived figure is computed by the core and cached here."""

    campaign: Campaign
    models: dict[str, DeviationModel]
    label: str
    notes: list[str] = field(default_factory=list)
    train_mask: NDArray[np.bool_] | None = None
    # Each model's out-of-sample error (the model folder's uncertainty.npz); the trilinear model's is
    # estimated on first use when the folder has none. A model without one has no model component.
    errors: dict[str, OutOfSampleError] = field(default_factory=dict)
    # Each model's curves on a dense (A, B) lattice (`prepare`); a model without one is predicted.
    lattices: dict[str, PredictionLattice] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.train_mask is None:
            self.train_mask = ~self.campaign.holdout_mask()
        # One array for every browser showing this dataset: the map's SVG cache is keyed by it.
        self.held_out_mask = ~np.asarray(self.train_mask, dtype=bool)
        self._views: OrderedDict[tuple, OrientationView] = OrderedDict()
        self._tasks: OrderedDict[tuple, dict[str, float]] = OrderedDict()
        self._figures: dict[str, MapFigure] = {}
        self._measured_views: dict[tuple, OrientationView] = {}  # every measured ring's view, once prepared
        self._prepare_asked = False
        self.prepared = threading.Event()  # set once `prepare` ended (tests and benchmarks wait for it)
        self._extra_figures: list[str] = []
        self._lock = threading.Lock()
        self.mean_curves = self.campaign.mean_curves()
        # What every polar chart of the campaign keeps off its centre (a ring's own touches join it).
        self.campaign_bounds_um = np.array(campaign_bounds(self.campaign.deviations))
        self.sigma_um = self.campaign.noise_sigma_um()
        # A campaign of single repetitions has no repetition spread: no floor to show.
        finite = np.isfinite(self.sigma_um)
        self.noise_floor_um: dict[str, float] = self.campaign.noise_floor_um() if finite else {}
        # The models in their tables' order, once (a dataset's models are replaced with the dataset, never changed).
        self._ordered_models = {n: self.models[n] for n in self.model_names}

    @property
    def a_range(self) -> tuple[float, float]:
        """The A slider's range: 0 to the head's reach, from minus the reach when the campaign has negative A."""
        low = -A_LIMIT_DEG if float(self.campaign.orientations[:, 0].min(initial=0.0)) < 0.0 else 0.0
        return low, A_LIMIT_DEG

    # -- models ----------------------------------------------------------------------------------
    @property
    def model_names(self) -> list[str]:
        return [n for n in MODEL_ORDER if n in self.models] + [n for n in self.models if n not in MODEL_ORDER]

    def with_model(self, name: str, model: DeviationModel) -> Dataset:
        """A copy holding one more (or a replaced) model; the views are recomputed."""
        return self._with_models({**self.models, name: model})

    def without_model(self, name: str) -> Dataset:
        """A copy without the named model (the same dataset when it has none)."""
        if name not in self.models:
            return self
        return self._with_models({k: v for k, v in self.models.items() if k != name})

    def with_figures(self, figures: Mapping[str, MapFigure]) -> Dataset:
        """A copy holding more per-ring figures (a diagnosis's): one browser's, never shared with the others."""
        copy = self._with_models(dict(self.models))
        for name, figure in figures.items():
            copy.add_figure(name, figure)
        return copy

    def _with_models(self, models: dict[str, DeviationModel]) -> Dataset:
        # A replaced model's error was of the old model: kept only for the same object.
        errors = {n: e for n, e in self.errors.items() if n in models and models[n] is self.models.get(n)}
        lattices = {n: g for n, g in self.lattices.items() if n in models and models[n] is self.models.get(n)}
        copy = Dataset(self.campaign, models, self.label, list(self.notes), self.train_mask, errors, lattices)
        with self._lock:
            for extra in self._extra_figures:  # figures of the campaign, not of the models: still true
                copy.add_figure(extra, self._figures[extra])
        return copy

    # -- one orientation ---------------------------------------------------------------------------
    def view(self, a_deg: float, b_deg: float) -> OrientationView:
        key = view_key(a_deg, b_deg)
        with self._lock:
            hit = self._views.get(key)
            if hit is not None:
                self._views.move_to_end(key)
                return hit
            hit = self._measured_views.get(key)
            if hit is not None:
                return hit
            known = bool(self._measured_views)  # prepared: an orientation not among them was not measured
        view = self._compute_view(float(a_deg), float(b_deg), unmeasured=known)
        with self._lock:
            self._views[key] = view
            while len(self._views) > VIEW_CACHE:
                self._views.popitem(last=False)
        return view

    def _compute_view(self, a: float, b: float, unmeasured: bool = False) -> OrientationView:
        c = self.campaign
        idx = None if unmeasured else c.index_of(a, b)
        curves: dict[str, NDArray[np.float64]] = {}
        reps = None
        if idx is not None:
            curves["measured"] = self.mean_curves[idx]
            reps = c.deviations[idx]
        for name in self._ordered_models:
            lattice = self.lattices.get(name)
            if idx is None and lattice is not None and lattice.covers(a):
                curves[name] = lattice.curve(a, b)  # within the lattice's tolerance of the model
            else:  # a measured ring (its tables compare the model's own prediction) or no lattice here
                curves[name] = np.asarray(self.models[name].predict([[a, b]], n_points=c.n_points))[0]
        held_out = idx is not None and not bool(self.train_mask[idx])
        # Tables 1-3 of the paper here, when first shown: of the campaign and models, not of the
        # dataset, which caches the view (no cycle keeps a replaced dataset's lattices alive).
        return OrientationView(a, b, idx, held_out, curves, reps, partial(tables_at, c, self._ordered_models, idx, curves))

    def prepare(self) -> None:
        """Build the missing models' lattices and every measured ring's view (a few seconds, once):
        afterwards no slider move predicts. A model whose lattice would take more than
        LATTICE_BUDGET_S of CPU (a hybrid's physics, ~13 s) keeps being predicted on demand.
        Returns early (unprepared) once the process is stopping."""
        stopping = _PREPARER.should_stop  # between pieces: waits while a clicked job runs, alone
        try:
            for name in [n for n in self.model_names if n not in self.lattices]:
                if not stopping() and build_cpu_s(self.models[name], self.campaign.n_points, self.a_range) <= LATTICE_BUDGET_S:
                    lattice = PredictionLattice.build(self.models[name], self.campaign.n_points, self.a_range, stop=stopping)
                    with self._lock:
                        self.lattices.setdefault(name, lattice)
            views = {}
            for a, b in self.campaign.orientations:  # a ring at a time: each may predict a model
                if stopping():
                    return
                views[view_key(a, b)] = view = self._compute_view(float(a), float(b))
                view.tables  # noqa: B018 (computed here, as its curves: a measured ring's tables predict its models)
            with self._lock:
                self._measured_views = views
        except BuildStopped:
            return
        finally:
            self.prepared.set()

    def drop_lattices(self) -> None:
        """Forget the lattices and the unmeasured views drawn from them: every later slider move
        predicts its models on demand (the design before the lattice cache, which the scale
        benchmark measures beside it)."""
        with self._lock:
            self.lattices.clear()
            self._views.clear()

    def prepare_in_background(self) -> None:
        """`prepare` on the app's one background thread, once per dataset; views are computed on demand meanwhile."""
        with self._lock:
            if self._prepare_asked:
                return
            self._prepare_asked = True
        _PREPARER.add(self)

    def model_error(self, model: str) -> OutOfSampleError | None:
        """The model's own error: from its folder, or (trilinear) by the cross-validation of the
        training rings, (a GP) from its posterior, calibrated on the held-out ones, made on first use; else None."""
        with self._lock:
            if model in self.errors:
                return self.errors[model]
        own = self.models[model]
        if not (model == "trilinear" or has_posterior(own)) or int(self.train_mask.sum()) < 2 * FOLDS:
            return None
        error = calibrated_model_error(type(own), own, self.campaign, self.train_mask)
        with self._lock:
            return self.errors.setdefault(model, error)

    def band(
        self, model: str, a_deg: float, b_deg: float, with_model_error: bool = True, kind: str = "touch", level: float = 0.95
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The model's band (lower, upper) in um of one touch (kind "touch") or of the mean of the
        campaign's repetitions ("mean"): repeatability and, when asked and known, the model's own
        error (bands.gaussian_band: the Monte Carlo's bounds without its trials)."""
        error = self.model_error(model) if with_model_error else None
        sources = Sources(self.models[model], self.campaign.n_repetitions, error)
        return gaussian_band(sources, (a_deg, b_deg), level, n_points=self.campaign.n_points, band=kind)

    def task(self, model: str, a_deg: float, b_deg: float) -> dict[str, float]:
        """RONt of one measurement of N touches at (A, B) by the model's Monte Carlo (task.task_uncertainty,
        every component of its band, a fixed seed so an orientation always shows the same figure):
        value, U (k = 2) and the 95 % interval, um; cached (a second or so per model)."""
        key = (model, *view_key(a_deg, b_deg))
        with self._lock:
            if key in self._tasks:
                return self._tasks[key]
        sources = Sources(self.models[model], self.campaign.n_repetitions, self.model_error(model))
        ront = task_uncertainty(sources, (a_deg, b_deg), self.campaign.n_points, rng=np.random.default_rng(0), ndig=1)["ront_um"]
        with self._lock:
            self._tasks[key] = ront
            while len(self._tasks) > VIEW_CACHE:
                self._tasks.popitem(last=False)
        return ront

    def cached_task(self, model: str, a_deg: float, b_deg: float) -> dict[str, float] | None:
        """The task's RONt if `task` computed it already, else None (the render thread never waits)."""
        with self._lock:
            return self._tasks.get((model, *view_key(a_deg, b_deg)))

    def measured_task(self, index: int) -> dict[str, float]:
        """The measured RONt of one measurement at a measured ring: the mean over its repetitions and
        U = 2 s (k = 2, s their spread: what one more measurement would scatter by)."""
        single = measured_task(self.campaign.deviations[index : index + 1])["single"][0, :, 0]
        spread = float(np.std(single, ddof=1)) if single.size > 1 else float("nan")
        return {"value": float(np.mean(single)), "U": COVERAGE_FACTOR * spread}

    # -- over all orientations (the error map and field) -----------------------------------------
    def figure_names(self) -> list[str]:
        """What the map can show: measured roundness, each model's out-of-sample error and its ratio
        to the floor, then what a diagnosis added (its per-ring figures and verdict)."""
        names = [LOO_FIGURE, LOO_RATIO_FIGURE, RONT_FIGURE]
        for m in self.model_names:
            if m != "trilinear":
                names += [f"{m} MAE, check rings", f"{m} MAE / noise floor, check rings"]
        if self.held_out_mask.any() and (~self.held_out_mask).sum() >= 2:  # off-the-shelf peers, fitted when shown
            names += [f"{p} MAE / noise floor, check rings" for p in PEER_MODELS]
        return names + list(self._extra_figures)

    def add_figure(self, name: str, figure: MapFigure) -> None:
        """A per-orientation figure computed elsewhere in the core (e.g. by the diagnosis)."""
        with self._lock:
            self._figures[name] = figure
            if name not in self._extra_figures:
                self._extra_figures.append(name)

    def has_figure(self, name: str) -> bool:
        with self._lock:
            return name in self._figures

    def figure(self, name: str) -> MapFigure:
        """A named figure: a value per ring (n_o,) with its unit and a note on what it is."""
        with self._lock:
            hit = self._figures.get(name)
        if hit is not None:
            return hit
        result = self._compute_figure(name)
        with self._lock:
            self._figures[name] = result
        return result

    def _compute_figure(self, name: str) -> MapFigure:
        c = self.campaign
        if name == RONT_FIGURE:
            return MapFigure(
                ron_t(self.mean_curves),
                "um",
                "peak to valley of the measured mean curve (ISO 12181): the ring's roundness, not a model's error",
            )
        ratio = "/ noise floor" in name
        if name in (LOO_FIGURE, LOO_RATIO_FIGURE):
            # Out of sample everywhere: each training ring by tables refitted without it, each check
            # ring by the training rings; each ring's floor holds the noise of the rings predicting it.
            mae = ring_mae(cross_val_predict(TrilinearModel, c, self.train_mask), c.deviations)["mean"]
            floor = OutOfSampleSmoother(c.orientations, self.train_mask).noise_floor(self.sigma_um, c.n_repetitions)["mean"]
            note = "out of sample at every ring: each training ring by tables refitted without it, each check ring by the training rings"
        else:
            model, held_out = name.split(" ")[0], self.held_out_mask
            peer = PEER_MODELS[model]().fit(c, ~held_out) if model in PEER_MODELS and model not in self.models else None
            if model not in self.models and peer is None:
                raise KeyError(name)
            # Only the check rings are out of sample for a model fitted on the others (its training rings are not shown).
            mae = np.full(c.n_orientations, np.nan)
            mae[held_out] = held_out_ring_mae(peer or self.models[model], c, held_out)["mean"]
            floor = self.noise_floor_um.get("mean", np.nan)
            kind = "peer (off the shelf: docs/methods/off_the_shelf.md)" if peer else "model"
            note = f"out of sample on the check rings only; the {model} {kind} saw the training rings (hollow)"
        if ratio:
            if not np.all(np.isfinite(floor)):
                return MapFigure(np.full(c.n_orientations, np.nan), "x floor", "noise floor unknown (a single repetition)")
            return MapFigure(mae / floor, "x floor", "MAE against the repetition mean over its noise floor; " + note)
        return MapFigure(mae, "um", "MAE against the repetition mean; " + note)

    def worst_orientations(self, name: str, count: int = 5) -> list[tuple[float, float, float]]:
        """The rings with the largest values of a figure, (A, B, value), largest first."""
        return ranked_rings(self.figure(name), self.campaign.orientations)[:count]


LATTICE_BUDGET_S = 5.0  # CPU seconds a model's lattice may take to build (a network's: ~2 s)
# Datasets are prepared one at a time beside the renders, the latest first; one nobody holds is skipped.
_PREPARER = LatestFirst(Dataset.prepare, name="ph-explorer-prepare")
# Before the interpreter finalises (atexit runs first): a preparation still predicting a network
# would be inside torch while torch's threads are destroyed, and the process would abort.
STOP_WAIT_S = 10.0
atexit.register(_PREPARER.stop, STOP_WAIT_S)


# -- loading -----------------------------------------------------------------------------------------


def dataset_for(campaign: Campaign, label: str, model_dir: Path | None, notes: list[str] | None = None) -> Dataset:
    """A Dataset for a campaign: the models of model_dir when given (held out: the card's rings, which
    they never saw), else the trilinear tables fitted now (held out: the campaign's check rings)."""
    models, train, found = campaign_models(campaign, model_dir)
    notes = [*(notes or []), *found]
    errors: dict[str, OutOfSampleError] = {}
    if model_dir is not None and (Path(model_dir) / ERRORS_FILE).is_file():
        errors = {name: error for name, error in load_errors(Path(model_dir), models)[0].items() if name in models}
    return Dataset(campaign, models, label, notes, train, errors)


def read_uploaded_campaign(
    name: str, content: bytes, geometry: Mapping[str, float] | None = None, sidecar: tuple[str, bytes] | None = None
) -> Campaign:
    """Read an uploaded CSV with the core's reader, and its uploaded sidecar TOML (name, content) when
    given, read as the command line reads NAME.toml beside NAME.csv; an InputError names the
    uploaded files, not temporary paths."""
    safe = Path(name or "upload.csv").name or "upload.csv"
    with tempfile.TemporaryDirectory(prefix="ph-explorer-upload-") as tmp:
        path = Path(tmp) / "upload.csv"  # its own name: an upload named *.toml would be its own sidecar
        path.write_bytes(content)
        shown = {str(path): safe}
        if sidecar is not None:
            sidecar_path(path).write_bytes(sidecar[1])
            shown[str(sidecar_path(path))] = Path(sidecar[0] or "sidecar.toml").name or "sidecar.toml"
        try:
            campaign = read_campaign(path, dict(geometry or {}))
        except InputError as error:
            file = None if error.file is None else shown.get(str(error.file), Path(str(error.file)).name)
            raise InputError(error.message, file=file, row=error.row, column=error.column) from None
    campaign.source = safe
    require_lattice(campaign)  # the models are fitted next: a design without a lattice is said here, in one line
    return campaign


def simulated_scenario(name: str) -> Campaign:
    """A shipped scenario's campaign, simulated by the twin with the scenario's own seed."""
    scenario = twin.load_scenario(name)
    return twin.simulate(scenario, scenario.seed)


def shipped_scenarios() -> dict[str, twin.Scenario]:
    """The shipped scenarios by name (their purpose for the list, their description once loaded)."""
    return {s.name: s for s in twin.list_scenarios()}


def default_dataset(
    scenario: str | None = None,
    data: Path | None = None,
    model: Path | None = None,
    geometry: Mapping[str, float] | None = None,
) -> Dataset:
    """The session's starting data: --data, --scenario, or the shipped paper campaign with assets/models/paper."""
    geometry, model_dir = dict(geometry or {}), (Path(model) if model is not None else None)
    if model_dir is not None and not model_dir.is_dir():
        raise InputError("no such model folder", file=str(model_dir))
    if data is not None:
        return dataset_for(read_lattice_campaign(data, geometry), f"campaign {Path(data).name}", model_dir)
    if scenario is not None:
        return dataset_for(simulated_scenario(scenario), f"scenario {scenario} (simulated by the twin)", model_dir)
    paper_csv = paths.assets_dir() / "data" / "paper.csv"
    return dataset_for(read_campaign(paper_csv, geometry), "the shipped paper campaign", model_dir or paths.default_model_dir())
