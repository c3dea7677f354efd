"""How large an effect must be for the diagnosis to see it, and heads that hold one at a known strength.

An effect's detection limit on a campaign is the factor on its amplitudes at which it just meets
the diagnosis's three tests: what it leaves out of sample (its touches through the circle fit and
the interpolator's smoother, as the search sees it) makes the baseline fail the within-noise test
(the gate: nothing is searched for in a model within noise), explains NULL_MARGIN times the most
pure noise explains over the catalog's whole scan (beyond noise), and lowers its check rings'
error by MATERIAL_REDUCTION when it is fitted exactly (material). Method: docs/methods/random_heads.md.
"""

from __future__ import annotations

import math

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import NULL_MARGIN
from ph_explorer.diagnosis.ranking import family_levels
from ph_explorer.diagnosis.search import MATERIAL_REDUCTION, CandidateSearch, Scan
from ph_explorer.diagnosis.within_noise import ScaledWithinNoise, noise_null, ring_sigma
from ph_explorer.effects import DEFAULT_CATALOG, Catalog, Effect
from ph_explorer.errors import InputError
from ph_explorer.harmonics import remove_size_and_centre
from ph_explorer.models.least_squares import Design
from ph_explorer.twin.random_heads import design_of, random_campaign

SETTING_DRAWS = 50  # settings tried before an effect is found too weak to reach a strength plausibly
GATE_STEP, GATE_STEPS, GATE_BISECTIONS = 2.0, 40, 12  # the gate's scan of factors up from 2^-20, and its refinement


class DetectionLimits:
    """The detection limits of effects on one campaign: the catalog's scans made once (module docstring)."""

    def __init__(self, campaign: Campaign, catalog: Catalog = DEFAULT_CATALOG, seed: int = 0) -> None:
        self.seed = seed
        self.search = CandidateSearch(campaign, ~campaign.holdout_mask(), seed, detail=False)
        scans = [self.search.scan(cls()) for cls in catalog.candidates().values()]
        levels = family_levels(scans)
        # Each effect's null level: the family's noise maximum on its own scale.
        self.levels = {s.effect.id: levels[id(s)] for s in scans if isinstance(s, Scan) and id(s) in levels}
        held = self.search.held_out
        self.left = float(np.sqrt(np.mean(self.search.residual[held].mean(axis=1) ** 2)))
        n_o, n_rep, n_pt = campaign.deviations.shape
        weights, sigma = self.search.smoother.weights, ring_sigma(campaign.deviations) if n_rep > 1 else None
        # The within-noise test's null is the same for every effect and factor: drawn once.
        self.null = noise_null(weights, sigma, n_rep, n_pt, seed) if sigma is not None else None

    def gate(self, design: Design) -> float:
        """The smallest factor at which the baseline fails the within-noise test (0 when it fails
        without the effect; inf when it never does, or the campaign has no repetitions to test)."""
        if self.null is None:
            return math.inf
        mean, within = design.apply(np.ones(1))
        # The spread only draws the test's null, which is given: the campaign's as it is.
        test = ScaledWithinNoise(self.search.residual, mean, within, self.search.smoother.weights, self.null, ~self.search.train)
        if test(0.0).fails:
            return 0.0
        low, high = 0.0, 2.0**-20
        for _ in range(GATE_STEPS):
            if test(high).fails:
                break
            low, high = high, high * GATE_STEP
        else:
            return math.inf
        for _ in range(GATE_BISECTIONS):
            middle = 0.5 * (low + high)
            low, high = (low, middle) if test(middle).fails else (middle, high)
        return high

    def limit(self, effect: Effect) -> float:
        """The factor on the effect's amplitudes at which the search's two tests are just met."""
        if effect.id not in self.levels:
            return math.inf  # it cannot be tested on this campaign (e.g. it needs touch times)
        signal = remove_size_and_centre(effect.forward(self.search.touches, np.random.default_rng(self.seed)))
        design = Design(signal[..., None], self.search.smoother)
        seen = float(design.total()[0])
        # Beyond noise: what it leaves out of sample explains NULL_MARGIN times the family's noise level.
        beyond = math.sqrt(NULL_MARGIN * self.levels[effect.id] / seen) if seen > 0 else math.inf
        # Material: at the check rings its mean curve, out of sample, lowers the rms by MATERIAL_REDUCTION
        # when fitted exactly: its rms there is sqrt(1 / (1 - r)^2 - 1) times what is left without it.
        at_checks = float(np.sqrt(np.mean(design.mean[self.search.held_out, :, 0] ** 2)))
        material = self.left * math.sqrt(1.0 / (1.0 - MATERIAL_REDUCTION) ** 2 - 1.0) / at_checks if at_checks > 0 else math.inf
        return max(beyond, material, self.gate(design))


