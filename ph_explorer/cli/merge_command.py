"""`ph-explorer merge BASE.csv NEW.csv --out ALL.csv [--replace] [--json]`: new rings appended to a campaign."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from ph_explorer.errors import InputError
from ph_explorer.io import checked_output_file, file_sha256, read_campaign, write_campaign
from ph_explorer.io.merge import merged_campaign


def merge_command(
    base: Path, new: Path, out: Path, replace: bool = False, json_output: bool = False, geometry: dict[str, Any] | None = None
) -> int:
    """Check, merge and write (io.merge); nothing is written when anything is refused."""
    resolved = {p.resolve() for p in (base, new)}
    if out.resolve() in resolved:
        raise InputError("must name a new file: the merge never writes over its inputs", option="--out")
    out = checked_output_file(out, "--out", "the merged campaign", "all.csv")
    merged, record = merged_campaign(read_campaign(base, geometry), read_campaign(new, geometry), replace, file_sha256(base))
    write_campaign(merged, out)
    summary = {
        "out": str(out),
        "rings": merged.n_orientations,
        "added": len(record["added"]),
        "replaced": len(record["replaced"]),
        "time_offset_s": record["time_offset_s"],
    }
    if json_output:
        print(json.dumps(summary, allow_nan=False))
    else:
        offset = "" if record["time_offset_s"] is None else f"; its touch times moved by {record['time_offset_s']:+.3f} s"
        print(
            f"{out}: {merged.n_orientations} rings, {len(record['added'])} added from {new} "
            f"({len(record['replaced'])} of {base} replaced){offset}"
        )
    return 0
