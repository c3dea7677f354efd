"""Is a candidate's gain replicated over rings? The test a claim ("found", "missing") must pass.

Each ring is a unit: its out-of-sample residual before (the chain so far) and after (the chain
with the candidate), the physical coefficients fitted without that ring, summed in squares over
single touches and divided by the ring's own noise variance, give its gain. The check rings and
the lattice rings each weigh half (no crowd of lattice rings outvotes check rings that lose
together); a sign-flip permutation of the gains is the null. A claim is replicated when that test
is significant, still is without its most influential ring, and the effect's size is determined
(an amplitude beyond its expanded uncertainty). Method: docs/methods/replication.md.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from ph_explorer.models import least_squares
from ph_explorer.models.least_squares import Design

REPLICATION_LEVEL = 0.05  # one-sided level of the sign-flip test over rings
SIGN_FLIPS = 4000  # random sign patterns of the null (with their mirror images: 2 x SIGN_FLIPS)
CARRYING_RINGS = 3  # the rings that gain most, named as those that carry a claim
# Below this many rings the sign-flip test has no resolution at the level (its smallest p-value is
# 2^-n: 1/64 at six rings, 1/16 at four): the rings' gains are then tested with Student's t.
MIN_FLIP_RINGS = 7
MIN_T_RINGS = 3  # fewer rings than this are no replication at all


@dataclass(frozen=True)
class FormBreak:
    """A claim's parameters that differ between the rings below and above `split_at` of a variable
    (diagnosis.form): its signature is the head's, its form is not."""

    variable: str  # "A" or "B" (the orientation's, deg) or "time" (s)
    split_at: float
    p_value: float
    p_without_top: float

    def words(self) -> str:
        unit = " s" if self.variable == "time" else " deg"
        return (
            f"its parameters differ between the rings with {self.variable} below and above {self.split_at:g}{unit} "
            f"(p = {self.p_value:.3g} over rings): the error has its signature, not its form"
        )


@dataclass(frozen=True)
class RivalShape:
    """A shape of a variable other than a claim's own (diagnosis.rival_shapes) that predicts the rings
    better in the claim's place: the error resembles the catalog effect where the rings look, and
    is another function of the head."""

    group: str  # error_functions.SHAPE_GROUPS key, e.g. "probe_time"
    words: str  # what it is, e.g. "pre-travel lobes of the probe ... changing over the campaign"
    p_value: float  # family-wise over the rival groups (family_test)
    p_without_top: float

    def words_why(self) -> str:
        return (
            f"{self.words} predicts the rings better in its place (p = {self.p_value:.3g} over rings, "
            "as the best of the other variables' shapes): the error resembles this effect, not its form"
        )


@dataclass
class Replication:
    """The evidence over rings for one candidate (see the module docstring)."""

    p_value: float  # the sign-flip test of the weighted gain over rings
    p_without_top: float  # the same without the most influential ring
    rings_gaining: int  # rings whose gain is positive
    rings: int  # rings tested
    check_gain: float  # mean gain of the check rings (noise variances per touch); NaN with none
    lattice_gain: float  # mean gain of the lattice rings (left out one at a time)
    carried_by: list[int] = field(default_factory=list)  # the rings that gain most (indices)
    determined: bool = True  # an amplitude beyond its expanded uncertainty (k = 2)
    form_breaks: FormBreak | None = None  # its parameters differ over the head (diagnosis.form)
    outpredicted: RivalShape | None = None  # a shape of another variable predicts the rings better

    @property
    def replicated(self) -> bool:
        significant = self.p_value < REPLICATION_LEVEL and self.p_without_top < REPLICATION_LEVEL
        return significant and self.determined and self.form_breaks is None and self.outpredicted is None

    def reasons(self) -> list[str]:
        """Why the claim is not replicated, in words ([] when it is)."""
        out = []
        if self.p_value >= REPLICATION_LEVEL:
            test = "sign-flip" if self.rings >= MIN_FLIP_RINGS else "Student's t"
            out.append(f"its gain over rings is not significant ({test} p = {self.p_value:.3g})")
        elif self.p_without_top >= REPLICATION_LEVEL:
            out.append(f"it does not survive leaving out its most influential ring (p = {self.p_without_top:.3g} without it)")
        if not self.determined:
            out.append("no amplitude exceeds its expanded uncertainty")
        if self.form_breaks is not None:
            out.append(self.form_breaks.words())
        if self.outpredicted is not None:
            out.append(self.outpredicted.words_why())
        return out

    def as_dict(self) -> dict[str, Any]:
        return {
            "replicated": self.replicated,
            "p_value": round(self.p_value, 5),
            "p_without_top": round(self.p_without_top, 5),
            "rings_gaining": self.rings_gaining,
            "rings": self.rings,
            "check_gain": None if not np.isfinite(self.check_gain) else round(self.check_gain, 4),
            "lattice_gain": None if not np.isfinite(self.lattice_gain) else round(self.lattice_gain, 4),
            "carried_by": self.carried_by,
            "determined": self.determined,
            "level": REPLICATION_LEVEL,
            "form_breaks": None if self.form_breaks is None else {f.name: getattr(self.form_breaks, f.name) for f in fields(FormBreak)},
            "outpredicted": None if self.outpredicted is None else {f.name: getattr(self.outpredicted, f.name) for f in fields(RivalShape)},
        }

    @classmethod
    def from_json(cls, data: dict[str, Any]) -> Replication:
        gains = [np.nan if data[k] is None else data[k] for k in ("check_gain", "lattice_gain")]
        return cls(
            data["p_value"],
            data["p_without_top"],
            data["rings_gaining"],
            data["rings"],
            *gains,
            list(data["carried_by"]),
            data["determined"],
            FormBreak(**data["form_breaks"]) if data.get("form_breaks") else None,
            RivalShape(**data["outpredicted"]) if data.get("outpredicted") else None,
        )


