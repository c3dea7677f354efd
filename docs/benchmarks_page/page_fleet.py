"""The benchmarks page's `## Many heads` section (`fleet`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from .page_format import get, holds, num, table

FLEET_INTRO = """\
## Many heads

`fleet`: healthy random heads of the population, written as campaign files and diagnosed as
`ph-explorer diagnose --data 'heads/*.csv'` does ([Many heads](fleet.md)), on a Dask LocalCluster
of one single-threaded worker and then of two (cluster start-up included). The expected wall time
of the population calibration is its diagnoses times the mean seconds of one here, over the cores.
"""


def fleet(results: Mapping[str, Any]) -> str:
    f = results.get("fleet", {})
    seconds, each = f.get("seconds") or {}, f.get("seconds_per_diagnosis") or {}
    population = f.get("population_calibration") or {}
    rows = [
        ["campaigns", num(f.get("campaigns"))],
        ["wall, 1 worker / 2 workers", f"{num(seconds.get('one_worker'), 's')} / {num(seconds.get('two_workers'), 's')}"],
        [f"ratio (target <= {num(f.get('target_ratio'))})", f"{num(f.get('ratio'))}: {holds(f.get('holds'))}"],
        ["rows equal between the runs", holds(f.get("rows_equal"))],
        ["seconds per diagnosis: median / mean / max", f"{num(each.get('median'))} / {num(each.get('mean'))} / {num(each.get('max'))}"],
        ["a worker's peak memory", num(f.get("worker_peak_mib"), "MiB")],
        ["bytes a task sends / returns", f"{num(get(f, 'bytes_per_task', 'sent'))} / {num(get(f, 'bytes_per_task', 'returned'))}"],
    ]
    rows += [
        [f"population calibration ({num(population.get('diagnoses'))} diagnoses) on {n} cores", num(v, "s")]
        for n, v in (population.get("expected_wall_s") or {}).items()
    ]
    return FLEET_INTRO + "\n" + table(["figure", "value"], rows) + "\n"
