"""Print the benchmarks page: `python docs/benchmarks_page` (or `python -m benchmarks_page` in docs/)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # docs/, where the package stands
sys.path.insert(1, str(Path(__file__).resolve().parent.parent.parent))  # the checkout: benchmarks.freshness

from benchmarks_page import PLOTS, RESULTS, load, render  # noqa: E402

print(render(load(), {name: f"img/benchmarks/{name}" for name in PLOTS if (RESULTS.parent / name).is_file()}))
