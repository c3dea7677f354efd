"""Test-wide settings.

One BLAS thread per process, as ph_explorer/__init__.py sets it for the CLI and the app: the core's
matrices are small, and threads that fight over two cores make it an order of magnitude slower.
Set here too because a test may import numpy before ph_explorer.
"""

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

# The longest file first: with one worker per core (pytest-xdist, a file per worker) the quick run
# of every benchmark, about half the suite's time, then overlaps the rest instead of following it.
FIRST = ("test_benchmarks.py",)


def pytest_collection_modifyitems(session, config, items):
    items.sort(key=lambda item: item.path.name not in FIRST)
