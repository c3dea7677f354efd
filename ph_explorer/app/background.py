"""Work beside the renders of `ph-explorer serve`, as plain threading code (no viser, no numpy).

* `Throttle`, one per costly part of a render (a following camera): at most every so often, and
  one call back once it may run again, so that the last values get it too;
* `Later`, one for every app: the delayed calls of every throttle on one daemon thread;
* `LatestFirst`, one per kind of background preparation (datasets' lattices): a job per object on
  one daemon thread, the latest asked first, skipping an object nobody holds any more; `stop`
  ends it before the process exits (a daemon thread inside torch when the interpreter finalises
  aborts the process: "terminate called without an active exception");
* `Foreground`, one for every app: work a user clicked for (a diagnosis, a refit) runs inside
  `running()`, and background work (lattices, the task's RONt) waits in `wait_idle()` between
  its pieces, so that a click is not shared with it on two cores and one GIL.
"""

from __future__ import annotations

import heapq
import threading
import time
import traceback
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any


class Throttle:
    """`ready()` is True at most once every `interval_s`; when it says False, `later()` is called
    once (on the Later thread) when it would say True, so that whoever asked can ask again."""

    def __init__(self, interval_s: float, later: Callable[[], None]) -> None:
        self.interval_s = interval_s
        self.later = later
        self._last = float("-inf")  # time.monotonic() of the last True
        self._armed = False  # a call of later() is scheduled
        self._closed = False
        self._lock = threading.Lock()

    def ready(self) -> bool:
        with self._lock:
            wait = self._last + self.interval_s - time.monotonic()
            if wait <= 0.0:
                self._last = time.monotonic()
                return True
            if not self._armed and not self._closed:
                self._armed = True
                LATER.call(wait, self._due)
            return False

    @property
    def armed(self) -> bool:
        """A call of later() is scheduled."""
        with self._lock:
            return self._armed

    def _due(self) -> None:
        with self._lock:
            self._armed = False
            if self._closed:
                return
        self.later()

    def close(self) -> None:
        with self._lock:
            self._closed = True


class _Worker:
    """One daemon thread running `_loop`, started by the first piece of work, woken by `_cond`."""

    def __init__(self, name: str) -> None:
        self.name = name
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None

    def _wake(self) -> None:
        """Start the thread if need be and wake it (call with `_cond` held, the work queued)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._loop, name=self.name, daemon=True)
            self._thread.start()
        self._cond.notify_all()  # the loop, and a `stop` waiting for it

    def _loop(self) -> None:
        raise NotImplementedError


class Later(_Worker):
    """Calls at given delays on one daemon thread (a thread per call, as threading.Timer starts,
    cost a render ~0.3 ms: starting a thread waits for it to run). Calls must be quick."""

    def __init__(self, name: str = "later") -> None:
        super().__init__(name)
        self._heap: list[tuple[float, int, Callable[[], None]]] = []
        self._count = 0

    def call(self, delay_s: float, fn: Callable[[], None]) -> None:
        with self._cond:
            self._count += 1
            heapq.heappush(self._heap, (time.monotonic() + delay_s, self._count, fn))
            self._wake()

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._heap or self._heap[0][0] > time.monotonic():
                    self._cond.wait(None if not self._heap else self._heap[0][0] - time.monotonic())
                fn = heapq.heappop(self._heap)[2]
            try:
                fn()
            except Exception:  # noqa: BLE001 - one failed call must not stop the others
                traceback.print_exc()


LATER = Later("ph-explorer-later")  # the delayed calls of every app (throttled cameras)


class Foreground:
    """How many clicked jobs run now; background work waits between its pieces while any does."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._running = 0

    @contextmanager
    def running(self) -> Iterator[None]:
        with self._cond:
            self._running += 1
        try:
            yield
        finally:
            with self._cond:
                self._running -= 1
                self._cond.notify_all()

    def wait_idle(self, give_up: Callable[[], bool] = lambda: False, poll_s: float = 0.25) -> None:
        """Return once no clicked job runs (or as soon as `give_up()` says True, asked every poll_s)."""
        with self._cond:
            while self._running and not give_up():
                self._cond.wait(poll_s)


FOREGROUND = Foreground()  # the clicked jobs of every app (sessions' diagnoses, refits, loads)


class LatestFirst(_Worker):
    """`job(obj)` for each object added, one at a time on a daemon thread, the latest added first.

    Only weak references are queued: an object dropped before its turn (a browser's data replaced
    again) is skipped. A failed job is printed; the others go on. A job that takes long should
    return soon after `stopping` is set.
    """

    def __init__(self, job: Callable[[Any], None], name: str = "latest-first") -> None:
        super().__init__(name)
        self.job = job
        self._waiting: list[weakref.ref[Any]] = []
        self._busy = False  # a job is running
        self.stopping = threading.Event()

    def add(self, obj: Any) -> None:
        with self._cond:
            if self.stopping.is_set():
                return
            self._waiting.append(weakref.ref(obj))
            self._wake()

    def should_stop(self) -> bool:
        """Asked by a job between its pieces: waits while a clicked job runs, then says whether to stop."""
        FOREGROUND.wait_idle(give_up=self.stopping.is_set)
        return self.stopping.is_set()

    def stop(self, timeout_s: float) -> bool:
        """Take no more jobs, drop the waiting ones and wait (at most timeout_s) for the running
        one to return; whether none runs any more. For the end of the process: nothing is taken after."""
        with self._cond:
            self.stopping.set()
            self._waiting.clear()
            return self._cond.wait_for(lambda: not self._busy, timeout_s)

    def _loop(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: bool(self._waiting))
                obj = self._waiting.pop()()
                self._busy = obj is not None
            if obj is not None:
                try:
                    self.job(obj)
                except Exception:  # noqa: BLE001 - that object stays unprepared
                    traceback.print_exc()
                del obj
                with self._cond:
                    self._busy = False
                    self._cond.notify_all()
