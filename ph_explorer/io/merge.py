"""Merging two campaigns of one head: a base and new rings measured after it (e.g. the rings that
would decide between two candidates), checked before anything is written.

The new rings must come from the same set-up (geometry, points per circle, repetitions) and the
same kind of file (touch times or none); their times are moved to begin after the base's last
touch, one of the base's own touch intervals later, so that time-dependent effects (drift) read
one campaign. An orientation measured in both is refused unless `replace` (the new ring then
replaces the base's ring). When the base names its check rings and the new file none, the new
rings off the lattice join them. Method: docs/methods/merging.md.
"""

from __future__ import annotations

from dataclasses import replace as with_fields
from typing import Any

import numpy as np

from ph_explorer.campaign import Campaign, orientation_label, orientation_match
from ph_explorer.errors import InputError
from ph_explorer.io.sidecar import GEOMETRY_KEYS


def merged_campaign(
    base: Campaign, new: Campaign, replace: bool = False, base_sha256: str | None = None
) -> tuple[Campaign, dict[str, Any]]:
    """(the merged campaign, what the merge did); InputError (naming NEW's file) when they conflict.
    base_sha256: the base file's, recorded so that a study made on it continues on the merge."""
    _check_compatible(base, new)
    same = orientation_match(base.orientations, new.orientations)  # (n_base, n_new)
    if same.any() and not replace:
        j = np.argwhere(same)[0, 1]
        raise InputError(
            f"{orientation_label(*new.orientations[j])} is already in {_named(base, 'the base campaign')}: "
            f"{int(same.any(axis=0).sum())} ring(s) measured twice; give --replace to let the new ones stand",
            file=new.source,
        )
    keep = ~same.any(axis=1)
    offset = _time_offset(base, new)
    times = None
    if base.times_s is not None and new.times_s is not None:
        times = np.concatenate([base.times_s[keep], new.times_s + offset])
    checks = _union(base.check_orientations, new.check_orientations)
    record = {
        "base": base.source,
        "base_sha256": base_sha256,
        "added_from": new.source,
        "added": [[float(a), float(b)] for a, b in new.orientations],
        "replaced": [[float(a), float(b)] for a, b in base.orientations[~keep]],
        "time_offset_s": None if times is None else round(float(offset), 3),
    }
    scenario = dict(base.scenario)
    scenario["merges"] = [*scenario.get("merges", []), record]
    out = with_fields(
        base,
        orientations=np.concatenate([base.orientations[keep], new.orientations]),
        deviations=np.concatenate([base.deviations[keep], new.deviations]),
        times_s=times,
        check_orientations=checks,
        scenario=scenario,
        source=None,
    )
    if new.check_orientations is None and base.check_orientations is not None:
        # The base names its check rings, the new file none: its rings off the lattice are held
        # out, as they would be in a campaign that names none (the rings that decide are tested there).
        added = np.arange(out.n_orientations) >= int(keep.sum())
        out.check_orientations = _union(checks, out.orientations[added & out.off_grid_mask()])
    return out, record


def _check_compatible(base: Campaign, new: Campaign) -> None:
    where = _named(base, "the base campaign")
    for key in GEOMETRY_KEYS:
        a, b = getattr(base.geometry, key), getattr(new.geometry, key)
        if not np.isclose(a, b, rtol=0.0, atol=1e-9):
            raise InputError(f"{key} is {b:g} here and {a:g} in {where}: not the same set-up", file=new.source)
    if new.n_points != base.n_points:
        raise InputError(f"{new.n_points} points per circle here and {base.n_points} in {where}", file=new.source)
    if new.n_repetitions != base.n_repetitions:
        raise InputError(
            f"{new.n_repetitions} repetitions here and {base.n_repetitions} in {where}: a campaign has one count per ring",
            file=new.source,
        )
    if (base.times_s is None) != (new.times_s is None):
        named = where, _named(new, "the new rings")
        has, lacks = named if new.times_s is None else named[::-1]
        raise InputError(f"{has} has touch times (t_s) and {lacks} has none: the merged campaign would hold half of them", file=new.source)


def _named(campaign: Campaign, otherwise: str) -> str:
    """The campaign's file, or what it is when it was made in memory (a merge, the twin's rings)."""
    return str(campaign.source) if campaign.source is not None else otherwise


def _time_offset(base: Campaign, new: Campaign) -> float:
    """What to add to the new touch times so that they begin after the base's last touch, one of
    the base's median touch intervals later (0 without times)."""
    if base.times_s is None or new.times_s is None:
        return 0.0
    steps = np.diff(np.sort(base.times_s.ravel()))
    interval = float(np.median(steps)) if steps.size else 0.0
    return float(base.times_s.max() + interval - new.times_s.min())


def _union(a: np.ndarray | None, b: np.ndarray | None) -> np.ndarray | None:
    """Both sets of check orientations (None when neither names any: the off-grid rings are used)."""
    if a is None and b is None:
        return None
    both = np.concatenate([x for x in (a, b) if x is not None])
    first = ~np.triu(orientation_match(both, both), k=1).any(axis=0)  # each orientation once
    return both[first]
