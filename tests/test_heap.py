"""planners.heap: pushes and pops against Python's heapq on the key columns; the other columns ride along."""

from __future__ import annotations

import heapq

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.heap import pop, push

_ROWS = st.tuples(st.integers(-3, 3), st.integers(-3, 3), st.integers(0, 9))


@settings(max_examples=200, deadline=None)
@given(ops=st.lists(st.one_of(st.none(), _ROWS), max_size=60), nkey=st.integers(1, 3))
def test_pops_follow_heapq_on_the_keys(ops, nkey):
    heap = np.zeros((len(ops), 3), dtype=np.int64)
    size, ref, live = 0, [], []
    for op in ops:  # None pops, a row pushes
        if op is not None:
            size = push(heap, size, op, nkey)
            heapq.heappush(ref, op[:nkey])
            live.append(op)
        elif size:
            size = pop(heap, size, nkey, 3)
            row = tuple(int(x) for x in heap[size])
            assert row[:nkey] == heapq.heappop(ref)
            live.remove(row)  # the popped row is one pushed and not popped yet, whole
    assert sorted(tuple(r) for r in heap[:size].tolist()) == sorted(live)
