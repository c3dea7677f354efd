"""Which effect is missing: every candidate effect competes for what the baseline cannot predict
out of sample.

Its basis columns are put through the same out-of-sample smoother as the data, so that an effect
is only credited with what the baseline does not already capture (docs/physics.md). Its scanned
parameters' values are tried one by one (cycles per revolution 1-40 for the cyclic errors). A
candidate counts only when it explains more than the same scan explains on pure noise of the
campaign's own repetition sigma (Monte Carlo, a look-elsewhere-corrected test), and when adding
it lowers the out-of-sample rms error against the reference that exposes it materially.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from functools import reduce
from itertools import islice
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import NULL_MARGIN, Candidate
from ph_explorer.diagnosis.evidence import binned_evidence
from ph_explorer.diagnosis.fitted_bases import WITHIN_BUDGET_BYTES, FittedBases, settings_key
from ph_explorer.diagnosis.within_noise import NoiseTest, within_noise
from ph_explorer.effects import Effect
from ph_explorer.kinematics import campaign_touches
from ph_explorer.models import least_squares
from ph_explorer.models.crossval import LeaveOut, OutOfSampleSmoother
from ph_explorer.models.deviation_model import draw_repetitions
from ph_explorer.models.hybrid import fitted_basis
from ph_explorer.models.least_squares import Design
from ph_explorer.uncertainty.jackknife import COVERAGE_FACTOR, jackknife_parameters

# Monte Carlo draws of pure noise for the significance of a candidate's scan.
NULL_DRAWS = 39
# The scanned settings the data cannot exclude beside the best: those whose explained sum of squares
# is within this many residual variances per touch of it (a profile likelihood's 95 % set for one
# parameter, chi-square with 1 degree of freedom).
SETTINGS_NOT_EXCLUDED = 3.84
# A candidate must explain more than NULL_MARGIN times the most that pure noise explained in the
# same scan (a look-elsewhere-corrected significance test) ...
# ... and lower the out-of-sample rms error against the reference that exposes it by at least this
# fraction: less is within what a user would see as the model's normal scatter, not a missing effect.
MATERIAL_REDUCTION = 0.15
# A candidate that is not material on the check rings is still taken when it brings at least this
# many of the rings that exceed their noise within it: more than one, so that no single ring decides,
# and at least this share of them, so that it explains a material part of the failure (as the
# check rings' 15 % does; with a catalog of many effects a couple of rings is what one of them
# takes from a failure it does not explain).
RINGS_BROUGHT_WITHIN = 2
SHARE_BROUGHT_WITHIN = 0.25
# Significant scan values of one effect tried for materiality, most explained first.
MAX_MATERIAL_TRIALS = 8
# Scan values fitted at once: as many as hold this many bytes of their columns (explained_beyond
# copies them once more), at least one; a ring's mean only, or the columns that change between
# repetitions (n_rep times larger). Two scans run at a time: a dense campaign's 40 harmonic orders
# held at once took 600 MB each.
SCAN_CHUNK_BYTES = 64 * 2**20
# A ring's out-of-sample residual and columns hold its neighbours' touches (through the
# interpolator), so delete-one-ring fits are not independent and the jackknife understates the
# spread. The factor that brings 95 % of fitted parameters within U on calibration heads of their
# own (benchmarks/population.py, part 0b; results.json population.u_calibration): 1.099 over 354
# parameters of 121 heads, seeds 950000-950149, measured with 1.0 (327 within U, 92.4 %).
JACKKNIFE_INFLATION = 1.1


@dataclass
class Scan:
    """One effect's scan: what each scan value explains of the data (best first), and the most any explains of each noise draw."""

    effect: Effect
    fixed: Design | None
    total: float  # the data's sum of squares left by `fixed`
    scanned: list[tuple[float, dict[str, Any]]]
    null_best: NDArray[np.float64]  # (NULL_DRAWS,)


FOLD_DESIGN_BUDGET_BYTES = 128 * 2**20  # a nested fold's designs kept (head_3's: about 100 MB)
# Beyond this many bytes of a search's designs (a dense campaign's: about 900 MB), a scan keeps only
# the settings judge() tries; the next step of a chain makes the others again (head_3's: about 60 MB).
KEPT_DESIGN_BYTES = 384 * 2**20


