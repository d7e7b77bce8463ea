"""The compiled binary min-heap of the searches and the matching: a 2-D int64 array, one entry a row, ordered by
its first ``nkey`` columns compared in turn (store ``-x`` for ``x`` descending); the other columns ride along.
``pop`` leaves the popped row at the heap's new size, where the caller reads it.  ``nkey`` and ``ncol`` (``push``:
the row tuple's length) are best literals at the call: the row swap then unrolls (flow A* took 30% longer without)."""

from __future__ import annotations

import numba
from numba import literal_unroll

__all__ = ["push", "pop"]


@numba.njit(cache=True, nogil=True)
def _before(heap, i, j, nkey) -> bool:
    """Row ``i`` pops before row ``j``."""
    for c in range(nkey):
        if heap[i, c] != heap[j, c]:
            return heap[i, c] < heap[j, c]
    return False


@numba.njit(cache=True, nogil=True)
def _swap(heap, i, j, ncol):
    for c in range(ncol):
        heap[i, c], heap[j, c] = heap[j, c], heap[i, c]


@numba.njit(cache=True, nogil=True)
def push(heap, size, row, nkey) -> int:
    """Add ``row`` (a tuple of integers, one per column) to the heap of ``size`` rows; returns the new size."""
    c = 0
    for x in literal_unroll(row):  # the tuple's items may differ in integer type
        heap[size, c] = x
        c += 1
    i = size
    while i > 0:
        q = (i - 1) >> 1
        if not _before(heap, i, q, nkey):
            break
        _swap(heap, i, q, len(row))
        i = q
    return size + 1


@numba.njit(cache=True, nogil=True)
def pop(heap, size, nkey, ncol) -> int:
    """Remove the first row (moved to index ``size - 1``); returns the new size.  ``ncol``: the heap's columns."""
    size -= 1
    _swap(heap, 0, size, ncol)
    i = 0
    while True:
        c = 2 * i + 1
        if c >= size:
            break
        if c + 1 < size and _before(heap, c + 1, c, nkey):
            c += 1
        if not _before(heap, c, i, nkey):
            break
        _swap(heap, i, c, ncol)
        i = c
    return size
