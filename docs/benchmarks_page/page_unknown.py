"""The benchmarks page's `## Effects no catalog holds` section (`population_unknown`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import num, pct, share_of, table

UNKNOWN_INTRO = """\
## Effects no catalog holds

`population_unknown` (issue 55): random heads, each holding one shape of a family no catalog holds
([the families and their distributions](methods/random_heads.md#unknown-shapes)), sized by what it
does to the check rings (1 to 3 noise floors), diagnosed as a user would. **none**: the verdict
says the campaign is within noise, the shape unseen; **catalog name**: `missing` with a catalog
effect named for the unknown part (beside a hidden catalog effect: a claim that names it, itself or
as an untold partner, is that effect's); **other mechanism**: of those, the heads where a claim is not
the shape's own mechanism either (its axis's angular positioning at a period within 1 cycle/rev of
one the shape has on the turn, itself or an untold partner, or its seat's lobing for a probe that
changes: what the catalog can say of a non-integer, drifting or coupled period); **honest**: `unexplained`, `partial` or `suggested`; **silent
none**: `none` with no ring named as measured badly and no touch outliers named either; **ring
named**: a ring named as measured badly ([suspect rings](methods/suspect_rings.md)); **outliers
named**: touch outliers named. Each share with its 95 % interval; the
check rings' error over their floor is what a user sees. The targets (none at most {none_max}, a
catalog name at most {name_max}, a bad ring named on at least {bad_min} of its heads) are those of
issue 55.

**Shapes** ([what no catalog holds](methods/shapes.md), issue 56): **shape right**: a shape claimed
on the group that holds the head's shape (its axis's angular positioning; the probe's lobes in time
for a probe that changes), or with that group among those the rings cannot tell, over the heads
whose shape a group holds; **shape wrong**: a shape claimed that does not hold it (any shape on a
bad-ring or outlier head); **after the shape**: of the heads with a shape claimed, the share whose
check rings' MAE (against the mean) is within {after} of their floor once it is added, and the
median check rings / floor before and after; **same head without it**: those heads again without
their shape, diagnosed alike: the share within {after} of their floor (what the share before can
reach at best: the background's interpolation error stays) and their median; **after, within the
head's own**: the share whose check rings once the shape is added are within {after} of that
head's own without it; **right group**: the same share once the truth's own group of error
functions (at the search's knots and penalty) is added beside the chain instead of the shape
claimed, and its median check rings / floor over every head a group holds
(benchmarks/shape_oracle.py): what a shape brings with no choice among groups to make; **oracle passes**: the head's own shape, its function known exactly and its
size free, fitted beside the chain, passes the shapes' replication test over rings
(benchmarks/shape_oracle.py): where it does not, no shape search over these rings can replicate
that shape (a function of the A joint shows only at rings off the lattice's A rows,
[the physics](physics.md), section 6); **right where it passes**: shape right over those heads.
"""


def unknown(results: Mapping[str, Any]) -> str:
    u = results.get("population_unknown", {})
    targets = u.get("targets") or {}

    groups = [("all", u.get("all") or {}), *(u.get("by_family") or {}).items()]
    rows = [[family, *(share_of(s.get(key)) for key in KEYS), num(s.get("check_ratio_median"))] for family, s in groups]
    shape_rows = [
        [
            family,
            share_of(s.get("shape_right")),
            share_of(s.get("shape_wrong")),
            share_of(s.get("after_shape_within")),
            f"{num(s.get('before_ratio_median_where_claimed'))} -> {num(s.get('after_shape_ratio_median'))}",
            f"{share_of(s.get('plain_within'))}, {num(s.get('plain_ratio_median'))}",
            share_of(s.get("after_shape_within_plain")),
            f"{share_of(s.get('right_group_within_plain'))}, {num(s.get('right_group_ratio_median'))}",
            share_of(s.get("oracle_passes")),
            share_of(s.get("shape_right_where_oracle_passes")),
        ]
        for family, s in groups
        if "shape_right" in s
    ]
    intro = UNKNOWN_INTRO.format(
        none_max=pct(targets.get("none_max")),
        name_max=pct(targets.get("catalog_name_max")),
        bad_min=pct(targets.get("bad_ring_named_min")),
        after=f"{targets.get('after_shape_within', 1.25)}x",
    )
    head = [
        "family",
        "none",
        "catalog name",
        "other mechanism",
        "honest",
        "silent none",
        "ring named",
        "outliers named",
        "check rings / floor (median)",
    ]
    shapes = [
        "family",
        "shape right",
        "shape wrong",
        "after the shape, within",
        "check rings / floor where claimed",
        "same head without it: within, median",
        "after, within the head's own",
        "right group: within the head's own, median",
        "oracle passes",
        "right where it passes",
    ]
    return (
        intro
        + f"\n{num(u.get('heads'))} heads, commit {u.get('commit')}, {num(u.get('run_seconds'), 's')}.\n\n"
        + table(head, rows)
        + ("\n" + table(shapes, shape_rows) if shape_rows else "")
        + axis_text(u)
        + suspect_text(u)
        + multi_text(u)
    )


KEYS = ("none", "catalog_name", "catalog_name_other_mechanism", "honest", "none_silent", "suspect_named", "outliers_named")


def axis_text(u: Mapping[str, Any]) -> str:
    """Shapes right and the oracle, by the shape's axis (A, B, the probe)."""
    by_axis = u.get("by_axis") or {}
    if not by_axis:
        return ""
    parts = [
        f"{axis}: right {share_of(s.get('shape_right'))}, oracle passes {share_of(s.get('oracle_passes'))}, "
        f"right where it passes {share_of(s.get('shape_right_where_oracle_passes'))}"
        for axis, s in by_axis.items()
    ]
    return "\n**By the shape's axis**: " + "; ".join(parts) + ".\n"


def multi_text(u: Mapping[str, Any]) -> str:
    """Heads with several catalog effects at once: every effect found, by kind."""
    multi = u.get("multi_effect") or {}
    if not multi:
        return ""
    kinds = ", ".join(f"{kind} {share_of(r)}" for kind, r in (multi.get("by_kind") or {}).items())
    return (
        f"\n**Several catalog effects at once** ({num(multi.get('heads'))} heads, two or three effects each, or two settings of one "
        f"axis error; benchmarks/multi_effects.py): every effect claimed on {share_of(multi.get('all_found'))} "
        f"(target at least {pct((u.get('targets') or {}).get('multi_all_found_min'))}; as catalog-effect heads are judged: at its "
        f"settings or at settings the claim cannot exclude, or as an untold pair that names it at its settings; with its own id and settings "
        f"exactly: {share_of(multi.get('all_found_exactly'))}); by kind: {kinds}; of all their effects, "
        f"{share_of(multi.get('each_effect_found'))} claimed."
        + (
            f" The bound (benchmarks/shape_oracle.py): every effect, at its own settings beside the others, passes the claims' "
            f"replication test by ring on {share_of(multi['oracle_passes'])}, and every effect is claimed on "
            f"{share_of(multi.get('all_found_where_oracle_passes'))} of those."
            if multi.get("oracle_passes")
            else ""
        )
        + "\n"
    )


def suspect_text(u: Mapping[str, Any]) -> str:
    """The bad-ring heads' rings named, and the suspect test's calibration heads (diagnosis.suspect)."""
    calibration = u.get("suspect_calibration") or {}
    used = str((calibration.get("used") or {}).get("alone"))
    return (
        f"\nA badly measured ring named on its head: {share_of(u.get('bad_ring_named'))} (its family's heads and as many more); "
        f"of those whose bad ring is not a check ring: {share_of(u.get('bad_ring_named_on_lattice'))}. "
        f"The suspect test's own calibration heads (seeds {calibration.get('healthy_seeds')} healthy, "
        f"{calibration.get('bad_ring_seeds')} with a bad ring, {num(calibration.get('bad_check_rings'))} of them on a check ring): a ring named on healthy heads {share_of((calibration.get('healthy_named') or {}).get(used))}, "
        f"the bad ring named {share_of((calibration.get('bad_ring_named') or {}).get(used))}.\n"
    )
