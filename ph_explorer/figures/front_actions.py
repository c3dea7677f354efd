"""What each front end offers the user to do next, by what it does: the command line's commands and
the explorer's buttons, as the diagnosis's words name them (figures.diagnosis_text). A command
names the campaign's own file when the front knows it, else FILE.csv."""

from __future__ import annotations

import shlex
from typing import Literal

Front = Literal["command line", "explorer"]  # whose actions "what to do next" names (the report: the command line's)
NEXT_RINGS = "ph-explorer design --data FILE.csv --next"  # the adaptive campaign's next rings, from either front
ACTIONS: dict[Front, dict[str, str]] = {
    "command line": {
        "decide": "ph-explorer design --data FILE.csv --decide",
        "add": "add the effects found (diagnose --save STUDY adds them; --add ID adds your choice) and watch the check-ring error fall",
        "own": "--effects FILE.py",
        "next": NEXT_RINGS,
        "keep": "--export-shapes SHAPES.toml keeps it, for --effects SHAPES.toml",
    },
    "explorer": {
        "decide": "Rings that would decide, below",
        "add": "tick the effects found, then Refit the hybrid",
        "own": "an effect file of your own, loaded with serve --effects",
        "next": NEXT_RINGS,
        "keep": "Save study keeps it (serve --study)",
    },
}


def front_actions(front: Front, data_file: str | None = None) -> dict[str, str]:
    """The front end's actions, each command naming `data_file` (as a shell would read it) when given."""
    named = shlex.quote(data_file) if data_file else "FILE.csv"
    return {key: text.replace("FILE.csv", named) for key, text in ACTIONS[front].items()}
