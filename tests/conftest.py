"""Test-wide settings.

One BLAS thread per process, as the CLI sets it (ph_explorer/cli.py): the core's matrices are
small, and threads that fight over two cores make it an order of magnitude slower.
"""

import os

for _variable in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
