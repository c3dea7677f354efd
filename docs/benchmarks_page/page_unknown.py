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
effect named for the unknown part; **honest**: `unexplained`, `partial` or `suggested`. Each share
with its 95 % interval; the check rings' error over their floor is what a user sees. The targets
(none at most {none_max}, a catalog name at most {name_max}) are those of issue 55, not yet met.
"""


def unknown(results: Mapping[str, Any]) -> str:
    u = results.get("population_unknown", {})
    targets = u.get("targets") or {}

    rows = [
        [family, share_of(s.get("none")), share_of(s.get("catalog_name")), share_of(s.get("honest")), num(s.get("check_ratio_median"))]
        for family, s in [("all", u.get("all") or {}), *(u.get("by_family") or {}).items()]
    ]
    intro = UNKNOWN_INTRO.format(none_max=pct(targets.get("none_max")), name_max=pct(targets.get("catalog_name_max")))
    head = ["family", "none", "catalog name", "honest", "check rings / floor (median)"]
    return (
        intro + f"\n{num(u.get('heads'))} heads, commit {u.get('commit')}, {num(u.get('run_seconds'), 's')}.\n\n" + table(head, rows) + "\n"
    )
