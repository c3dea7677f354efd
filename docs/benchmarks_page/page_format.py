"""The benchmarks page's formatting: figures, rates, intervals, tables and folded blocks, as every section writes them."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

Plots = Mapping[str, str]  # file name -> its path in the site, relative to benchmarks.md


def num(value: Any, unit: str = "") -> str:
    """A figure as the results file holds it: integers grouped by thousands, floats to 6 digits."""
    if value is None:
        return "-"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        text = f"{value:,}".replace(",", " ")
    elif isinstance(value, float):
        if math.isinf(value):
            text = "inf"
        elif abs(value) >= 1e5:
            text = f"{round(value):,}".replace(",", " ")
        else:
            text = f"{value:.6g}"
    else:
        text = str(value)
    return f"{text} {unit}".rstrip() if unit else text


def pct(value: Any) -> str:
    return "-" if value is None else f"{100 * value:.1f} %"


def interval(pair: Any, unit: str = "") -> str:
    if not pair or len(pair) != 2:
        return "-"
    return f"{num(pair[0])}-{num(pair[1])}{' ' + unit if unit else ''}"


def pct_interval(pair: Any) -> str:
    if not pair or len(pair) != 2:
        return "-"
    return f"{100 * pair[0]:.1f}-{100 * pair[1]:.1f} %"


def share_of(x: Any) -> str:
    """A rate of results.json ({"count", "of", "share", "ci95"}) as 'k of n: p % (interval)'."""
    x = x or {}
    return f"{num(x.get('count'))} of {num(x.get('of'))}: {pct(x.get('share'))} ({pct_interval(x.get('ci95'))})"


def holds(value: Any) -> str:
    if value is None:
        return "-"
    return "**holds**" if value else "**does not hold**"


def get(data: Any, *keys: Any) -> Any:
    """data[k0][k1]..., or None where a key is missing."""
    for key in keys:
        if isinstance(data, Mapping) and key in data:
            data = data[key]
        elif isinstance(data, list) and isinstance(key, int) and -len(data) <= key < len(data):
            data = data[key]
        else:
            return None
    return data


def cell(value: Any) -> str:
    text = value if isinstance(value, str) else num(value)
    return " ".join(text.split()).replace("|", "\\|")


def table(header: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def folded(title: str, body: str, kind: str = "warning") -> str:
    """A collapsed block (pymdownx.details): the answers a student should not read first."""
    indented = "\n".join(("    " + line) if line.strip() else "" for line in body.splitlines())
    return f'??? {kind} "{title}"\n\n{indented}\n'


def image(plots: Plots, name: str, alt: str) -> str:
    return f"![{alt}]({plots[name]})\n" if name in plots else ""


def joined(items: Any) -> str:
    return ", ".join(str(i) for i in items) if items else "none"
