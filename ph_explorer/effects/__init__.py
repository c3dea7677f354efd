"""The catalog of physical effects of the PH20/TP20 head-touch twin (see effects/base.py).

`DEFAULT_CATALOG` maps each built-in effect id to its class; `DEFAULT_CATALOG.with_file(path)`
is a catalog that also holds the Effect subclasses of a user's own Python file;
`catalog.make(spec)` builds an effect from a scenario's {"id": ..., <parameters>} table.
"""

from ph_explorer.effects.base import Effect, EffectSum, Evidence, Parameter
from ph_explorer.effects.catalog import BUILTIN_EFFECTS, DEFAULT_CATALOG, Catalog, load_user_effects

__all__ = ["BUILTIN_EFFECTS", "DEFAULT_CATALOG", "Catalog", "Effect", "EffectSum", "Evidence", "Parameter", "load_user_effects"]
