"""The catalog of physical effects of the PH20/TP20 head-touch twin (see effects/effect.py).

`DEFAULT_CATALOG` maps each built-in effect id to its class; `DEFAULT_CATALOG.with_file(path)`
is a catalog that also holds the Effect subclasses of a user's own Python file;
`catalog.make(spec)` builds an effect from a scenario's {"id": ..., <parameters>} table. Every
effect says where it sits (`axis`), what kind of error it is (`kind`, one of effect.KINDS) and its
ISO 230-1 style `symbol` (EXB, XOB, ...: error motions in effects/motions.py, location errors in
effects/location.py).

Method: docs/methods/effects.md.
"""

from ph_explorer.effects.catalog import BUILTIN_EFFECTS, DEFAULT_CATALOG, Catalog, load_user_effects
from ph_explorer.effects.effect import Effect, EffectSum, Evidence, Parameter, effect_label, settings_label, settings_text

__all__ = [
    "BUILTIN_EFFECTS",
    "DEFAULT_CATALOG",
    "Catalog",
    "Effect",
    "EffectSum",
    "Evidence",
    "Parameter",
    "effect_label",
    "settings_label",
    "settings_text",
    "load_user_effects",
]
