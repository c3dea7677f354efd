"""Which rings to measure (ph_explorer/planning/ring_design.py, `ph-explorer design`)."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from command_line import run_cli

from ph_explorer.campaign import Campaign, lattice_axes, orientation_match
from ph_explorer.errors import InputError
from ph_explorer.geometry import A_LIMIT_DEG
from ph_explorer.io import write_campaign
from ph_explorer.kinematics import touch_kinematics
from ph_explorer.planning.ring_design import candidate_orientations, design_log_det, propose_rings


@pytest.fixture(scope="module")
def twelve():
    return propose_rings(12)


def test_the_design_is_reproducible(twelve) -> None:
    again = propose_rings(12)
    np.testing.assert_array_equal(again.orientations, twelve.orientations)
    assert again.log_det == pytest.approx(twelve.log_det)


def test_every_touch_of_every_ring_is_within_reach(twelve) -> None:
    touches = touch_kinematics(twelve.orientations)
    assert touches.reachable.all()
    assert np.abs(touches.a_deg).max() <= A_LIMIT_DEG
    # The candidates stop where a ring's joint sweep would take the A joint past its limit.
    candidates = candidate_orientations()
    assert touch_kinematics(candidates).reachable.all()
    next_row = candidates[:, 0].max() + 15.0
    assert not touch_kinematics([[next_row, 0.0]]).reachable.all()


def test_the_design_is_a_lattice_the_data_part_keeps_whole(twelve) -> None:
    """Every ring on the lattice lattice_axes finds (else the trilinear data part drops it)."""
    o = twelve.orientations
    assert len(o) == 12 and len(np.unique(o, axis=0)) == 12
    a_axis, b_axis = lattice_axes(o)
    assert np.isin(o[:, 0], a_axis).all() and np.isin(o[:, 1], b_axis).all()


def _random_designs(candidates: np.ndarray, size: int, count: int, lattice: bool) -> list[np.ndarray]:
    """Random designs of the same size; with lattice, only those obeying the same lattice rule."""
    rng = np.random.default_rng(7)
    designs = []
    while len(designs) < count:
        pick = candidates[rng.choice(len(candidates), size, replace=False)]
        a_axis, b_axis = lattice_axes(pick)
        if not lattice or (np.isin(pick[:, 0], a_axis).all() and np.isin(pick[:, 1], b_axis).all()):
            designs.append(pick)
    return designs


@pytest.mark.parametrize("lattice", [True, False])
def test_the_design_makes_effects_identifiable_better_than_random(lattice: bool) -> None:
    """Criterion: the D-criterion, log det of the information matrix of the catalog's effect
    columns after the circle fit (orthonormalised over the candidates, + 1e-4 I), the log of the
    inverse volume of the parameters' confidence ellipsoid. The design beats 20 random designs of
    the same size from the same candidates (under the same lattice rule) on median by a margin,
    and 18 of the 20 outright."""
    candidates = candidate_orientations()
    design = propose_rings(12, lattice=lattice)
    ours = design_log_det(design.orientations, candidates)
    assert ours == pytest.approx(design.log_det, abs=1e-6)
    random = np.array([design_log_det(o, candidates) for o in _random_designs(candidates, 12, 20, lattice)])
    assert ours > np.median(random) + 20.0  # e^20: a confidence volume many times smaller
    assert (ours > random).sum() >= 18


def test_the_measuring_order_puts_the_most_informative_rings_first(twelve) -> None:
    assert twelve.gain[0] == twelve.gain.max()
    assert twelve.gain[:3].sum() > twelve.gain[-3:].sum()


def test_with_data_the_next_rings_are_new_and_add_most_information() -> None:
    measured = np.array([(a, b) for a in (15.0, 45.0, 75.0) for b in (-120.0, 0.0, 120.0)])
    campaign = Campaign(measured, np.zeros((len(measured), 2, 64)))
    following = propose_rings(4, measured=campaign)
    assert not orientation_match(following.orientations, measured).any()
    assert following.measured == 9
    # The information it adds: more than four random new rings add.
    candidates = candidate_orientations()
    left = candidates[~orientation_match(candidates, measured).any(axis=1)]
    both = np.concatenate([measured, following.orientations])
    rng = np.random.default_rng(3)
    random = [design_log_det(np.concatenate([measured, left[rng.choice(len(left), 4, replace=False)]]), candidates) for _ in range(10)]
    assert design_log_det(both, candidates) > max(random)


def test_the_same_ring_in_space_is_proposed_once() -> None:
    """At A0 = 0 every B0 is the same circle (the stylus points down, the B joint sweeps the full
    turn): among a lattice's rings that holds one ring per B0 there, at most one is proposed, and
    none when a measured campaign already holds one."""
    lattice = np.array([(a, b) for a in (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0) for b in np.arange(-160.0, 181.0, 20.0)])
    design = propose_rings(12, lattice)
    assert (design.orientations[:, 0] == 0.0).sum() <= 1
    measured = Campaign(np.array([[0.0, 40.0], [45.0, 0.0]]), np.zeros((2, 2, 64)))
    following = propose_rings(12, lattice, measured=measured)
    assert (following.orientations[:, 0] == 0.0).sum() == 0


def test_a_budget_larger_than_the_candidates_is_bad_input() -> None:
    with pytest.raises(InputError, match="budget"):
        propose_rings(5, candidates=[[15.0, 0.0], [30.0, 20.0]])
    with pytest.raises(InputError, match="at least one"):
        propose_rings(0)


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return run_cli(*args)


def test_cli_design_json_is_one_object() -> None:
    result = run("design", "--budget", "6", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["budget"] == 6 and len(report["orientations"]) == 6 and report["order"] == [1, 2, 3, 4, 5, 6]
    assert report["orientations"] == propose_rings(6).orientations.tolist()
    assert "drift" in " ".join(report["not_designed_for"])  # needs touch times: said, not hidden


def test_cli_design_text_and_data(tmp_path: Path) -> None:
    measured = np.array([(a, b) for a in (15.0, 45.0) for b in (-120.0, 0.0, 120.0)])
    path = write_campaign(Campaign(measured, np.random.default_rng(1).normal(0, 0.2, (6, 3, 64))), tmp_path / "c.csv")
    result = run("design", "--budget", "3", "--data", str(path))
    assert result.returncode == 0, result.stderr
    assert "the next 3 rings after the 6 of c.csv" in result.stdout


@pytest.mark.parametrize(
    "args, expected",
    [
        (("--budget", "0"), "option --budget"),
        (("--budget", "500"), "option --budget"),
        (("--budget", "3", "--data", "missing.csv"), "missing.csv"),
        (("--budget", "3", "--pivot-to-ball-mm", "2"), "option --pivot-to-ball-mm"),
    ],
)
def test_cli_design_bad_input_is_one_line_and_exit_2(args: tuple[str, ...], expected: str) -> None:
    result = run("design", *args)
    assert result.returncode == 2, result.stdout
    assert expected in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.stderr


def test_the_design_does_not_depend_on_the_blas_threads() -> None:
    """The rank of the effects' columns is read from their singular values: from the eigenvalues
    of their Gram matrix (the condition squared, 1e-16 of the largest) it changed with the number
    of BLAS threads, and the 14-ring design among the paper's training rings with it."""
    from threadpoolctl import threadpool_limits

    from ph_explorer.twin import load_scenario, simulate

    scenario = load_scenario("paper")
    campaign = simulate(scenario, scenario.seed)
    pool = campaign.orientations[~campaign.holdout_mask()]
    designs = []
    for threads in (1, 2):
        with threadpool_limits(limits=threads, user_api="blas"):
            designs.append(propose_rings(14, pool, campaign.geometry).orientations)
    assert np.array_equal(designs[0], designs[1])
