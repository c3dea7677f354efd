"""A claim rests on replicated evidence: rings as units, no single ring and no crowd of lattice
rings decides (ph_explorer.diagnosis.replication)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ph_explorer.diagnosis.candidates import Candidate
from ph_explorer.diagnosis.choice import next_found
from ph_explorer.diagnosis.replication import (
    REPLICATION_LEVEL,
    SIGN_FLIPS,
    determined_size,
    random_signs,
    replication,
    ring_gains,
    sign_flip_p,
)
from ph_explorer.diagnosis.results import flagged_in
from ph_explorer.diagnosis.within_noise import NoiseTest
from ph_explorer.models.least_squares import Design

N_RINGS = 60
CHECK = np.arange(N_RINGS) >= 50  # ten check rings, fifty lattice rings


def noise_gains(seed: int) -> np.ndarray:
    """What adding a term of no use does to each ring: a small loss or gain, symmetric."""
    return np.random.default_rng(seed).normal(0.0, 1.0, N_RINGS)


def test_a_gain_most_rings_share_is_replicated():
    gain = noise_gains(1) + 2.0
    test = replication(gain, CHECK)
    assert test.replicated and test.p_value < REPLICATION_LEVEL and test.p_without_top < REPLICATION_LEVEL
    assert test.rings_gaining > 50


def test_the_sign_flip_p_is_the_share_of_sign_patterns_and_mirrors_at_least_as_large():
    """The p-value from its definition, written out: each random sign pattern (rng.choice of -1, +1)
    and its mirror image applied to the gains, the statistic the check rings' mean and the lattice
    rings' mean averaged, the observed value counted once."""
    for seed, shift in ((4, 0.0), (5, 0.3), (6, -0.2)):
        gain = noise_gains(seed) + shift
        signs = np.random.default_rng(seed).choice(np.array([-1.0, 1.0]), size=(SIGN_FLIPS, N_RINGS))
        patterns = np.concatenate([signs, -signs]) * gain
        null = (patterns[:, CHECK].mean(axis=1) + patterns[:, ~CHECK].mean(axis=1)) / 2
        observed = (gain[CHECK].mean() + gain[~CHECK].mean()) / 2
        expected = (1 + (null >= observed - 1e-9).sum()) / (null.size + 1)
        assert sign_flip_p(gain, CHECK, np.random.default_rng(seed)) == expected


def test_random_signs_are_numpys_draws_and_leave_the_stream_where_numpy_does():
    """The fast path (two signs per 64-bit word) against rng.integers, with even and odd counts and
    after a draw that leaves half a word in the generator's buffer (which takes numpy's own way)."""
    for seed, flips, rings, before in ((0, 4000, 131, 0), (1, 100, 7, 0), (2, 3, 5, 0), (3, 100, 64, 3), (4, 50, 60, 1)):
        ours, numpys = np.random.default_rng(seed), np.random.default_rng(seed)
        ours.integers(0, 2, size=before), numpys.integers(0, 2, size=before)
        signs = random_signs(ours, flips, rings)
        assert signs.dtype == np.float64 and signs.shape == (flips, rings)
        assert np.array_equal(signs, numpys.integers(0, 2, size=(flips, rings), dtype=np.int64) * 2.0 - 1.0)
        assert np.array_equal(ours.integers(0, 2, size=9), numpys.integers(0, 2, size=9)) and ours.random() == numpys.random()


def test_one_ring_of_many_carries_no_claim():
    gain = noise_gains(2)
    gain[55] = 400.0  # one check ring at many times its noise, the others within it
    test = replication(gain, CHECK)
    assert not test.replicated
    assert test.carried_by[0] == 55
    assert "not significant" in test.reasons()[0] or "most influential ring" in test.reasons()[0]


def test_four_rings_that_gain_together_are_not_enough_without_their_leader():
    gain = noise_gains(3) * 0.1
    gain[[50, 51, 52, 53]] = [900.0, 40.0, 40.0, 40.0]  # a leader and three followers: four rings of sixty
    test = replication(gain, CHECK)
    assert test.p_without_top > test.p_value
    assert not test.replicated


