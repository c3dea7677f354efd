"""The benchmarks page put together: the head, then each section of results.json in its order, then any
section the page has no layout for yet as key and value.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

from .page_adaptive import adaptive
from .page_calibration import calibration
from .page_coverage import coverage
from .page_deciding import deciding
from .page_efficiency import data_efficiency
from .page_fleet import fleet
from .page_format import Plots, num, table
from .page_hidden import hidden_effects
from .page_large import large_campaign
from .page_overview import overview
from .page_peers import peers
from .page_population import population
from .page_scale import scale
from .page_speed import speed
from .page_unknown import unknown

ROOT = Path(__file__).resolve().parent.parent.parent
RESULTS = ROOT / "benchmarks" / "results.json"
PLOTS = ("data_efficiency.png", "speed.png", "calibration.png", "peers.png", "adaptive.png")
METADATA = (
    "date",
    "mode",
    "commit",
    "machine",
    "total_seconds",
    "section_seconds",
    "updated",
    "data_efficiency_details",
    "target",
    "scale_100",
)


def flattened(data: Any, prefix: str = "") -> Iterable[tuple[str, Any]]:
    if isinstance(data, Mapping):
        for key, value in data.items():
            yield from flattened(value, f"{prefix}.{key}" if prefix else str(key))
    elif isinstance(data, list) and data and all(isinstance(v, (int, float, str, bool)) or v is None for v in data) and len(data) <= 12:
        yield prefix, ", ".join(num(v) for v in data)
    elif isinstance(data, list):
        for i, value in enumerate(data):
            yield from flattened(value, f"{prefix}[{i}]")
    else:
        yield prefix, data


def other_section(name: str, data: Any) -> str:
    """A section this page has no layout for yet: its figures as key and value."""
    return f"## {name}\n\n" + table(["key", "value"], list(flattened(data))) + "\n"


SECTIONS: dict[str, Callable[[Mapping[str, Any], Plots], str]] = {
    "data_efficiency": data_efficiency,
    "speed": speed,
    "scale": lambda r, p: scale(r),
    "diagnosis_calibration": calibration,
    "population": lambda r, p: population(r),
    "population_unknown": lambda r, p: unknown(r),
    "adaptive_campaign": adaptive,
    "deciding": lambda r, p: deciding(r),
    "hidden_effects": lambda r, p: hidden_effects(r),
    "uncertainty_coverage": lambda r, p: coverage(r),
    "large_campaign": lambda r, p: large_campaign(r),
    "fleet": lambda r, p: fleet(r),
    "peers": peers,
}


def render(results: Mapping[str, Any], plots: Plots) -> str:
    """The whole page: the run, the targets, then each section of results.json."""
    parts = [overview(results)]
    for name, write in SECTIONS.items():
        if name in results:
            parts.append(write(results, plots))
    for name, data in results.items():
        if name not in SECTIONS and name not in METADATA:
            parts.append(other_section(name, data))
    return "\n\n".join(parts) + "\n"


def load(path: Path = RESULTS) -> dict[str, Any]:
    return json.loads(path.read_text(encoding="utf-8"))
