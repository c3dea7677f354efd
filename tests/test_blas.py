"""Independent parts of one diagnosis two at a time (ph_explorer.blas.in_parts)."""

from __future__ import annotations

import threading
import time

from ph_explorer.blas import PARTS_AT_ONCE, in_parts


def test_the_costliest_parts_begin_first_and_the_results_keep_the_items_order() -> None:
    """Given each part's cost, the costliest begin first (a long part begun last would leave a core
    idle at the end); the results come back in the items' order, whatever order they ran in."""
    began: list[int] = []
    lock = threading.Lock()

    def part(item: int) -> int:
        with lock:
            began.append(item)
        time.sleep(0.01)
        return item * item

    items = [3, 1, 4, 1, 5, 9, 2, 6]
    out = in_parts(part, items, cost=float)
    assert out == [item * item for item in items]
    assert sorted(began[:PARTS_AT_ONCE]) == sorted(items, reverse=True)[:PARTS_AT_ONCE][::-1]
    began.clear()
    assert in_parts(part, items) == [item * item for item in items] and sorted(began[:PARTS_AT_ONCE]) == sorted(items[:PARTS_AT_ONCE])
