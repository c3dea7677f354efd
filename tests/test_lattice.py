"""The lattice cache of a model's curves (ph_explorer.models.lattice) and the explorer's use of it.

The lattice must give the model's own curves within TOLERANCE_UM wherever it says it covers, say
it does not where the model is not smooth enough, and once a dataset is prepared a slider move
must not call any model (no torch on the render path).
"""

from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

from ph_explorer.app.background import FOREGROUND, LatestFirst
from ph_explorer.app.dataset import Dataset, default_dataset
from ph_explorer.models.deviation_model import DeviationModel, as_orientations
from ph_explorer.models.lattice import TOLERANCE_UM, BuildStopped, PredictionLattice, build_cpu_s

A_RANGE = (0.0, 40.0)  # a part of the A range keeps the builds short


@pytest.fixture(scope="module")
def dataset() -> Dataset:
    return default_dataset()  # the shipped paper campaign with assets/models/paper: network and trilinear


def random_orientations(n: int, a_range: tuple[float, float] = A_RANGE, seed: int = 3) -> NDArray[np.float64]:
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(*a_range, n), rng.uniform(-180.0, 180.0, n)])


@pytest.mark.parametrize("name", ["network", "trilinear"])
def test_lattice_gives_the_models_curves_within_its_tolerance(dataset: Dataset, name: str) -> None:
    model = dataset.models[name]
    lattice = PredictionLattice.build(model, 64, A_RANGE)
    assert lattice.trusted.all()  # both are smooth enough everywhere
    o = random_orientations(3000)
    exact = model.predict(o, n_points=64)
    error = np.abs(lattice.predict(o) - exact).max()
    assert error <= TOLERANCE_UM, error
    if name == "trilinear":  # bilinear between its own grid lines (multiples of the step): exact
        assert error < 1e-5
    # The one-orientation path a slider move takes is the same interpolation.
    for a, b in [*o[:50], (0.0, -180.0), (40.0, 180.0), (40.0, 179.99), (12.5, 0.0)]:
        np.testing.assert_allclose(lattice.curve(a, b), lattice.predict([[a, b]])[0], atol=1e-6)
    assert lattice.covers(0.0) and lattice.covers(40.0) and not lattice.covers(40.6) and not lattice.covers(-1.0)


