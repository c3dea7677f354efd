"""Test-wide settings.

One BLAS thread per process, as ph_explorer/__init__.py sets it for the CLI and the app: the core's
matrices are small, and threads that fight over two cores make it an order of magnitude slower.
Set here too because a test may import numpy before ph_explorer.
"""

import os

import pytest  # imports no numpy: the BLAS settings below still come first

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

# The longest work first, so that with one worker per core (pytest-xdist) the long units overlap
# instead of one of them trailing at the end: the quick benchmark's groups (test_benchmarks.py),
# then the files measured longest. Each file is one unit (its module fixtures made once), except
# tests that name a group of their own (the quick benchmark's groups, each a unit).
LONGEST = (
    "quick_diagnoses",
    "quick_hidden_effects",
    "quick_data_efficiency",
    "quick_large_campaign",
    "quick_speed",
    "test_browser_loop.py",
    "test_browser_decide.py",
    "quick_fleet",
    "test_diagnosis.py",
    "test_training.py",
)


def unit(item: pytest.Item) -> str:
    """The worker unit of a test: its own xdist_group, or else its file."""
    marker = item.get_closest_marker("xdist_group")
    return str(marker.args[0]) if marker else item.path.name


@pytest.hookimpl(tryfirst=True)  # before xdist's hook reads the groups
def pytest_collection_modifyitems(session, config, items):
    for item in items:
        if item.get_closest_marker("xdist_group") is None:
            item.add_marker(pytest.mark.xdist_group(item.path.name))
    rank = {name: i for i, name in enumerate(LONGEST)}
    items.sort(key=lambda item: rank.get(unit(item), len(LONGEST)))
