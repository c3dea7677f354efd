"""Independent tasks on Dask's distributed scheduler: a fleet of campaigns, the benchmarks' many
diagnoses (docs/fleet.md).

One runner for all: a task gets a small input (a file's path, a seed), does its work on a worker
with one BLAS thread (the diagnosis's products are too small for a thread pool, and the workers
share the cores) and returns plain data. Without a scheduler address the tasks run on a
LocalCluster of single-threaded worker processes, one per core. Dask is imported only when a
client starts, so that importing this module costs nothing.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any

from ph_explorer.blas import one_blas_thread

if TYPE_CHECKING:
    from dask.distributed import Client


@dataclass
class TaskRun:
    """What a run of tasks gives back: each task's result in the order of its input, how many
    workers there were at the start, and how many of them were gone at the end (Dask ran what
    they held again on the others)."""

    results: list[Any]
    workers: int
    workers_lost: int


@contextlib.contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None, in_process: bool = False) -> Iterator[Client]:
    """A client of the scheduler at `scheduler` (tcp://HOST:PORT), else of a LocalCluster of
    `workers` single-threaded workers (default: one per core), closed on exit.

    in_process: the LocalCluster's workers are threads of this process (no start-up imports); for
    a few tasks, such as a smoke test's."""
    from dask.distributed import Client, LocalCluster

    if scheduler is not None:
        with Client(scheduler) as client:
            client.wait_for_workers(1)
            yield client
        return
    count = workers or os.cpu_count() or 1
    # No dashboard; the scheduler's own HTTP server (health routes) on a free port, not 8787, which
    # another cluster on this machine may hold.
    options = {"dashboard_address": None, "scheduler_kwargs": {"dashboard_address": ":0"}}
    with (
        LocalCluster(n_workers=count, threads_per_worker=1, processes=not in_process, **options) as cluster,
        Client(cluster) as client,
    ):
        yield client


def run_tasks(
    client: Client,
    function: Callable[..., Any],
    inputs: Sequence[Any],
    on_result: Callable[[Any], None] | None = None,
    **options: Any,
) -> TaskRun:
    """function(input, **options) for every input on the client's workers, one BLAS thread each;
    on_result(result) in this process as each one ends (in the order they end)."""
    from dask.distributed import as_completed

    workers = set(client.scheduler_info()["workers"])
    futures = client.map(partial(one_thread_task, function, options), list(inputs), pure=False)
    index = {future.key: i for i, future in enumerate(futures)}
    results: list[Any] = [None] * len(futures)
    for future in as_completed(futures):
        result = future.result()
        results[index[future.key]] = result
        if on_result is not None:
            on_result(result)
    lost = workers - set(client.scheduler_info()["workers"])
    return TaskRun(results, len(workers), len(lost))


def one_thread_task(function: Callable[..., Any], options: dict[str, Any], item: Any) -> Any:
    return one_blas_thread(function)(item, **options)
