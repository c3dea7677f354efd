"""The benchmarks page, written from benchmarks/results.json: `python docs/benchmarks_page`.

Every figure on the page is read from the results file when the site is built; the prose says what
each section measures and why, and holds no measured number. docs/hooks.py puts the page into the
site as benchmarks.md, with the plots `python -m benchmarks` draws beside the results.

One module a section of the page (page_overview, page_efficiency, page_speed, page_scale,
page_calibration, page_population, page_deciding, page_hidden, page_coverage, page_large,
page_fleet, page_peers), their formatting in page_format; page_assemble puts them together.
"""

from .page_assemble import PLOTS, RESULTS, load, render
from .page_population import VERDICT_RATES_MARKER, verdict_rates

__all__ = ["PLOTS", "RESULTS", "VERDICT_RATES_MARKER", "load", "render", "verdict_rates"]