def detection_limit(effect: Effect, campaign: Campaign, catalog: Catalog = DEFAULT_CATALOG, seed: int = 0) -> float:
    """The factor on the effect's amplitudes at which the search sees it on the campaign (DetectionLimits)."""
    return DetectionLimits(campaign, catalog, seed).limit(effect)


def _limit_noise_seed(seed: int) -> int:
    return int(np.random.SeedSequence([int(seed), 3]).generate_state(1)[0])


def _drawn(cls: type[Effect], rng: np.random.Generator) -> Effect:
    """The effect with its amplitudes at half their plausible maximum, random signs and phases, and
    its scanned settings drawn from its scan grid."""
    params: dict[str, float] = {}
    for p in cls.parameters:
        if p.name in cls.scan:
            params[p.name] = float(rng.choice(cls.scan[p.name]))
        elif p.period is not None:
            params[p.name] = float(rng.uniform(0.0, p.period))
        elif p.plausible is not None:
            params[p.name] = 0.5 * p.plausible[1] * float(rng.choice([-1.0, 1.0]))
    return cls(**params)


def head_with_effect(
    seed: int, effect_id: str, strength: float | None = None, design: str | None = None, catalog: Catalog = DEFAULT_CATALOG
) -> tuple[Campaign, float]:
    """(campaign, strength): the random head of `seed` with one hidden catalog effect at `strength`
    times its detection limit (None: drawn from 1-3); see hidden_effect_of."""
    hidden, strength = hidden_effect_of(seed, effect_id, strength, design, catalog)
    return random_campaign(seed, design_of(seed, design), [hidden]), strength


def hidden_effect_of(
    seed: int,
    effect_id: str,
    strength: float | None = None,
    design: str | None = None,
    catalog: Catalog = DEFAULT_CATALOG,
    draw: int = 1,
) -> tuple[Effect, float]:
    """(effect, strength): the effect head_with_effect hides in the head of `seed`. Settings are
    redrawn until its amplitudes stay within their plausible ranges; `draw`: another draw of its
    settings and strength on the same head (a second effect, or a second setting of one)."""
    if effect_id not in catalog:
        error = catalog.unknown(effect_id, column=None)
        error.option = "--hidden-effect"
        raise error
    cls = catalog[effect_id]
    if not cls.candidate or not cls.amplitudes():
        raise InputError(f"effect {effect_id!r} has no amplitude to set at a strength", option="--hidden-effect")
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(draw)]))
    strength = float(rng.uniform(1.0, 3.0)) if strength is None else float(strength)
    if not (np.isfinite(strength) and strength > 0):
        raise InputError(f"must be a positive number, got {strength:g}", option="--strength")
    design = design_of(seed, design)
    # The limit is read on another draw of the head's touch noise: the hidden effect's campaign
    # keeps the head's own, and a limit read on it would know its noise.
    limits = DetectionLimits(random_campaign(seed, design, noise_seed=_limit_noise_seed(seed)), catalog, seed)
    for _ in range(SETTING_DRAWS):
        effect = _drawn(cls, rng)
        factor = strength * limits.limit(effect)
        scaled = {**effect.params, **{name: effect.params[name] * factor for name in cls.amplitudes()}}
        hidden = cls(**scaled)
        if np.isfinite(factor) and not cls.implausible(hidden.params):
            return hidden, strength
    raise InputError(
        f"effect {effect_id!r} cannot reach {strength:g}x its detection limit on this design within its plausible range",
        option="--strength",
    )
