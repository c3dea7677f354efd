"""The render scheduler of `ph-explorer serve`, as plain threading code (no viser, no numpy).

A browser's slider event returns at once; ONE render thread per app (`RenderQueue`) draws the
sessions' dirty states (`RenderState`) in the order they became dirty, each with its latest values,
and a state that moved again while drawn goes to the back; a state that may wait (what follows the
sliders) is drawn when no other waits, or once it has waited LATER_MAX_WAIT_S. `RenderStats` gathers
the render figures for benchmarks; `Following` draws what follows the sliders at most every so
often, after the renders the eye follows, and at their last values; `WhenResting` runs a slow
figure's job once a slider rests, never one per move.
Values set by scripts and tests are drawn in the caller's thread (`RenderState.render_now`).

Method: docs/methods/render_queue.md.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

from ph_explorer.app.background import Throttle

Clock = Callable[[], float]
TimedHook = Callable[[float, float], None]

# The longest a render that may wait (what follows the sliders: tables, charts, a following camera)
# waits while other sessions' renders of what the eye follows are queued (seconds): under a class's
# load it then lags by about this much rather than delaying every slider move.
LATER_MAX_WAIT_S = 1.0


class RenderState:
    """One session's render bookkeeping; all its flags are guarded by one condition.

    `render()` draws the session's latest values (it reads them itself, so requests only need to
    say "changed"). `clock` stamps events (time.time, as viser stamps a browser's updates) and
    `timer` measures renders; both can be injected to make latencies deterministic in tests.
    After every successful render `on_timed(render_s, latency_s)` is called (so an app can also
    aggregate the times of all its sessions), in the rendering thread, without any lock held.
    `later`: the render may wait for the others in the queue (RenderQueue).
    """

    def __init__(
        self,
        render: Callable[[], None],
        on_timed: TimedHook | None = None,
        clock: Clock = time.time,
        timer: Clock = time.perf_counter,
        later: bool = False,
    ) -> None:
        self.render = render
        self.later = later
        self.on_timed = on_timed
        self.clock = clock
        self.timer = timer
        self.render_count = 0  # successful renders
        self.render_times: deque[float] = deque(maxlen=10_000)  # seconds per render
        # Seconds from the oldest event a render drew to the end of that render (on `clock`).
        self.latency_times: deque[float] = deque(maxlen=10_000)
        self._cond = threading.Condition()  # notified whenever a render ends, and on close
        self._dirty = False  # values changed since a render last took them
        self._rendering = False  # a thread (the queue's or a caller) is drawing this state
        self._renderer: int | None = None  # that thread's ident
        self._since: float | None = None  # clock time of the oldest event not yet taken
        self._closed = False

    @property
    def idle(self) -> bool:
        """Nothing pending and nothing being drawn: the latest values are on screen."""
        with self._cond:
            return not (self._dirty or self._rendering)

    @property
    def needs_render(self) -> bool:
        """Dirty, open and nobody drawing it: the render queue must (still) hold it."""
        with self._cond:
            return self._dirty and not self._rendering and not self._closed

    def _mark(self, since: float | None) -> None:
        """Under _cond: values changed at `since`; the oldest pending event is what latency counts."""
        since = self.clock() if since is None else float(since)
        self._dirty = True
        if self._since is None or since < self._since:
            self._since = since

    def _take(self) -> float:
        """Under _cond: this thread starts drawing the latest values; returns since when they wait."""
        since = self._since if self._since is not None else self.clock()
        self._dirty, self._since = False, None
        self._rendering, self._renderer = True, threading.get_ident()
        return since

    def _release(self) -> None:
        """Under _cond: the render ended (drawn or failed); wake the waiters."""
        self._rendering, self._renderer = False, None
        self._cond.notify_all()

    def _timed(self, since: float) -> None:
        start = self.timer()
        self.render()
        render_s = self.timer() - start
        latency_s = max(0.0, self.clock() - since)
        self.render_count += 1  # only the thread holding _rendering gets here
        self.render_times.append(render_s)
        self.latency_times.append(latency_s)
        if self.on_timed is not None:
            self.on_timed(render_s, latency_s)

    def request(self, since: float | None = None) -> bool:
        """Values changed at `since` (default: now); never blocks on a render.

        Returns whether the caller must schedule this state on the render queue: not while a
        thread draws it (that thread renders again, or re-queues it at the back), not once closed.
        """
        with self._cond:
            if self._closed:
                return False
            self._mark(since)
            return not self._rendering

    def render_now(self, wait: bool = True, timeout: float = 30.0) -> bool:
        """Draw the latest values in this thread, looping until nothing is pending.

        If another thread is drawing this state: with `wait`, wait (up to `timeout`) for it to end,
        then draw what is still pending, so the caller returns with its values drawn; without
        `wait`, leave them to that thread. Returns whether the caller's values are drawn (False:
        left to another thread, timed out, or closed). A failed render raises here.
        """
        deadline = time.monotonic() + timeout
        with self._cond:
            if self._closed:
                return False
            self._mark(None)
            if self._renderer == threading.get_ident():
                return False  # called from inside this state's render: its renderer draws it next
            while self._rendering:
                remaining = deadline - time.monotonic()
                if not wait or remaining <= 0:
                    return False
                self._cond.wait(remaining)
            if self._closed:
                return False
            if not self._dirty:
                return True  # another thread took (and drew) these values meanwhile
            since = self._take()
        try:
            while True:
                self._timed(since)
                with self._cond:
                    if not self._dirty or self._closed:
                        self._release()
                        return True
                    since = self._take()
        except BaseException:
            with self._cond:
                self._release()
            raise

    def render_queued(self) -> bool:
        """The render thread's turn: draw the latest values once.

        Skips a state that is clean, closed or being drawn by another thread. Returns whether it
        moved again meanwhile and must go to the back of the queue. A failed render raises (its
        values are dropped); `needs_render` then says whether newer values wait.
        """
        with self._cond:
            if self._rendering or not self._dirty or self._closed:
                return False
            since = self._take()
        try:
            self._timed(since)
        finally:
            with self._cond:
                self._release()
                again = self._dirty and not self._closed
        return again

    def wait_rendered(self, timeout: float = 10.0) -> bool:
        """Wait until the latest values are drawn (or the state is closed); False on timeout."""
        with self._cond:
            return self._cond.wait_for(lambda: not (self._dirty or self._rendering), timeout)

    def close(self) -> None:
        """No more renders: pending values are dropped (a render in progress still ends)."""
        with self._cond:
            self._closed = True
            self._dirty, self._since = False, None
            self._cond.notify_all()


class RenderStats:
    """Render figures over many states (an app's sessions; benchmarks read them): seconds per
    render, seconds from the oldest event to the end of its render, successful and failed renders.

    `rendered` is a RenderState's `on_timed` hook; `failed` is called by whoever sees a render fail.
    """

    def __init__(self) -> None:
        self.render_times: deque[float] = deque(maxlen=10_000)
        self.latency_times: deque[float] = deque(maxlen=10_000)
        self.render_count = 0
        self.error_count = 0
        self.last_error: str | None = None
        self._lock = threading.Lock()  # renders end in the render thread and in callers' threads

    def rendered(self, render_s: float, latency_s: float) -> None:
        with self._lock:
            self.render_count += 1
            self.render_times.append(render_s)
            self.latency_times.append(latency_s)

    def failed(self, error: Exception) -> None:
        with self._lock:
            self.error_count += 1
            self.last_error = f"{type(error).__name__}: {error}"


class RenderQueue:
    """The app's single render thread and its FIFOs of dirty states, each queued at most once: the
    states that may wait (RenderState.later) are drawn when no other is queued, or once the first of
    them has waited `later_max_wait_s`."""

    def __init__(self, name: str = "ph-explorer-render", later_max_wait_s: float = LATER_MAX_WAIT_S) -> None:
        self._queue: deque[RenderState] = deque()
        self._later: deque[tuple[RenderState, float]] = deque()  # (state, time.monotonic() it was queued)
        self._queued: set[RenderState] = set()  # the states in either (identity)
        self.later_max_wait_s = later_max_wait_s
        self._cond = threading.Condition()
        self._stopping = False
        self._thread = threading.Thread(target=self._loop, name=name, daemon=True)
        self._thread.start()

    @property
    def thread(self) -> threading.Thread:
        return self._thread

    def request(self, state: RenderState, since: float | None = None) -> None:
        """A browser's event: mark `state` dirty and queue it if needed; returns at once."""
        if state.request(since):
            self.schedule(state)

    def schedule(self, state: RenderState) -> None:
        """Queue `state` at the back, unless it is queued already (it keeps its place) or stopped."""
        with self._cond:
            if self._stopping or state in self._queued:
                return
            self._queued.add(state)
            if state.later:
                self._later.append((state, time.monotonic()))
            else:
                self._queue.append(state)
            self._cond.notify()

    def _next(self) -> RenderState:
        """Under _cond, something queued: the next state to draw."""
        if self._later and (not self._queue or time.monotonic() - self._later[0][1] >= self.later_max_wait_s):
            return self._later.popleft()[0]
        return self._queue.popleft()

    def _loop(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._later and not self._stopping:
                    self._cond.wait()
                if self._stopping:
                    return
                state = self._next()
                self._queued.discard(state)
            try:
                again = state.render_queued()
            except Exception:  # one session's failed render must not stop the others'
                traceback.print_exc()
                again = state.needs_render
            if again:
                self.schedule(state)

    def stop(self, timeout: float = 10.0) -> bool:
        """End the thread after its current render (queued states are dropped); True once it ended."""
        with self._cond:
            self._stopping = True
            self._queue.clear()
            self._later.clear()
            self._queued.clear()
            self._cond.notify_all()
        if threading.current_thread() is not self._thread:
            self._thread.join(timeout)
        return not self._thread.is_alive()

    def __enter__(self) -> RenderQueue:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


class Following:
    """What follows a session's renders (a following camera, tables, charts): a render by the queue's
    thread leaves it to a catch-up render, which may wait for the renders the eye follows
    (RenderState.later) and draws it at the values drawn last, at most every `interval_s` (and once
    more when the interval has passed, so the last values get it); a render in another thread
    (go_to, a script) draws it at once.

    In a render, `due()` says whether that render draws it; `draw()` draws it at the values drawn
    last; `on_timed` times the catch-up renders that drew, as RenderState's does.
    """

    def __init__(self, draw: Callable[[], None], queue: RenderQueue, interval_s: float, on_timed: TimedHook | None = None) -> None:
        self.draw = draw
        self.queue = queue
        self.on_timed = on_timed
        self._drew = False  # whether the last catch-up render drew (one render thread: no lock)
        self.catch_up = RenderState(self._catch_up, on_timed=self._timed, later=True)
        self._throttle = Throttle(interval_s, lambda: queue.request(self.catch_up))

    def due(self) -> bool:
        if threading.current_thread() is not self.queue.thread:
            return True
        self.queue.request(self.catch_up)  # after the renders the eye follows (coalesced while queued)
        return False

    def _catch_up(self) -> None:
        self._drew = self._throttle.ready()  # not ready: drawn within the interval (the throttle asks again)
        if self._drew:
            self.draw()

    def _timed(self, render_s: float, latency_s: float) -> None:
        if self._drew and self.on_timed is not None:  # a turn that drew nothing is no catch-up render
            self.on_timed(render_s, latency_s)

    def wait_caught_up(self, timeout: float = 10.0) -> bool:
        """Wait until no catch-up is due or drawing (what follows shows the values drawn last); False on timeout."""
        deadline = time.monotonic() + timeout
        while self._throttle.armed or not self.catch_up.idle:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.005)  # the catch-up is a timer's call, then a render: no condition spans both
        return True

    def close(self) -> None:
        self._throttle.close()
        self.catch_up.close()


class WhenResting:
    """Run `job(*values)` on its own thread once the values asked for have not changed for `settle_s`.

    `want(*values)` only records them (one timer at a time, however often it is called); when the
    timer ends and the latest values are older than settle_s, the job runs with them, else the
    timer waits out the rest. The job itself checks whether its values are still current.
    """

    def __init__(self, job: Callable[..., None], settle_s: float, name: str = "when-resting") -> None:
        self.job = job
        self.settle_s = settle_s
        self._lock = threading.Lock()
        self._wanted: tuple[tuple[object, ...], float] | None = None  # (values, since when)
        self._timer: threading.Timer | None = None
        self._closed = False
        self._worker = ThreadPoolExecutor(max_workers=1, thread_name_prefix=name)

    def want(self, *values: object) -> None:
        with self._lock:
            if self._closed:
                return
            self._wanted = (values, time.monotonic())
            if self._timer is None:
                self._start(self.settle_s)

    def _start(self, delay: float) -> None:
        """Under _lock."""
        self._timer = threading.Timer(delay, self._rested)
        self._timer.daemon = True
        self._timer.start()

    def _rested(self) -> None:
        with self._lock:
            self._timer = None
            if self._wanted is None or self._closed:
                return
            values, since = self._wanted
            waited = time.monotonic() - since
            if waited < self.settle_s:  # changed again meanwhile: wait out the rest
                self._start(self.settle_s - waited)
                return
            self._wanted = None
            self._worker.submit(self.job, *values)

    def close(self) -> None:
        with self._lock:
            self._closed = True
            if self._timer is not None:
                self._timer.cancel()
            self._wanted = None
        self._worker.shutdown(wait=False, cancel_futures=True)