class JumpModel(DeviationModel):
    """Smooth in B, with a jump of 0.1 um at A = 6.46 deg (as a hybrid's physics has at the stylus cone's half-angle)."""

    name = "jump"

    def fit(self, campaign: object, train: ArrayLike | None = None) -> JumpModel:
        return self

    def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        o = as_orientations(orientations)
        theta = np.radians(360.0 * np.arange(n_points or 64) / (n_points or 64))
        level = 0.2 * np.sin(np.radians(o[:, 1])) + 0.1 * (o[:, 0] > 6.46)
        return level[:, None] * np.cos(3 * theta)[None, :]

    def repetition_sigma(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
        return np.full((len(as_orientations(orientations)), n_points or 64), 0.1)

    def save(self, directory: str | Path) -> Path:
        raise NotImplementedError

    @classmethod
    def load(cls, directory: str | Path) -> JumpModel:
        raise NotImplementedError


def test_lattice_does_not_cover_where_the_model_jumps() -> None:
    model = JumpModel()
    lattice = PredictionLattice.build(model, 64, A_RANGE)
    assert not lattice.covers(6.3) and not lattice.covers(6.46)  # the band [6.0, 6.5] holds the jump
    assert lattice.covers(5.9) and lattice.covers(6.6) and lattice.covers(30.0)
    o = random_orientations(3000)
    covered = np.array([lattice.covers(a) for a in o[:, 0]])
    assert 0.95 < covered.mean() < 1.0
    error = np.abs(lattice.predict(o[covered]) - model.predict(o[covered], n_points=64)).max()
    assert error <= TOLERANCE_UM, error
    assert build_cpu_s(model, 64, A_RANGE) < 5.0  # a cheap model is worth a lattice


def test_prepared_dataset_draws_a_slider_move_without_calling_a_model(dataset: Dataset, monkeypatch: pytest.MonkeyPatch) -> None:
    ds = dataset.with_figures({})  # a copy: its own caches and lattices
    measured = [tuple(o) for o in ds.campaign.orientations[:3]]
    before = {o: ds.view(*o) for o in measured}
    ds.prepare()
    assert set(ds.lattices) == {"network", "trilinear"} and ds.prepared.is_set()
    exact = {name: model.predict for name, model in ds.models.items()}

    def refuse(*_: object, **__: object) -> None:
        raise AssertionError("a model was called on a slider move")

    for model in ds.models.values():
        monkeypatch.setattr(model, "predict", refuse)
    for a, b in random_orientations(40, (0.0, 115.0), seed=5):
        view = ds.view(a, b)
        assert not view.measured
        for name, curve in view.curves.items():
            np.testing.assert_allclose(curve, exact[name]([[a, b]], n_points=64)[0], atol=TOLERANCE_UM)
    for o in measured:  # a measured ring's view is computed by the models themselves, once, when prepared
        after = ds.view(*o)
        assert after.measured and set(after.curves) == set(before[o].curves)
        for name in after.curves:
            np.testing.assert_allclose(after.curves[name], before[o].curves[name], atol=1e-12)
    # A copy with the same models keeps their lattices (a refit adds a model, the others stay).
    assert ds.with_figures({}).lattices["network"] is ds.lattices["network"]


def test_a_preparation_waits_while_a_clicked_job_runs(dataset: Dataset, monkeypatch: pytest.MonkeyPatch) -> None:
    """A diagnosis clicked right after the page loads does not share the cores with the lattices:
    the background preparation waits between its pieces while a clicked job runs, then goes on."""
    ds = dataset.with_figures({})
    assert not ds.lattices and not ds.prepared.is_set()
    calls: list[str] = []
    for name, model in ds.models.items():
        monkeypatch.setattr(model, "predict", lambda *a, _name=name, _predict=model.predict, **k: calls.append(_name) or _predict(*a, **k))
    with FOREGROUND.running():
        ds.prepare_in_background()
        threading.Event().wait(0.5)
        assert calls == [] and not ds.prepared.is_set()
    assert ds.prepared.wait(60.0) and set(ds.lattices) == set(ds.model_names) and calls


def test_latest_first_runs_the_latest_and_skips_the_dropped() -> None:
    class Box:
        def __init__(self, n: int) -> None:
            self.n = n

    done: list[int] = []
    started, gate, finished = threading.Event(), threading.Event(), threading.Event()

    def job(box: Box) -> None:
        started.set()
        gate.wait(10.0)
        done.append(box.n)
        if len(done) == 3:
            finished.set()

    runner = LatestFirst(job, name="test-latest-first")
    first = Box(0)
    runner.add(first)
    assert started.wait(10.0)  # the first is being prepared: the others wait
    kept = [Box(1), Box(2)]
    dropped = Box(3)
    runner.add(kept[0])
    runner.add(dropped)
    runner.add(kept[1])
    del dropped  # nobody holds it: skipped
    gate.set()
    assert finished.wait(10.0)
    assert done == [0, 2, 1]


def test_stop_ends_the_running_build_between_batches_and_takes_no_more() -> None:
    """What runs at the process' exit: the running job sees `stopping`, its build stops at the next
    batch (BuildStopped), `stop` returns once it has, and nothing added afterwards runs."""
    calls: list[int] = []
    started = threading.Event()

    class Slow(JumpModel):
        def predict(self, orientations: ArrayLike, n_points: int | None = None) -> NDArray[np.float64]:
            calls.append(len(as_orientations(orientations)))
            started.set()
            threading.Event().wait(0.05)  # a batch takes a while
            return super().predict(orientations, n_points)

    outcome: list[str] = []

    def job(model: Slow) -> None:
        try:
            PredictionLattice.build(model, 64, (0.0, 115.0), stop=runner.stopping.is_set)
            outcome.append("built")
        except BuildStopped:
            outcome.append("stopped")

    runner = LatestFirst(job, name="test-stop")
    model = Slow()
    runner.add(model)
    assert started.wait(10.0)
    assert runner.stop(10.0) and outcome == ["stopped"]
    assert 1 <= len(calls) <= 2  # of the 21 batches of the whole lattice
    runner.add(Slow())
    threading.Event().wait(0.2)
    assert outcome == ["stopped"] and len(calls) <= 2


def test_a_large_campaigns_lattice_keeps_under_its_memory_bound_with_a_coarser_step() -> None:
    from ph_explorer.models.lattice import MAX_BYTES, STEP_DEG, step_for

    assert step_for(64, (0.0, 115.0)) == STEP_DEG  # the paper's: 43 MB
    coarse = step_for(256, (-115.0, 115.0))  # 256 points per ring, negative A: 340 MB at 0.5 deg
    assert coarse > STEP_DEG
    lattice = PredictionLattice.build(JumpModel(), 256, (-115.0, 115.0))
    assert lattice.step_deg == coarse and lattice.nbytes <= MAX_BYTES
    o = random_orientations(500, (-115.0, 115.0))
    covered = np.array([lattice.covers(a) for a in o[:, 0]])
    assert covered.mean() > 0.9  # this model is smooth in B: the coarse lattice still covers most of A
    error = np.abs(lattice.predict(o[covered]) - JumpModel().predict(o[covered], n_points=256)).max()
    assert error <= TOLERANCE_UM, error
