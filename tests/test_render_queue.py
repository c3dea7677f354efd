"""The render scheduler (ph_explorer.app.render_queue) on its own: plain threads, no viser.

Renders are fake: each reads its session's current value and logs (name, value, thread). A test
that needs a render to be "in progress" holds it on an Event after it read its values, so the
order of events is forced by synchronisation, never by sleeping; waits have generous timeouts.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from ph_explorer.app.background import Throttle
from ph_explorer.app.render_queue import RenderQueue, RenderState, RenderStats

TIMEOUT = 10.0  # generous: only reached when a test fails


class Session:
    """A fake session: `value` is what its next render draws; `log` is shared between sessions."""

    def __init__(self, name: str, log: list[tuple[str, int, str]], **state_options: object) -> None:
        self.name, self.log, self.value = name, log, 0
        self.fail: Exception | None = None  # raised by the next render
        self.during: list = []  # callables run by the next render, after it read its value
        self._hold: tuple[threading.Event, threading.Event] | None = None
        self.state = RenderState(self.render, **state_options)  # type: ignore[arg-type]

    def hold(self) -> tuple[threading.Event, threading.Event]:
        """The next render sets `started` once it has read its value, then waits for `release`."""
        self._hold = (threading.Event(), threading.Event())
        return self._hold

    def held_render(self, queue: RenderQueue, value: int | None = None) -> threading.Event:
        """Queue a render (of `value`, if given) and wait until the render thread is inside it;
        returns the Event that releases it."""
        started, release = self.hold()
        if value is not None:
            self.value = value
        queue.request(self.state)
        assert started.wait(TIMEOUT)
        return release

    def render(self) -> None:
        value = self.value
        hold, self._hold = self._hold, None
        during, self.during = self.during, []
        if hold is not None:
            hold[0].set()
            assert hold[1].wait(TIMEOUT), "a held render was never released"
        for call in during:
            call()
        fail, self.fail = self.fail, None
        if fail is not None:
            raise fail
        self.log.append((self.name, value, threading.current_thread().name))

    def drawn(self) -> list[int]:
        return [value for name, value, _ in self.log if name == self.name]


@pytest.fixture
def log() -> list[tuple[str, int, str]]:
    return []


@pytest.fixture
def queue() -> Iterator[RenderQueue]:
    q = RenderQueue(name="test-render")
    yield q
    assert q.stop(timeout=TIMEOUT)


def drain(queue: RenderQueue, log: list) -> None:
    """Wait until every state queued so far was served (a sentinel queued last is drawn)."""
    sentinel = Session("sentinel", log)
    queue.request(sentinel.state)
    assert sentinel.state.wait_rendered(TIMEOUT)


def hold_queue(queue: RenderQueue, log: list) -> tuple[Session, threading.Event]:
    """Keep the render thread busy drawing a blocker; returns it and the Event that releases it."""
    blocker = Session("blocker", log)
    return blocker, blocker.held_render(queue)


def names(log: list) -> list[str]:
    return [name for name, _, _ in log if name != "sentinel"]


def test_moves_during_a_render_are_coalesced_and_the_latest_wins(queue: RenderQueue, log: list) -> None:
    a = Session("a", log)
    release = a.held_render(queue, 1)
    for value in range(2, 101):  # a browser dragging a slider while its first render runs
        a.value = value
        assert a.state.request() is False  # being drawn: its renderer re-queues it
    release.set()
    assert a.state.wait_rendered(TIMEOUT)
    drain(queue, log)
    assert a.drawn() == [1, 100]
    assert a.state.render_count == 2 and len(a.state.render_times) == 2


def test_moves_while_queued_are_coalesced(queue: RenderQueue, log: list) -> None:
    _, release = hold_queue(queue, log)
    a = Session("a", log)
    for value in range(1, 51):
        a.value = value
        queue.request(a.state)
    release.set()
    assert a.state.wait_rendered(TIMEOUT)
    drain(queue, log)
    assert a.drawn() == [50]


def test_oldest_dirty_session_first_and_a_queued_session_keeps_its_place(queue: RenderQueue, log: list) -> None:
    _, release = hold_queue(queue, log)
    c, a, b = Session("c", log), Session("a", log), Session("b", log)
    for session in (c, a, b, a, c):  # a and c move again while queued: they keep their place
        session.value += 1
        queue.request(session.state)
    release.set()
    drain(queue, log)
    assert names(log) == ["blocker", "c", "a", "b"]
    assert (c.drawn(), a.drawn(), b.drawn()) == ([2], [2], [1])


def test_a_session_that_moves_during_its_render_goes_to_the_back(queue: RenderQueue, log: list) -> None:
    a, b, c = Session("a", log), Session("b", log), Session("c", log)
    release = a.held_render(queue, 1)
    b.value = c.value = 1
    queue.request(b.state)
    queue.request(c.state)
    a.value = 2
    queue.request(a.state)  # a moved again while drawn: after b and c, not right away
    release.set()
    drain(queue, log)
    assert [(name, value) for name, value, _ in log if name != "sentinel"] == [("a", 1), ("b", 1), ("c", 1), ("a", 2)]


def test_a_session_moving_at_every_render_does_not_starve_the_others(queue: RenderQueue, log: list) -> None:
    a, b = Session("a", log), Session("b", log)
    moves = iter(range(2, 6))

    def move_again() -> None:  # a browser that sends a new value during each render of `a`
        value = next(moves, None)
        if value is not None:
            a.value = value
            a.during.append(move_again)
            queue.request(a.state)

    started, release = a.hold()
    a.during.append(move_again)
    queue.request(a.state)
    assert started.wait(TIMEOUT)
    queue.request(b.state)
    release.set()
    assert a.state.wait_rendered(TIMEOUT) and b.state.wait_rendered(TIMEOUT)
    drain(queue, log)
    assert names(log) == ["a", "b", "a", "a", "a", "a"]
    assert a.drawn() == [0, 2, 3, 4, 5]


def test_render_now_returns_once_its_values_are_drawn_even_during_a_queued_render(queue: RenderQueue, log: list) -> None:
    a = Session("a", log)
    release = a.held_render(queue, 1)
    done, result = threading.Event(), []

    def script() -> None:  # the server sets a value (go_to) while the render thread draws `a`
        a.value = 2
        result.append(a.state.render_now(wait=True, timeout=TIMEOUT))
        result.append(list(log))
        done.set()

    threading.Thread(target=script, name="script").start()
    assert not done.wait(0.2)  # it waits for the render of value 1 ...
    release.set()
    assert done.wait(TIMEOUT)
    drawn_ok, log_at_return = result
    assert drawn_ok is True
    # ... and returns with its value drawn (by itself, or by the render thread if it was quicker)
    assert [(n, v) for n, v, _ in log_at_return] == [("a", 1), ("a", 2)]
    drain(queue, log)
    assert a.state.render_count == 2  # the render thread did not draw it once more
    assert a.state.idle


def test_render_now_draws_in_the_callers_thread(log: list) -> None:
    a = Session("a", log)
    a.value = 7
    assert a.state.render_now() is True
    assert log == [("a", 7, threading.current_thread().name)]
    assert a.state.idle and a.state.render_count == 1


def test_render_now_without_wait_leaves_the_values_to_the_render_thread(queue: RenderQueue, log: list) -> None:
    a = Session("a", log)
    release = a.held_render(queue, 1)
    a.value = 2
    assert a.state.render_now(wait=False, timeout=TIMEOUT) is False  # returns at once
    assert a.drawn() == []
    release.set()
    assert a.state.wait_rendered(TIMEOUT)
    assert [(n, v, t) for n, v, t in log] == [("a", 1, "test-render"), ("a", 2, "test-render")]


def test_render_now_called_from_inside_its_own_render_does_not_deadlock(log: list) -> None:
    a = Session("a", log)
    inner: list[bool] = []
    a.during.append(lambda: inner.append(a.state.render_now(timeout=3.0)))
    start = time.monotonic()
    assert a.state.render_now() is True
    assert time.monotonic() - start < 2.0  # not the inner call's timeout
    assert inner == [False] and a.state.render_count == 2  # its loop drew the new values


def test_wait_rendered_times_out_while_a_render_is_held(queue: RenderQueue, log: list) -> None:
    a = Session("a", log)
    release = a.held_render(queue)
    assert a.state.wait_rendered(0.05) is False and not a.state.idle
    release.set()
    assert a.state.wait_rendered(TIMEOUT) is True and a.state.idle


def test_closed_sessions_are_not_rendered(queue: RenderQueue, log: list) -> None:
    _, release = hold_queue(queue, log)
    a = Session("a", log)
    queue.request(a.state)
    a.state.close()  # its browser left while it was queued
    release.set()
    drain(queue, log)
    assert a.drawn() == []
    assert a.state.request() is False and a.state.render_now() is False
    assert a.state.wait_rendered(TIMEOUT) and a.drawn() == []


def test_closing_during_a_render_lets_it_end_but_not_requeue(queue: RenderQueue, log: list) -> None:
    a = Session("a", log)
    release = a.held_render(queue, 1)
    a.value = 2
    queue.request(a.state)
    a.state.close()
    release.set()
    assert a.state.wait_rendered(TIMEOUT)
    drain(queue, log)
    assert a.drawn() == [1]


def test_a_failing_render_does_not_stop_the_thread(queue: RenderQueue, log: list, capfd: pytest.CaptureFixture) -> None:
    f, g = Session("f", log), Session("g", log)
    started, release = f.hold()
    f.fail = RuntimeError("boom in f")
    queue.request(f.state)
    assert started.wait(TIMEOUT)
    queue.request(g.state)
    f.value = 2
    queue.request(f.state)  # moved during the failing render: still drawn afterwards
    release.set()
    assert g.state.wait_rendered(TIMEOUT) and f.state.wait_rendered(TIMEOUT)
    drain(queue, log)
    assert names(log) == ["g", "f"] and f.drawn() == [2]  # its failed render drew nothing
    assert f.state.render_count == 1 and queue.thread.is_alive()
    assert "RuntimeError: boom in f" in capfd.readouterr().err


def test_render_now_raises_a_failed_render_and_recovers(log: list) -> None:
    a = Session("a", log)
    a.fail = ValueError("bad value")
    with pytest.raises(ValueError, match="bad value"):
        a.state.render_now()
    assert a.state.idle  # not stuck "rendering"
    a.value = 3
    assert a.state.render_now() is True and a.drawn() == [3]


def test_latency_runs_from_the_oldest_pending_event() -> None:
    now = [100.0]
    timed: list[tuple[float, float]] = []
    a = Session("a", [], clock=lambda: now[0], timer=lambda: now[0], on_timed=lambda r, lat: timed.append((r, lat)))
    a.during.append(lambda: now.__setitem__(0, 115.0))  # the render ends at 115, having started at 100
    for since in (10.0, 12.0, 11.0):  # browser events, stamped by their clock, not in order
        assert a.state.request(since=since) is True
    assert a.state.render_queued() is False  # no thread: the test plays the render thread
    assert timed == [(15.0, 105.0)]
    a.during.append(lambda: now.__setitem__(0, 116.0))
    a.state.request()  # stamped now (115): the pending time was reset by the last render
    assert a.state.render_queued() is False
    assert timed[-1] == (1.0, 1.0)
    assert list(a.state.latency_times) == [105.0, 1.0] and list(a.state.render_times) == [15.0, 1.0]


def test_render_queued_says_whether_to_requeue() -> None:
    a = Session("a", [])
    assert a.state.render_queued() is False and a.state.render_count == 0  # clean: nothing drawn
    a.state.request()
    a.during.append(lambda: a.state.request())  # moved during its render
    assert a.state.render_queued() is True and a.state.needs_render
    assert a.state.render_queued() is False and a.state.idle and a.state.render_count == 2


def test_stop_joins_the_thread_after_its_render_and_drops_the_queue(log: list) -> None:
    queue = RenderQueue(name="test-render")
    blocker, release = hold_queue(queue, log)
    a = Session("a", log)
    queue.request(a.state)
    assert queue.stop(timeout=0.05) is False  # still drawing the blocker
    release.set()
    queue.thread.join(TIMEOUT)
    assert not queue.thread.is_alive()
    assert names(log) == ["blocker"]  # `a` was dropped
    queue.request(a.state)  # no thread any more: ignored
    assert queue.stop() is True and names(log) == ["blocker"]


def test_stop_on_an_idle_queue_returns_once_the_thread_ended() -> None:
    with RenderQueue(name="test-render") as queue:
        assert queue.thread.is_alive()
    assert not queue.thread.is_alive()


def test_stats_gather_the_renders_of_every_state(queue: RenderQueue, log: list) -> None:
    stats = RenderStats()
    a = Session("a", log, on_timed=stats.rendered)
    b = Session("b", log, on_timed=stats.rendered)
    queue.request(a.state)
    queue.request(b.state)
    assert a.state.wait_rendered(TIMEOUT) and b.state.wait_rendered(TIMEOUT)
    b.fail = RuntimeError("boom")
    with pytest.raises(RuntimeError):
        b.state.render_now()
    stats.failed(RuntimeError("boom"))  # what the app does when it sees a render fail
    assert stats.render_count == 2 and len(stats.render_times) == len(stats.latency_times) == 2
    assert stats.error_count == 1 and stats.last_error == "RuntimeError: boom"


def test_when_resting_runs_once_with_the_latest_values_after_they_rest() -> None:
    from ph_explorer.app.render_queue import WhenResting

    ran: list[tuple] = []
    done = threading.Event()

    def job(*values: object) -> None:
        ran.append(values)
        done.set()

    resting = WhenResting(job, settle_s=0.2)
    start = time.monotonic()
    for k in range(20):  # a slider dragged for ~0.4 s: one want per move
        resting.want(float(k), -float(k))
        time.sleep(0.02)
    assert done.wait(5.0)
    assert ran == [(19.0, -19.0)] and time.monotonic() - start >= 0.2 + 19 * 0.02
    time.sleep(0.4)
    assert len(ran) == 1  # nothing more was asked: nothing more ran
    resting.want(1.0, 2.0)
    resting.close()  # closed before it rested: never runs
    time.sleep(0.4)
    assert len(ran) == 1


def test_throttle_allows_once_per_interval_and_calls_back_once_it_may() -> None:
    called = threading.Event()
    calls: list[float] = []

    def later() -> None:
        calls.append(time.monotonic())
        called.set()

    throttle = Throttle(0.2, later)
    start = time.monotonic()
    assert throttle.ready()  # the first time: at once
    assert not throttle.ready() and not throttle.ready()  # within the interval: refused, one call back armed
    assert called.wait(TIMEOUT)
    assert calls[0] - start >= 0.19 and len(calls) == 1
    assert throttle.ready()  # asked again when called back: allowed
    throttle.close()


def test_what_follows_is_drawn_at_most_once_per_interval_and_ends_at_the_last_values(queue: RenderQueue) -> None:
    """A drag of 40 moves in ~0.4 s: every move is drawn (coalesced), what follows at most every
    0.1 s plus the first, and once the drag ends, at the last value drawn; a render by another
    thread (a script's jump) draws what follows at once."""
    from ph_explorer.app.render_queue import Following

    drawn: list[int] = []  # the live values, in render order
    followed: list[tuple[int, float]] = []  # (the value what follows shows, when)
    value = [0]

    def follow() -> None:
        followed.append((drawn[-1], time.monotonic()))

    def render() -> None:
        drawn.append(value[0])
        if following.due():
            follow()

    following = Following(follow, queue, interval_s=0.1)
    state = RenderState(render)
    start = time.monotonic()
    for k in range(1, 41):
        value[0] = k
        queue.request(state)
        time.sleep(0.01)
    assert state.wait_rendered(TIMEOUT) and following.wait_caught_up(TIMEOUT)
    dragged = time.monotonic() - start
    assert drawn[-1] == 40 and followed[-1][0] == 40  # both end at the last move
    assert 2 <= len(followed) <= 2 + dragged / 0.1  # throttled, not once per move
    assert all(later - earlier >= 0.099 for (_, earlier), (_, later) in zip(followed, followed[1:]))
    value[0] = 99
    state.render_now()  # another thread: what follows at once, whatever the interval
    assert followed[-1][0] == 99 and following.wait_caught_up(0.0)
    following.close()


def test_a_catch_up_turn_that_draws_nothing_is_not_timed_as_a_catch_up_render(queue: RenderQueue) -> None:
    """A render by the queue's thread leaves what follows to a catch-up render; a catch-up turn that
    finds it drawn within the interval draws nothing, and is not timed (the benchmarks count and
    time the catch-up renders); one that draws is."""
    from ph_explorer.app.render_queue import Following

    drawn: list[str] = []
    timed: list[float] = []
    following = Following(lambda: drawn.append("catch-up"), queue, interval_s=1.0, on_timed=lambda render_s, _: timed.append(render_s))
    state = RenderState(lambda: following.due() and drawn.append("render"))
    queue.request(state)
    assert state.wait_rendered(TIMEOUT) and following.catch_up.wait_rendered(TIMEOUT)
    assert drawn == ["catch-up"] and len(timed) == 1  # the first render's catch-up draws what follows
    queue.request(following.catch_up)  # a turn within the interval: nothing to draw
    assert following.catch_up.wait_rendered(TIMEOUT) and drawn == ["catch-up"] and len(timed) == 1
    assert following.wait_caught_up(TIMEOUT)  # the interval over: the catch-up it asked for draws
    assert drawn == ["catch-up", "catch-up"] and len(timed) == 2
    following.close()


def test_a_render_that_may_wait_waits_for_the_others_up_to_its_longest_wait(log: list) -> None:
    """What follows the sliders waits while renders the eye follows are queued (a class's sliders
    first), but no longer than later_max_wait_s: then it goes before them."""
    queue = RenderQueue(name="test-render", later_max_wait_s=0.3)
    try:
        eye, follows = Session("eye", log), Session("follows", log, later=True)
        blocker, release = hold_queue(queue, log)
        queue.request(follows.state)
        queue.request(eye.state)
        release.set()
        assert eye.state.wait_rendered(TIMEOUT) and follows.state.wait_rendered(TIMEOUT)
        assert names(log) == ["blocker", "eye", "follows"]  # queued after it, drawn before it
        log.clear()
        blocker, release = hold_queue(queue, log)
        queue.request(follows.state)
        time.sleep(0.35)  # it has waited its longest
        queue.request(eye.state)
        release.set()
        assert eye.state.wait_rendered(TIMEOUT) and follows.state.wait_rendered(TIMEOUT)
        assert names(log) == ["blocker", "follows", "eye"]
    finally:
        assert queue.stop(timeout=TIMEOUT)
