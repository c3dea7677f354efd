"""What a ring would show of a question the diagnosis leaves open (planning.deciding): each ring's
evidence, the expectation of its gain in the diagnosis's test over rings, in touch noise variances;
how far that gain scatters about it, from what the diagnosed model leaves at its check rings; and
how often the test would pass on those gains (decision_power). Method:
docs/methods/deciding.md#the-rings-that-would-decide.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.replication import replication
from ph_explorer.diagnosis.results import Diagnosis
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect, effect_label
from ph_explorer.kinematics import campaign_touches, touch_kinematics
from ph_explorer.models.hybrid import HybridModel, fitted_basis

POWER_DRAWS = 100  # draws of the rings' gains (decision_power)
SEES_NOTHING = 1e-6  # a ring whose evidence is below this share of the largest (or of one noise variance) sees nothing


@dataclass
class Question:
    """What a few rings should decide: tell `effect` from `other`, or confirm `effect` (other None)."""

    effect: Effect
    other: Effect | None = None
    shared: float = 0.0  # the share of their columns' variance on the measured rings (partners.confounding)
    separated_by: str = ""  # a measurement other than rings that would separate them (diagnosis.separation)

    @property
    def names(self) -> tuple[str, str]:
        """The two sides in words: their ids, each with its settings when both are one effect (its period)."""
        if self.other is None:
            return self.effect.id, ""
        if self.other.id == self.effect.id:
            return effect_label(self.effect), effect_label(self.other)
        return self.effect.id, self.other.id

    @property
    def label(self) -> str:
        return " vs ".join(self.names) if self.other is not None else self.effect.id

    @property
    def words(self) -> str:
        """The question's sides named at their settings: 'a_axis_axial_motion 20 cycles/rev or a_axis_tilt_motion 21 cycles/rev'."""
        return " or ".join(effect_label(e) for e in (self.effect, self.other) if e is not None)

    def reason(self, gain: float, total: float) -> str:
        if self.other is not None:
            first, second = self.names
            return f"tells {first} from {second}: evidence {gain:.0f} of the set's {total:.0f}"
        return f"confirms or refutes {self.effect.id}: evidence {gain:.0f} of the set's {total:.0f}"


def seen_columns(effect: Effect, campaign: Campaign, pool: NDArray[np.float64], weights: NDArray[np.float64]) -> NDArray[np.float64]:
    """The effect's columns as the out-of-sample residual sees them, at the measured rings then the
    pool's, (n_o + n_pool, n_pt, k): after each ring's circle fit, less the data model's prediction
    there (weights: the smoother over both, the pool's rings held out); zeros where it cannot act."""
    own, new = campaign_touches(campaign), touch_kinematics(pool, campaign.geometry, 1)
    k = len(effect.coefficients())
    if effect.unmet_needs(new) or effect.unmet_needs(own):
        return np.zeros((len(weights), campaign.n_points, k))
    columns = np.concatenate([fitted_basis(effect, own)[0].mean(axis=1), fitted_basis(effect, new)[0][:, 0]])
    return np.nan_to_num(columns - np.tensordot(weights, columns, axes=(1, 0)))


