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
# instead of one of them trailing at the end. Each file is one unit (its module fixtures made once),
# except tests that name a group of their own (the quick benchmark's groups, each a unit). Measured
# on 2026-11-28 (`--durations`, 2 workers): test_diagnosis.py about 150 s in all, the quick groups
# 47-103 s, the two browser walks 67-76 s, test_training.py about 80 s.
LONGEST = (
    "test_diagnosis.py",
    "quick_hidden_effects",
    "quick_diagnoses",
    "test_training.py",
    "quick_data_efficiency",
    "test_browser_loop.py",
    "test_browser_decide.py",
    "quick_speed",
    "quick_large_campaign",
    "quick_fleet",
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
