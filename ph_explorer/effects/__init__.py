"""The catalog of physical effects of the PH20/TP20 head-touch twin (see effects/effect.py).

`DEFAULT_CATALOG` maps each built-in effect id to its class; `DEFAULT_CATALOG.with_file(path)`
is a catalog that also holds the Effect subclasses of a user's own Python file;
`catalog.make(spec)` builds an effect from a scenario's {"id": ..., <parameters>} table.

Every effect says where it sits (`axis`: "A", "B", "probe", "ring", "environment" or None), what
kind of error it is (`kind`, one of effect.KINDS) and its ISO 230-1 style `symbol`. For the rotary
axes the symbols follow ISO 230-1 adapted to the head: an error motion is E + direction + axis, a
location error direction + O + axis (O for the standard's zero), with X, Y, Z for translations and
A, B, C for rotations about x, y, z of the frame the axis sits in. B sits in the machine frame
(turns about z): EXB, EYB radial, EZB axial, EAB, EBB tilt, ECB angular positioning; XOB, YOB the
position of its line, AOB, BOB its tilt from z. A sits in the frame carried by B (turns about its
x): EYA, EZA radial, EXA axial, EBA, ECA tilt, EAA angular positioning; YOA, ZOA the position of
its line, BOA its squareness to B. Each is read at every touch through the small-displacement
screw of its axis (effect.screw_deviation); location errors in effects/location.py, error motions
in effects/motions.py (the cyclic angular errors of effects/axes.py are their angular positioning
members).
"""

from ph_explorer.effects.catalog import BUILTIN_EFFECTS, DEFAULT_CATALOG, Catalog, load_user_effects
from ph_explorer.effects.effect import Effect, EffectSum, Evidence, Parameter, effect_label

__all__ = [
    "BUILTIN_EFFECTS",
    "DEFAULT_CATALOG",
    "Catalog",
    "Effect",
    "EffectSum",
    "Evidence",
    "Parameter",
    "effect_label",
    "load_user_effects",
]