def _size(design: Design) -> int:
    """A design's bytes: its mean part and its within part."""
    return design.mean.nbytes + (0 if design.within is None else design.within.nbytes)


def _rms(x: NDArray[np.float64]) -> float:
    return float(np.sqrt(np.mean(x**2)))


class CandidateSearch:
    """Scores candidate effects against what the baseline cannot predict out of sample."""

    def __init__(
        self,
        campaign: Campaign,
        train: NDArray[np.bool_],
        seed: int = 0,
        detail: bool = True,
        bases: FittedBases | None = None,
        leave_out: LeaveOut = "ring",
        null_draws: int = NULL_DRAWS,
    ) -> None:
        self.campaign = campaign
        # detail: each candidate with its parameters' uncertainty (a jackknife over rings) and its
        # evidence; a search that only chooses (a nested fold's) needs neither.
        self.detail = detail
        self.train = np.asarray(train, dtype=bool)
        self.held_out = np.flatnonzero(~self.train)
        # Every ring's out-of-sample residual: leave-one-out at training rings, the whole training
        # set at held-out rings (whose measurements never enter a data-driven fit).
        # bases: the fitted columns shared with other searches on subsets of the same touches (nested folds).
        self.bases = bases if bases is not None else FittedBases(campaign_touches(campaign), keep=False)
        self.touches = campaign_touches(campaign) if bases is not None else self.bases.touches
        self._designs: dict[tuple[str, tuple], Design] = {}
        # The shapes of other variables fitted in a claim's place, by claim and chain (rival_shapes._rivals):
        # its claim test and its pair test ask for the same ones.
        self.rival_shapes: dict[tuple, Any] = {}
        self._before: tuple[Design | None, tuple[NDArray, NDArray]] | None = None  # judge's last check_residual
        self._design_bytes = self._within_design_bytes = 0
        # The designs kept and in_rows are asked for from threads (rank_candidates', loop.ShapesAhead's).
        self._lock, self._rows_lock = threading.Lock(), threading.Lock()
        self.seed = seed
        self._in_rows: CandidateSearch | None = None
        self.group_views: dict[str, CandidateSearch] = {}  # the search each shape group is judged in (shapes.view_of)
        self.smoother = OutOfSampleSmoother(campaign.orientations, self.train, leave_out=leave_out)
        self.residual = self.smoother.residual(campaign.deviations)
        sigma = campaign.noise_sigma_um()
        self.sigma = sigma if np.isfinite(sigma) and sigma > 0 else float(np.std(self.residual))
        n_o, n_rep, n_pt = campaign.deviations.shape
        # Pure touch noise with the campaign's post-fit spread, through the same circle fit and smoother (none for a nested fold's).
        self.null_draws = null_draws
        noise = draw_repetitions(np.zeros((n_o, n_pt)), self.sigma, n_rep * null_draws, np.random.default_rng(seed))
        noise = noise.reshape(n_o, n_rep, null_draws, n_pt)
        noise -= self.smoother.predict(noise.mean(axis=1))[:, None]  # smoother.residual, in place: it is big
        # Column 0: the data's residual; the others: what noise alone would leave.
        columns = np.empty((n_o, n_rep, n_pt, 1 + null_draws))
        columns[..., 0] = self.residual
        columns[..., 1:] = np.moveaxis(noise, 2, -1)  # (n_o, n_rep, n_pt, draws)
        del noise
        self.targets = Design(columns, None, owned=True)
        del columns
        self.targets_total = self.targets.total()  # every scan's starting sums of squares

    def in_rows(self) -> CandidateSearch:
        """The same search with each inner A row's training rings predicted without their whole row
        (crossval.inner_rows), on the same fitted columns; made once (docs/methods/shapes.md)."""
        with self._rows_lock:
            if self._in_rows is None:
                self._in_rows = CandidateSearch(self.campaign, self.train, self.seed, detail=False, bases=self.bases, leave_out="row")
        return self._in_rows

    def within_noise_after(self, effects: Sequence[Effect], seed: int = 0) -> NoiseTest | None:
        """The within-noise test of what the effects (none: the baseline) leave out of sample, each
        ring's terms fitted without that ring (as the replication test fits them), so that the
        rings that alone carry an effect are not judged on a fit to themselves."""
        residual, spread = self.residual, self.campaign.deviations
        if effects:
            design = self.design(effects)
            mean, within = design.apply_each(least_squares.jackknife(design, self.targets, np.arange(self.campaign.n_orientations)))
            changing = 0.0 if within is None else within
            residual, spread = residual - mean[:, None, :] - changing, spread - changing
        return within_noise(residual, self.smoother.weights, spread, seed, held_out=~self.train)

    def design(self, effects: Sequence[Effect]) -> Design:
        """The effects' fitted basis columns, side by side, through the smoother."""
        return reduce(Design.stacked, [self._design(effect) for effect in effects])

    def fitted_u(self, chain: Sequence[Effect], count: int) -> list[tuple[dict[str, float], dict[str, float]]]:
        """(params, params_u) of the chain's first `count` effects in the joint fit of the whole chain,
        U (k = 2) from the fits without each ring, as a candidate's."""
        joint = self.design(chain)
        coefficients = least_squares.fit(joint, self.targets)[0][:, 0]
        without = least_squares.jackknife(joint, self.targets, np.arange(self.campaign.n_orientations))
        edges = np.cumsum([0, *(self.design([effect]).n_columns for effect in chain[:count])])
        k = COVERAGE_FACTOR * JACKKNIFE_INFLATION
        return [jackknife_parameters(e, without[:, a:b], coefficients[a:b], k=k) for e, a, b in zip(chain, edges[:-1], edges[1:])]

    def _design(self, effect: Effect) -> Design:
        """One effect's design at its settings, made once per search (every ranking and every
        step of the chain asks for the same scan values again)."""
        key = settings_key(effect)
        if key in self._designs:
            return self._designs[key]
        design = Design(self.bases(effect), self.smoother)
        # Kept for the search: a ring's mean only, always (a nested fold's scan, on shared bases
        # and two at a time, within FOLD_DESIGN_BUDGET_BYTES); one that changes between
        # repetitions, n_rep times larger, within WITHIN_BUDGET_BYTES of the search's own (a nested
        # fold's shared bases keep its columns instead).
        size = _size(design)
        with self._lock:
            if key in self._designs:  # made meanwhile in another thread
                return self._designs[key]
            if self.bases.keep:
                keep = design.within is None and self._design_bytes + size <= FOLD_DESIGN_BUDGET_BYTES
            else:
                keep = design.within is None or self._within_design_bytes + size <= WITHIN_BUDGET_BYTES
                self._within_design_bytes += size if keep and design.within is not None else 0
            if keep:
                self._design_bytes += size
                self._designs[key] = design
        return design

    def forget_designs(self, effect: Effect | None = None, settings: Sequence[dict[str, Any]] = ()) -> None:
        """Let designs made so far go (their memory): every one (e.g. before the nested folds'
        searches), or the effect's at the given settings."""
        keys = list(self._designs) if effect is None else [settings_key(effect.with_settings(**each)) for each in settings]
        for key in keys:
            with self._lock:
                design = self._designs.pop(key, None)
                size = 0 if design is None else _size(design)  # kept with the bytes _design counted: its size, and its within part's
                self._design_bytes -= size
                self._within_design_bytes -= size if design is not None and design.within is not None else 0

    def scan(self, effect: Effect, fixed: Design | None = None) -> Scan | Candidate:
        """What every scan value of the effect explains of the data and of each pure-noise draw,
        beyond the columns `fixed` already in the model; an untested Candidate when it cannot be."""
        unmet = effect.unmet_needs(self.touches)
        if unmet:
            return Candidate.untested(effect.id, effect.name, effect.teaching, note=f"the {effect.id} effect {'; '.join(unmet)}")
        total_all = self.targets_total
        base = least_squares.fit(fixed, self.targets)[1] if fixed is not None else np.zeros_like(total_all)
        every = effect.scan_grid()
        if not every:
            return Candidate.untested(effect.id, effect.name, effect.teaching)
        library = self.bases.library(effect)
        if library is not None:  # every setting's columns gathered from one library, each column made once
            columns, indices = library
            del library
            # The columns are this scan's own: one that changes between repetitions becomes the design's within part in place.
            design = Design(columns, self.smoother, owned=columns.flags.writeable)
            del columns
            explained = least_squares.explained_by_library(fixed, design, indices, self.targets)
            del design
            return self._scanned(effect, fixed, every, explained, total_all, base)
        # The scanned values a few at a time (least_squares.explained_beyond, SCAN_CHUNK_BYTES of
        # columns), grouped by column count, each few made only when scored, so that a dense
        # campaign never holds every scan value's.
        first = self.design([effect.with_settings(**every[0])])
        held = first.mean.nbytes if first.within is None else first.within.nbytes
        chunk = max(1, min(len(every), SCAN_CHUNK_BYTES // max(held, 1)))
        grid: list[dict[str, Any]] = []
        parts = []
        for start in range(0, len(every), chunk):
            part = [
                (settings, first if start + i == 0 else self.design([effect.with_settings(**settings)]))
                for i, settings in enumerate(every[start : start + chunk])
            ]
            part = [(settings, design) for settings, design in part if design.n_columns]
            block = np.zeros((len(part), 1 + self.null_draws))
            for count in {design.n_columns for _, design in part}:
                same = [i for i, (_, design) in enumerate(part) if design.n_columns == count]
                block[same] = least_squares.explained_beyond(fixed, [part[i][1] for i in same], self.targets)
            grid += [settings for settings, _ in part]
            parts.append(block)
            del part
        if not grid:
            return Candidate.untested(effect.id, effect.name, effect.teaching)
        return self._scanned(effect, fixed, grid, np.concatenate(parts), total_all, base)

    def _scanned(
        self,
        effect: Effect,
        fixed: Design | None,
        grid: list[dict[str, Any]],
        explained: NDArray[np.float64],
        total_all: NDArray[np.float64],
        base: NDArray[np.float64],
    ) -> Scan:
        """The Scan of what each setting of grid explains (explained: (settings, 1 + NULL_DRAWS))."""
        null_best = np.maximum(0.0, explained[:, 1:].max(axis=0))
        scanned = sorted(((float(e), settings) for e, settings in zip(explained[:, 0], grid)), key=lambda item: item[0], reverse=True)
        if self._design_bytes > KEPT_DESIGN_BYTES:  # a large campaign: keep only what judge() asks for again
            self.forget_designs(effect, [settings for _, settings in scanned[MAX_MATERIAL_TRIALS:]])
        return Scan(effect, fixed, float(total_all[0] - base[0]), scanned, null_best)

    def score(self, effect: Effect, fixed: Design | None = None) -> Candidate:
        """One candidate judged on its own null (rank_candidates judges every candidate against
        the null of the whole family)."""
        scanned = self.scan(effect, fixed)
        return scanned if isinstance(scanned, Candidate) else self.judge(scanned, float(scanned.null_best.max()))

    def judge(self, scan: Scan, null_level: float, detail: bool = True) -> Candidate:
        """The candidate's best scan value: beyond noise when it explains more than NULL_MARGIN
        times null_level (what pure noise explains at most in the look-elsewhere family, in this
        effect's units); among those with a plausible fit (most explained first, at most
        MAX_MATERIAL_TRIALS) the first that also lowers the held-out error materially is chosen, so
        that a large but harmless component of the same effect (a low-order cyclic error the grid
        resolves) does not hide a short-period one that it does not (docs/diagnosis.md, step 2).
        """
        effect, fixed, total, scanned = scan.effect, scan.fixed, scan.total, scan.scanned
        threshold = NULL_MARGIN * null_level
        beyond = [item for item in scanned if item[0] > threshold]
        # What the fixed columns leave at the check rings: the same for every candidate of a ranking.
        cached = self._before  # read once: rank_candidates judges in threads
        if cached is None or cached[0] is not fixed:
            cached = self._before = (fixed, self.check_residual(fixed))
        before = cached[1]
        chosen = None
        # An implausible fit is never the explanation: the settings tried are those beyond noise whose fit is
        # plausible (a low period of an axis swept in part fits anything at a size no head has); else the best.
        for trials in (islice(self._plausible(effect, fixed, beyond), MAX_MATERIAL_TRIALS), beyond[:MAX_MATERIAL_TRIALS] or scanned[:1]):
            for explained, settings in trials:
                design = self.design([effect.with_settings(**settings)])
                joint = design if fixed is None else fixed.stacked(design)
                reduction = self.check_reduction(joint, before)
                if chosen is None or (reduction >= MATERIAL_REDUCTION and chosen[2] < MATERIAL_REDUCTION):
                    chosen = (explained, settings, reduction, design, joint)
                if reduction >= MATERIAL_REDUCTION:
                    break
            if chosen is not None:
                break
        explained, settings, reduction, design, joint = chosen
        left = max(total - explained, 0.0) / self.residual.size  # what is left, per touch
        not_excluded = [other for value, other in scanned if other != settings and explained - value <= SETTINGS_NOT_EXCLUDED * left]
        own = least_squares.fit(joint, self.targets)[0][-design.n_columns :, 0]
        found = effect.with_settings(**settings)
        if self.detail and detail:
            every_ring = np.arange(self.campaign.n_orientations)
            without = least_squares.jackknife(joint, self.targets, every_ring)[:, -design.n_columns :]
            params, params_u = jackknife_parameters(found, without, own, k=COVERAGE_FACTOR * JACKKNIFE_INFLATION)
        else:
            params, params_u = found.from_coefficients(own), {}
        implausible = found.implausible(params)
        return Candidate(
            effect=effect.id,
            name=effect.name,
            explained_fraction=explained / max(total, 1e-300),
            error_reduction=reduction,
            noise_fraction=float((null_level if np.isfinite(null_level) else scan.null_best.max()) / max(total, 1e-300)),
            # A fit outside the effect's plausible range is never the explanation.
            significant=bool(explained > threshold and reduction >= MATERIAL_REDUCTION and not implausible),
            params={k: float(v) for k, v in params.items()},
            params_u={k: float(v) for k, v in params_u.items()},
            settings=settings,
            settings_not_excluded=tuple(not_excluded),
            teaching=effect.teaching,
            evidence=self.evidence(found, design, own) if self.detail and detail else {},
            note="best catalog fit implausible: " + "; ".join(implausible) if implausible else "",
            beyond_noise=bool(explained > threshold and not implausible),
            implausible=bool(implausible),
        )

    def _plausible(
        self, effect: Effect, fixed: Design | None, scanned: Sequence[tuple[float, dict[str, Any]]]
    ) -> Iterator[tuple[float, dict[str, Any]]]:
        """The scan values (in turn) whose fit beside `fixed` is plausible (Effect.implausible)."""
        for item in scanned:
            found = effect.with_settings(**item[1])
            design = self.design([found])
            joint = design if fixed is None else fixed.stacked(design)
            if not found.implausible(found.from_coefficients(least_squares.fit(joint, self.targets)[0][-design.n_columns :, 0])):
                yield item

    def check_residual(self, design: Design | None) -> tuple[NDArray, NDArray]:
        """The held-out rings' residual (mean, single touches) left by design, each ring left out of its fit."""
        residual = self.residual[self.held_out]
        if design is not None and design.n_columns:
            coef = least_squares.jackknife(design, self.targets, self.held_out)  # (m, c)
            mean = np.einsum("opc,oc->op", design.mean[self.held_out], coef)
            within = 0.0 if design.within is None else np.einsum("orpc,oc->orp", design.within[self.held_out], coef)
            residual = residual - mean[:, None, :] - within
        return residual.mean(axis=1), residual

    def check_reduction(self, joint: Design, before: tuple[NDArray, NDArray]) -> float:
        """How much the joint design lowers the held-out rings' rms error from `before` (a
        check_residual), against the reference that exposes it: the repetition mean, or single
        repetitions for what changes between them."""
        mean_before, single_before = before
        mean_after, single_after = self.check_residual(joint)
        by_mean = 1.0 - _rms(mean_after) / max(_rms(mean_before), 1e-300)
        by_single = 1.0 - _rms(single_after) / max(_rms(single_before), 1e-300)
        return float(max(by_mean, by_single, 0.0))

    def evidence(self, effect: Effect, design: Design, coef: NDArray[np.float64]) -> dict[str, Any]:
        """The candidate's whole fitted term and what the data say of it, binned against the effect's
        own variable: the residual plus the part of the term the baseline already predicts, so that
        the plot shows the effect at the size its parameters state."""
        mean, within = design.apply(coef)
        out_of_sample = mean[:, None, :] + (0.0 if within is None else within)
        whole = fitted_basis(effect, self.touches)[0] @ coef
        return binned_evidence(effect.evidence(self.touches), self.residual + whole - out_of_sample, whole)
