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

import threading
from collections.abc import Callable, Iterable
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

from threadpoolctl import threadpool_limits

F = TypeVar("F", bound=Callable)
T = TypeVar("T")
R = TypeVar("R")

PARTS_AT_ONCE = 2  # a diagnosis's independent parts fitted at a time (the machine's 2 cores)
_LEAD = threading.local()  # set in a thread that stands in for the main one (stand_in_for_main)


def one_blas_thread(function: F) -> F:
    """Run the function with BLAS limited to one thread (restored after it returns or raises)."""
    return threadpool_limits.wrap(limits=1, user_api="blas")(function)


def parts_at_once() -> int:
    """PARTS_AT_ONCE from the main thread or one standing in for it; one from a thread already
    beside others (a nested fold's, a Dask task's), which would only contend for the same cores."""
    return PARTS_AT_ONCE if threading.current_thread() is threading.main_thread() or getattr(_LEAD, "lead", False) else 1


def stand_in_for_main() -> None:
    """Mark the calling thread as doing the main thread's part (a thread pool's initializer:
    diagnosis.loop's shapes looked for ahead, while the main thread searches on)."""
    _LEAD.lead = True


class Dropped(Exception):
    """The work a part belongs to was dropped before the part began (in_parts' stop)."""


def in_parts(
    function: Callable[[T], R],
    items: Iterable[T],
    stop: threading.Event | None = None,
    cost: Callable[[T], float] | None = None,
) -> list[R]:
    """The function of each item, in the items' order, as many at a time as parts_at_once allows
    (in the calling thread when one); stop: once set, each part not yet begun raises Dropped
    instead. cost: each part's expected cost; the costliest begin first, so that no long part
    begins last while the other core idles (the parts are independent: the results are the same)."""

    def part(item: T) -> R:
        if stop is not None and stop.is_set():
            raise Dropped
        return function(item)

    items = list(items)
    workers = parts_at_once()
    if workers == 1:
        return list(map(part, items))
    order = sorted(range(len(items)), key=lambda i: cost(items[i]), reverse=True) if cost is not None else list(range(len(items)))
    with ThreadPoolExecutor(max_workers=workers) as pool:
        done = dict(zip(order, pool.map(part, [items[i] for i in order])))
    return [done[i] for i in range(len(items))]