def ring_residual_squares(residual: NDArray[np.float64], design: Design | None, targets: Design) -> NDArray[np.float64]:
    """(n_o,): each ring's sum of squares over single touches of what the design leaves of the
    residual (n_o, n_rep, n_pt), its coefficients fitted without that ring."""
    if design is not None and design.n_columns:
        mean, within = design.apply_each(least_squares.jackknife(design, targets, np.arange(residual.shape[0])))
        residual = residual - mean[:, None, :] - (0.0 if within is None else within)
    return (residual**2).sum(axis=(1, 2))


def ring_weights(check: NDArray[np.bool_]) -> NDArray[np.float64]:
    """(n_o,): each ring's weight in the statistic: half the check rings' mean gain plus half the
    lattice rings' (the whole mean when one group is empty)."""
    groups = sum(1 for g in (check, ~check) if g.any())
    return np.where(check, 1.0 / max(check.sum(), 1), 1.0 / max((~check).sum(), 1)) / max(groups, 1)


def random_signs(rng: np.random.Generator, flips: int, rings: int) -> NDArray[np.float64]:
    """(flips, rings) of +1 and -1: rng.integers(0, 2, (flips, rings), dtype=np.int64) * 2.0 - 1.0,
    the same draws from the same stream at a fifth of its cost (most of which is fresh memory).
    numpy draws each as the top bit of a 32-bit word (Lemire's method: two values never reject),
    and PCG64 gives a 64-bit word as two of them, the low one first; any other case (another bit
    generator, a half word left in its buffer, an odd count) takes numpy's own way."""
    count, generator = flips * rings, rng.bit_generator
    if count % 2 or sys.byteorder != "little" or not isinstance(generator, np.random.PCG64) or generator.state["has_uint32"]:
        return rng.integers(0, 2, size=(flips, rings), dtype=np.int64) * 2.0 - 1.0
    words = generator.random_raw(count // 2).view(np.uint32)
    signs = np.empty(count)
    np.multiply(np.right_shift(words, 31, out=words), 2.0, out=signs)
    signs -= 1.0
    return signs.reshape(flips, rings)


def sign_flip_p(gain: NDArray[np.float64], check: NDArray[np.bool_], rng: np.random.Generator) -> float:
    """One-sided p-value of the weighted mean gain against random sign flips of every ring's gain."""
    weighted = gain * ring_weights(check)
    observed = float(weighted.sum())
    signs = random_signs(rng, SIGN_FLIPS, gain.size)  # rng.choice([-1.0, 1.0], size)'s draws, the same stream
    half = signs @ weighted  # a sign pattern's statistic; its mirror image is its negative
    null = np.concatenate([half, -half])
    return float((1.0 + (null >= observed - 1e-12 * np.abs(observed)).sum()) / (null.size + 1.0))


def ring_gains(
    residual: NDArray[np.float64], before: Design | None, after: Design, targets: Design, noise_variance: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(n_o,): each ring's fall in its out-of-sample sum of squares from `before` (the chain's
    design, None: nothing) to `after` (the chain with the candidate), in its own noise variances."""
    fall = ring_residual_squares(residual, before, targets) - ring_residual_squares(residual, after, targets)
    return fall / np.maximum(noise_variance, 1e-300)


def few_rings_p(gain: NDArray[np.float64]) -> float:
    """One-sided p-value of the rings' mean gain by Student's t (n - 1 degrees of freedom): the
    test of a few rings, where sign flips cannot reach the level."""
    n = gain.size
    if n < MIN_T_RINGS:
        return 1.0
    mean, spread = float(gain.mean()), float(gain.std(ddof=1))
    if spread == 0.0:
        return 0.0 if mean > 0 else 1.0
    return float(special.stdtr(n - 1, -mean / (spread / np.sqrt(n))))


def rings_p(gain: NDArray[np.float64], check: NDArray[np.bool_], rng: np.random.Generator) -> float:
    """The test over rings: sign flips with MIN_FLIP_RINGS rings or more, Student's t below."""
    return sign_flip_p(gain, check, rng) if gain.size >= MIN_FLIP_RINGS else few_rings_p(gain)


def replication(gain: NDArray[np.float64], check: NDArray[np.bool_], determined: bool = True, seed: int = 0) -> Replication:
    """The replication test of a candidate from its rings' gains (ring_gains); check: the check
    rings; determined: from its parameters (determined_size). Rings whose gain is exactly zero
    (their out-of-sample residual cannot see the effect, e.g. lattice rings of an effect of A0
    alone, which the interpolator reproduces along B) are no units."""
    gain, check = np.asarray(gain, dtype=float), np.asarray(check, dtype=bool)
    seen = np.abs(gain) > 1e-9 * max(float(np.abs(gain).max(initial=0.0)), 1e-300)
    index, gain, check = np.flatnonzero(seen), gain[seen], check[seen]
    rng = np.random.default_rng(seed)
    p_value = rings_p(gain, check, rng)
    # The most influential ring: the one whose gain adds most to the statistic (its group's weight).
    top = int(np.argmax(ring_weights(check) * gain)) if gain.size else 0
    keep = np.arange(gain.size) != top
    p_without = rings_p(gain[keep], check[keep], rng) if keep.sum() >= 2 else 1.0
    order = np.argsort(-gain)
    return Replication(
        p_value=p_value,
        p_without_top=p_without,
        rings_gaining=int((gain > 0).sum()),
        rings=int(gain.size),
        check_gain=float(gain[check].mean()) if check.any() else float("nan"),
        lattice_gain=float(gain[~check].mean()) if (~check).any() else float("nan"),
        carried_by=[int(index[i]) for i in order[:CARRYING_RINGS] if gain[i] > 0],
        determined=determined,
    )


def determined_size(params: dict[str, float], params_u: dict[str, float], amplitudes: list[str]) -> bool:
    """Whether the effect's size is determined: some amplitude exceeds its expanded uncertainty.

    (Components of a vector, e.g. an axis offset along x and y, may each be near zero; the claim
    is of the effect, not of each component.) No uncertainty known (a search that only chooses):
    not judged.
    """
    judged = [name for name in amplitudes if name in params and name in params_u and np.isfinite(params_u[name])]
    if not judged:
        return True
    return any(abs(params[name]) > params_u[name] for name in judged)


def family_test(
    gains: NDArray[np.float64], check: NDArray[np.bool_], seed: int = 0, standardise: bool = False
) -> tuple[NDArray[np.float64], float]:
    """Each group's weighted gain over rings, and the family-wise p-value of the largest.

    gains: (groups, n_o), each ring's gain with each group (in noise variances); a group's statistic
    is the rings' weighted sum of gains (check rings and lattice rings weighing half each, as a
    claim's), the group that predicts the rings best scoring highest. The null flips every ring's
    sign in all groups at once, so the largest statistic over the groups is compared with the
    largest under each flip (Westfall and Young's max-T): the correction for taking the best of
    correlated groups, exact under the sign-flip null (docs/methods/shapes.md). standardise: each
    statistic over its own null spread, so that a group whose gains differ much (both ways) does
    not carry the null's maximum (differences of gains, which may be negative)."""
    weighted = gains * ring_weights(check)[None]
    if standardise:
        weighted = weighted / np.maximum(np.sqrt((weighted**2).sum(axis=1, keepdims=True)), 1e-300)
    statistics = weighted.sum(axis=1)
    rng = np.random.default_rng(seed)
    signs = random_signs(rng, SIGN_FLIPS, gains.shape[1])
    null = (signs @ weighted.T).max(axis=1)  # (flips,): the best group under each flip
    observed = float(statistics.max())
    return statistics, float((1.0 + (null >= observed - 1e-12 * abs(observed)).sum()) / (null.size + 1.0))