class Evidence:
    """What each ring, measured or new, would add to one question, in touch noise variances, as the
    test over rings sees it (module docstring). For a pair, each candidate's prediction in turn is
    the truth and the other, at its settings or one scan step away (neighbour_settings), is refitted
    without the ring on the measured rings and the chosen new ones: what it cannot follow at the
    ring is the ring's evidence, and the truth and refit that leave least count. For a suggested
    candidate, its term at the ring. With the residual's spectrum (residual_spectrum), also how far
    each ring's gain scatters about its evidence (every_ring)."""

    def __init__(
        self,
        question: Question,
        campaign: Campaign,
        pool: NDArray[np.float64],
        weights: NDArray[np.float64],
        spectrum: NDArray[np.float64] | None = None,
    ) -> None:
        self.scale = campaign.n_repetitions / max(campaign.noise_sigma_um(), 1e-12) ** 2
        self.n_o = campaign.n_orientations
        self.check = campaign.holdout_mask()
        self.spectrum = spectrum
        x = seen_columns(question.effect, campaign, pool, weights)
        cx = np.asarray(question.effect.coefficients(), dtype=float)
        # Per (truth, refit): the truth's signal energy per ring, the refit's Gram blocks and their
        # products with the signal per ring (the measured rings first, then the pool's); the same
        # in the residual's inner product (spectral_products) when its spectrum is known.
        self.fits: list[tuple[tuple[NDArray, NDArray, NDArray], tuple[NDArray, NDArray, NDArray] | None]] = []
        if question.other is None:
            signal = np.einsum("opi,i->op", x, cx)
            self.term = (signal**2).sum(axis=1)  # (n_o + n_pool,), a suggestion's evidence
            self.term_scatter = None if spectrum is None else spectral_products(signal[..., None], signal, spectrum)[2]
            return
        y = seen_columns(question.other, campaign, pool, weights)
        cy = np.asarray(question.other.coefficients(), dtype=float)
        for truth, coef, rival in ((x, cx, question.other), (y, cy, question.effect)):
            signal = np.einsum("opi,i->op", truth, coef)
            for settings in rival.neighbour_settings():
                fitted = seen_columns(rival.with_settings(**settings), campaign, pool, weights)
                plain = (np.einsum("opi,opj->oij", fitted, fitted), np.einsum("opi,op->oi", fitted, signal), (signal**2).sum(axis=1))
                self.fits.append((plain, None if spectrum is None else spectral_products(fitted, signal, spectrum)))

    @staticmethod
    def _refit(fit: tuple[NDArray, NDArray, NDArray], total_g: NDArray, total_c: NDArray, at: NDArray[np.int64]) -> NDArray:
        """The refit's coefficients on the totals less each ring of `at` (totals: one per ring or shared), (len(at), k)."""
        return np.einsum("nij,nj->ni", np.linalg.pinv(total_g - fit[0][at], rcond=1e-10, hermitian=True), total_c - fit[1][at])

    @staticmethod
    def _left(fit: tuple[NDArray, NDArray, NDArray], beta: NDArray, at: NDArray[np.int64]) -> NDArray:
        """What the refit `beta` cannot follow of the truth at each ring of `at`, in the fit's inner product, (len(at),)."""
        gram, cross, energy = fit[0][at], fit[1][at], fit[2][at]
        return energy - 2 * np.einsum("ni,ni->n", cross, beta) + np.einsum("ni,nij,nj->n", beta, gram, beta)

    def per_ring(self, rings: list[int], extra: NDArray[np.int64]) -> NDArray[np.float64]:
        """(len(extra), len(rings) + 1): each new ring's evidence when the pool's `rings` and, in
        turn, each of `extra` (last column) are measured."""
        new = [self.n_o + i for i in rings]
        if not self.fits:
            term = self.scale * self.term
            return np.column_stack([np.broadcast_to(term[new], (len(extra), len(rings))), term[self.n_o + extra]])
        out = []
        for fit, _ in self.fits:
            gram, cross = fit[0], fit[1]
            total_g = gram[: self.n_o].sum(axis=0) + gram[new].sum(axis=0) + gram[self.n_o + extra]  # (n_extra, k, k)
            total_c = cross[: self.n_o].sum(axis=0) + cross[new].sum(axis=0) + cross[self.n_o + extra]
            columns = []
            for at in [*(np.full(len(extra), j) for j in new), self.n_o + extra]:  # the rings chosen (a few), then each extra ring itself
                columns.append(self._left(fit, self._refit(fit, total_g, total_c, at), at))
            out.append(np.column_stack(columns))
        each = np.stack(out)  # (fits, n_extra, rings + 1)
        least = np.argmin(each.sum(axis=2), axis=0)  # per extra ring, the fit that leaves least
        return self.scale * each[least, np.arange(len(extra))]

    def every_ring(self, rings: list[int]) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64] | None]:
        """Every ring's evidence, the measured rings' then the pool's `rings`, with the pool's
        measured, which are check rings (the new ones are), and the variance of each one's gain
        about it (None without the residual's spectrum): the test's units, their groups, their scatter."""
        at = np.concatenate([np.arange(self.n_o), self.n_o + np.asarray(rings, dtype=int)])
        check = np.concatenate([self.check, np.ones(len(rings), dtype=bool)])
        if not self.fits:
            scatter = None if self.term_scatter is None else 4.0 * self.scale**2 * self.term_scatter[at]
            return self.scale * self.term[at], check, scatter
        betas = [self._refit(fit, fit[0][at].sum(axis=0), fit[1][at].sum(axis=0), at) for fit, _ in self.fits]
        left = [self._left(fit, beta, at) for (fit, _), beta in zip(self.fits, betas)]
        least = int(np.argmin(np.stack(left).sum(axis=1)))
        spectral = self.fits[least][1]
        # The gain's cross term with the residual: 2 x scale x (what is left) . (the residual).
        scatter = None if spectral is None else 4.0 * self.scale**2 * self._left(spectral, betas[least], at)
        return self.scale * left[least], check, scatter


