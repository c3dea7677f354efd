"""Heads with two or three catalog effects at once (issue 55, item 6), for the population's
`multi_effect` part: what the one-effect-at-a-time search finds when a head holds several.

Each head is a random head (twin.random_heads: design, background, noise law from its seed) of one
of three kinds, in turn: two different catalog effects (`pair`), three (`triple`), or two settings
of one axis error of a cycles-per-revolution scan (`harmonics`, e.g. B 15/rev and 17/rev: a beat).
Each effect is drawn as the one-effect heads' are (diagnosis.detection.hidden_effect_of: settings
from its scan, 1-3x its own detection limit on this head alone), each draw its own. A head is
judged `all_found` when every effect it holds is claimed (found_each: as the catalog-effect heads
are judged, an untold pair holding it counts), and `all_found_exactly` with its id and settings.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ph_explorer.campaign import Campaign
from ph_explorer.diagnosis.candidates import Candidate
from ph_explorer.diagnosis.detection import hidden_effect_of
from ph_explorer.effects import DEFAULT_CATALOG, Effect
from ph_explorer.effects.error_functions import SHAPE_GROUPS
from ph_explorer.errors import InputError
from ph_explorer.twin.random_heads import design_of, random_campaign

KINDS = ("pair", "triple", "harmonics")
COUNTS = {"pair": 2, "triple": 3, "harmonics": 2}
CATALOG_EFFECTS = [effect_id for effect_id, cls in DEFAULT_CATALOG.candidates().items() if cls.amplitudes()]
HARMONIC_EFFECTS = [effect_id for effect_id in CATALOG_EFFECTS if "cycles_per_rev" in DEFAULT_CATALOG[effect_id].scan]
DRAWS = 8  # draws of an effect's settings tried before another effect is taken
REPLACEMENTS, REPLACEMENT_STRIDE = 6, 1_000_000  # heads tried per seed, and how far apart their seeds are


@dataclass
class MultiEffectHead:
    campaign: Campaign
    kind: str
    effects: list[Effect]
    head_seed: int


def effects_of(seed: int, kind: str, design: str, rng: np.random.Generator) -> list[Effect] | None:
    """The kind's effects on the head of `seed` (each 1-3x its detection limit, settings distinct); None when they cannot all be drawn plausibly."""
    ids = [str(rng.choice(HARMONIC_EFFECTS))] * 2 if kind == "harmonics" else [str(i) for i in rng.permutation(CATALOG_EFFECTS)]
    effects: list[Effect] = []
    draw = 2  # draw 1 is the one-effect heads' own
    for effect_id in ids:
        for _ in range(DRAWS):
            draw += 1
            try:
                effect, _ = hidden_effect_of(seed, effect_id, None, design, draw=draw)
            except InputError:
                break  # it cannot reach its strength plausibly on this design: the next effect
            if all(not (e.id == effect.id and e.settings() == effect.settings()) for e in effects):
                effects.append(effect)
                break
        if len(effects) == COUNTS[kind]:
            return effects
    return None


def multi_effect_head(seed: int) -> MultiEffectHead:
    """The head of `seed` with its kind's effects (module docstring); a head on which they cannot all
    be drawn is replaced by the next of the seed's stream."""
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 556]))
    kind = KINDS[int(seed) % len(KINDS)]
    for head in (int(seed) + REPLACEMENT_STRIDE * k for k in range(REPLACEMENTS)):
        design = design_of(head)
        effects = effects_of(head, kind, design, rng)
        if effects is not None:
            return MultiEffectHead(random_campaign(head, design, effects), kind, effects, head)
    raise RuntimeError(f"no {kind} of effects reaches its strength on seed {seed} nor its replacements")


def partner_settings(candidate: Candidate, untold: bool = False) -> dict[str, list[dict[str, float]]]:
    """A claim's confounded partners, each at the settings the diagnosis names it at (Partner.settings);
    untold: only those the rings were asked about and do not tell it from (Candidate.untold)."""
    partners = candidate.untold if untold else candidate.confounded_with
    return {p.effect: [{k: float(v) for k, v in s.items()} for s in p.settings] for p in partners}


def claim_record(candidate: Candidate) -> dict[str, Any]:
    """A claim as the benchmarks judge it (holds_truth; for an unknown shape, unknown_population's
    own_mechanism): its effect, settings, the settings it cannot exclude, its confounded partners at
    theirs, of those the untold ones, its periods (claimed or not excluded), and the group of a
    shape its rings cannot tell it from."""
    return {
        "effect": candidate.effect,
        "settings": {k: float(v) for k, v in candidate.settings.items()},
        "not_excluded": [{k: float(v) for k, v in o.items()} for o in candidate.settings_not_excluded],
        "confounded_with": [o.effect for o in candidate.confounded_with],
        "partner_settings": partner_settings(candidate),
        "untold_settings": partner_settings(candidate, untold=True),
        "cycles": [float(o["cycles_per_rev"]) for o in (candidate.settings, *candidate.settings_not_excluded) if "cycles_per_rev" in o],
        "untold_shape": None if candidate.untold_shape is None else candidate.untold_shape.group,
    }


def holds_truth(claim: dict[str, Any], effect_id: str, settings: dict[str, float]) -> bool:
    """Whether a claim's record holds an effect: its id at its settings or at settings the claim
    cannot exclude, or a partner the rings did not tell it from, named at its settings (an untold
    pair holds the truth; the pair's credit: issue 55)."""
    if claim["effect"] == effect_id and (claim["settings"] == settings or settings in claim.get("not_excluded", [])):
        return True
    return settings in claim.get("untold_settings", {}).get(effect_id, [])


def found_each(effects: list[Effect], found: list[dict[str, Any]], exact: bool = False) -> list[bool]:
    """For each effect the head holds: a claim holds it (holds_truth, the population's catalog-effect
    rule); exact: only its id at its own settings."""

    def holds(effect: Effect, claim: dict[str, Any]) -> bool:
        settings = {k: float(v) for k, v in effect.settings().items()}
        if exact:
            return claim["effect"] == effect.id and claim["settings"] == settings
        return holds_truth(claim, effect.id, settings)

    return [any(holds(effect, claim) for claim in found) for effect in effects]


def shaped_each(effects: list[Effect], shapes: list[dict[str, Any]]) -> list[bool]:
    """For each effect the head holds: a claimed shape of the effect's axis and ISO 230-7 component
    group holds it (its group, or one of the groups the rings cannot tell it from). Not a catalog
    claim: the error motion named at what the rings tell of it, without its period."""
    return [
        any(
            any(SHAPE_GROUPS[g].axis == effect.axis and SHAPE_GROUPS[g].kind == effect.kind for g in (s["group"], *s["untold"]))
            for s in shapes
        )
        for effect in effects
    ]
