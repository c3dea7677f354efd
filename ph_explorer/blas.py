"""One BLAS thread for the diagnosis's many small products.

The diagnosis and the identifiability of a design make thousands of products of a few basis
columns with a few dozen targets over every ring's points: each far too small for a BLAS thread
pool to pay for itself. On 2 busy cores OpenBLAS's own threads then spin against each other (and,
once torch has run in the same process, against its OpenMP pool: a diagnosis in the explorer took
600 s instead of 25 s); measured, one BLAS thread makes these products 10-25 times faster. The
parallelism that pays is independent parts of one diagnosis two at a time, in threads (numpy
releases the GIL in the heavy parts): the nested cross-validation's folds, the shape groups.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable)

PARTS_AT_ONCE = 2  # a diagnosis's independent parts fitted at a time (the machine's 2 cores)


def one_blas_thread(function: F) -> F:
    """Run the function with BLAS limited to one thread (restored after it returns or raises)."""
    return threadpool_limits.wrap(limits=1, user_api="blas")(function)