def spectral_products(
    columns: NDArray[np.float64], signal: NDArray[np.float64], spectrum: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """The Gram blocks of columns (n, n_pt, k), their products with the signal (n, n_pt) and its
    energy, in the inner product of the residual's circulant covariance: u . K v for touches at
    360 k / N round the ring (docs/formats.md), as harmonics weighted by its spectrum (residual_spectrum)."""
    f, s = np.fft.rfft(columns, axis=1), np.fft.rfft(signal, axis=1)
    return (
        np.einsum("oki,okj,k->oij", f.conj(), f, spectrum).real,
        np.einsum("oki,ok,k->oi", f.conj(), s, spectrum).real,
        np.einsum("ok,ok,k->o", s.conj(), s, spectrum).real,
    )


def check_residual(
    campaign: Campaign, result: Diagnosis, catalog: Catalog = DEFAULT_CATALOG
) -> tuple[Campaign, NDArray[np.int64], NDArray[np.float64]]:
    """The campaign the diagnosis fitted (result.judged), its check rings, and the residual there,
    (n_check, n_pt) repetition means, of the model its verdict rests on: its last step's hybrid, or
    (a diagnosis that added nothing, the explorer's, which leaves the ticking to the user) the
    effects it found at their settings and the shapes it claimed. Each ring is left out of the
    physical fit, as the error history and the test over rings predict it (predict_held_out)."""
    fitted = result.judged(campaign)
    train = ~fitted.holdout_mask()
    held_out = np.flatnonzero(~train)
    model = result.hybrid
    if model is None or (not result.chain and (result.found or result.claimed_shapes)):
        found = [catalog[c.effect]().with_settings(**c.settings) for c in result.found]
        model = HybridModel([*found, *(shape.effect() for shape in result.claimed_shapes)]).fit(fitted, train)
    return fitted, held_out, (fitted.deviations[held_out] - model.predict_held_out(fitted, held_out)).mean(axis=1)


def residual_spectrum(campaign: Campaign, result: Diagnosis, catalog: Catalog = DEFAULT_CATALOG) -> NDArray[np.float64] | None:
    """What the diagnosed model leaves at a ring it did not see, as the weights of the harmonics of
    a ring (rfft bins) in its covariance over a turn: the measured check rings' residual (its touch
    noise, and what the data model and the fitted sizes miss alike, the same in every repetition),
    its periodogram averaged over them, so that u . K v = sum_k w_k Re(U_k* V_k). White noise of
    variance v gives v for every touch (Parseval). None without check rings or repetitions."""
    fitted, held_out, residual = check_residual(campaign, result, catalog)
    if held_out.size == 0 or fitted.n_repetitions < 2:
        return None
    n = fitted.n_points
    return one_sided(n) * (np.abs(np.fft.rfft(residual, axis=1)) ** 2).mean(axis=0) / n**2


def one_sided(n: int) -> NDArray[np.float64]:
    """(n // 2 + 1,): each rfft bin's count in a sum over all n harmonics (2, but 1 for the bins that are their own mirror)."""
    counts = np.full(n // 2 + 1, 2.0)
    counts[0] = 1.0
    if n % 2 == 0:
        counts[-1] = 1.0
    return counts


def decision_power(
    gains: NDArray[np.float64], check: NDArray[np.bool_], scatter: NDArray[np.float64] | None = None, draws: int = POWER_DRAWS
) -> float:
    """How often the test over rings (diagnosis.replication: significant, and without its most
    influential ring) passes when each ring's gain scatters about its expectation g with variance
    `scatter` (every_ring: its cross term with what the model leaves at the ring), never below 4 g
    (its cross term with the touch noise alone); rings that see nothing (g = 0) are no units."""
    gains, seen, variance = units(gains, scatter)
    noise = np.random.default_rng(0).standard_normal((draws, gains.size))
    drawn = np.where(seen, gains + np.sqrt(variance) * noise, 0.0)
    return float(np.mean([replication(d, check, True, seed=k).replicated for k, d in enumerate(drawn)]))


def scatter_ratio(gains: NDArray[np.float64], scatter: NDArray[np.float64] | None) -> float:
    """How many times the touch noise's 4 g the gains scatter, over the rings that see the question (1: the touch noise alone)."""
    gains, seen, variance = units(gains, scatter)
    return float(variance[seen].sum() / (4.0 * gains[seen].sum())) if seen.any() else 1.0


def units(
    gains: NDArray[np.float64], scatter: NDArray[np.float64] | None
) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64]]:
    """The rings' expected gains (none below 0), which see the question (no rounding of the largest,
    nor of one noise variance: the test's units), and each gain's variance (never below 4 g)."""
    gains = np.maximum(np.asarray(gains, dtype=float), 0.0)
    seen = gains > max(SEES_NOTHING * float(gains.max(initial=0.0)), SEES_NOTHING)
    return gains, seen, 4.0 * gains if scatter is None else np.maximum(4.0 * gains, scatter)