def test_a_crowd_of_lattice_rings_does_not_outvote_check_rings_that_lose_together():
    gain = np.where(CHECK, -1.0, 0.5) + 0.05 * noise_gains(4)
    pooled = replication(gain, np.zeros(N_RINGS, dtype=bool))  # every ring alike: the crowd wins
    assert pooled.replicated
    test = replication(gain, CHECK)
    assert not test.replicated and test.check_gain < 0 < test.lattice_gain


def test_an_undetermined_size_is_no_claim():
    test = replication(noise_gains(5) + 2.0, CHECK, determined=False)
    assert not test.replicated and "uncertainty" in test.reasons()[-1]
    assert determined_size({"a": 1.0, "b": 0.01}, {"a": 0.4, "b": 0.5}, ["a", "b"])  # one amplitude suffices
    assert not determined_size({"a": 1.0}, {"a": 1.2}, ["a"])
    assert determined_size({"a": 1.0}, {}, ["a"])  # no uncertainty known: not judged


def test_the_gains_are_out_of_sample_per_ring():
    """A column that fits the residual everywhere gains at every ring; one fitted to noise loses."""
    rng = np.random.default_rng(6)
    n_o, n_rep, n_pt = 30, 4, 16
    theta = np.linspace(0, 2 * np.pi, n_pt, endpoint=False)
    column = np.broadcast_to(np.cos(3 * theta)[None, None, :, None], (n_o, n_rep, n_pt, 1))
    noise = rng.normal(0.0, 1.0, (n_o, n_rep, n_pt))
    variance = np.ones(n_o)
    for amplitude, gains_everywhere in ((2.0, True), (0.0, False)):
        residual = amplitude * column[..., 0] + noise
        targets = Design(residual[..., None], None)
        gain = ring_gains(residual, None, Design(column, None), targets, variance)
        assert (gain > 0).all() == gains_everywhere
        assert replication(gain, np.zeros(n_o, dtype=bool)).replicated == gains_everywhere


def test_a_model_within_noise_takes_no_effect_however_much_a_candidate_lowers_the_check_rings():
    """One yardstick: a significant candidate on a model the within-noise test passes is "not needed", never found."""
    candidate = replace(Candidate.untested("b_axis_cyclic", "B-axis cyclic error", ""), significant=True, beyond_noise=True)
    passing = NoiseTest(np.ones(5), 0, 0.0, 1.0, 1.0, False)
    (judged,), taken = next_found([candidate], passing, None, None, [], {})
    assert taken is None and not candidate.not_needed  # a new record: the old one is not changed
    assert judged.status == "not needed" and "within noise without it" in judged.note
    assert flagged_in([[judged]], "not_needed") == (judged,) and flagged_in([[judged]], "suggested") == ()
    # On a failing model an untested candidate is passed over (nothing to take), and not marked.
    untested = Candidate.untested("lobing", "Lobing", "")
    failing = NoiseTest(np.full(5, 1e-4), 5, 3.0, 1.0, 1e-4, True)
    (passed,), taken = next_found([untested], failing, None, None, [], {})
    assert taken is None and passed.status != "not needed"


def test_five_check_rings_that_all_gain_replicate_an_effect_the_lattice_rings_cannot_see():
    """An effect of A0 alone: the interpolator reproduces it along B at every lattice ring (gain
    exactly 0: no units), so five check rings are the evidence; sign flips cannot reach 0.05 with
    four of them, Student's t can, and does when they gain together."""
    gain = np.zeros(N_RINGS)
    five = np.flatnonzero(CHECK)[:5]
    check = np.zeros(N_RINGS, dtype=bool)
    check[five] = True
    gain[five] = [1486.0, 1236.0, 1404.0, 1412.0, 1254.0]
    test = replication(gain, check)
    assert test.replicated and test.rings == 5 and test.p_without_top < 0.01 and test.as_dict()["lattice_gain"] is None
    # One of the five carries it, the others are noise: not replicated.
    gain[five] = [1486.0, 0.8, -1.1, 0.4, -0.3]
    test = replication(gain, check)
    assert not test.replicated and test.carried_by[0] == five[0]
