"""The benchmarks page's `## A bigger campaign` section (`large_campaign`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import get, holds, num, table

LARGE_INTRO = """\
## A bigger campaign

`large_campaign`: the paper scenario at its size and a denser design, each command run through
the command line in its own process (interpreter and imports included; `serve` until it prints its
URL), its peak resident memory read from the kernel through `benchmarks/peak.py`, a launcher that
imports nothing (a process forked from the benchmark's own would carry the benchmark's high-water
mark). The growth exponent is log(dense / paper) of the figure over log(dense / paper) of the
touches: below 1, a command grows slower than the touches.
"""


def large_campaign(results: Mapping[str, Any]) -> str:
    lc = results.get("large_campaign", {})
    touches = lc.get("touches") or {}
    commands = list((lc.get("paper") or {}).keys())
    rows = []
    for c in commands:
        p, d, g = get(lc, "paper", c) or {}, get(lc, "dense", c) or {}, get(lc, "growth_exponent", c) or {}
        rows.append(
            [
                f"`{c}`",
                f"{num(p.get('seconds'))} / {num(p.get('peak_mib'))}",
                f"{num(d.get('seconds'))} / {num(d.get('peak_mib'))}",
                f"{num(g.get('seconds'))} / {num(g.get('peak_mib'))}",
                "yes" if p.get("ok", True) and d.get("ok", True) else "no",
            ]
        )
    t = lc.get("diagnosis_target") or {}
    return "\n".join(
        [
            LARGE_INTRO,
            f"Dense design: {lc.get('design', '')}. {lc.get('note', '')}.",
            "",
            table(
                [
                    "command",
                    f"paper ({num(touches.get('paper'))} touches): s / MiB",
                    f"dense ({num(touches.get('dense'))} touches): s / MiB",
                    "growth exponent (s / MiB)",
                    "ran",
                ],
                rows,
            ),
            f"`diagnose` on the dense design within {num(t.get('seconds'), 's')} and {num(t.get('peak_mib'), 'MiB')}: {holds(lc.get('diagnosis_holds'))}.",
            "",
        ]
    )
