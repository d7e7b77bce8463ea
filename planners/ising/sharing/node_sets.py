"""Node sets of the compiled Ising target sharing: sorted node arrays interned in a pool.

A set is an ``int64`` id into a pool ``(sets, index, chain, targets, unions)``: the sorted node
arrays, a dict from a set's hash (XOR of a splitmix64 of each node) to the first id with that
hash, for each id the next one with the same hash (-1: none) and the id of its targets (-1: not
yet known; one pool serves one world, so one robot count), and the unions made so far.  Equal sets get the same id, so ids compare,
key memos and fill tables as the sets would, in worlds of any size.  Id :data:`EMPTY` is the
empty set.  The pool keeps its own copy of an interned array; callers never write to the arrays
it hands out.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.typed import Dict, List

__all__ = ["EMPTY", "new_pool", "intern", "nodes_of", "size", "union", "robots_in", "targets_of", "contains"]

EMPTY = 0
_PAIR = types.UniTuple(types.int64, 2)


@numba.njit(cache=True, inline="always")
def _mix(x):
    z = x + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@numba.njit(cache=True)
def intern(pool, nodes):
    """The id of the sorted, distinct ``nodes`` (a new id, and a copy kept, when first met)."""
    sets, index, chain, targets, _unions, meta, R = pool
    h = np.uint64(0)
    for v in nodes:
        h ^= _mix(np.uint64(v))
    new = len(sets)
    if h in index:
        i = index[h]
        while True:
            s = sets[i]
            if s.shape[0] == nodes.shape[0] and (s == nodes).all():
                return i
            if chain[i] < 0:
                break
            i = chain[i]
        chain[i] = new
    else:
        index[h] = new
    sets.append(nodes.copy())
    chain.append(-1)
    targets.append(-1)
    m = meta[0]
    if new >= m.shape[0]:
        grown = np.zeros((2 * m.shape[0], 2), dtype=np.int64)
        grown[: m.shape[0]] = m
        meta[0] = grown
        m = grown
    m[new, 0] = nodes.shape[0]
    m[new, 1] = np.searchsorted(nodes, R)
    return new


@numba.njit(cache=True)
def new_pool(R):
    """An empty pool holding :data:`EMPTY`, for a world of ``R`` robots."""
    meta = List.empty_list(types.int64[:, ::1])
    meta.append(np.zeros((64, 2), dtype=np.int64))
    pool = (List.empty_list(types.int64[::1]), Dict.empty(key_type=types.uint64, value_type=types.int64),
            List.empty_list(types.int64), List.empty_list(types.int64),
            Dict.empty(key_type=_PAIR, value_type=types.int64), meta, np.int64(R))
    intern(pool, np.zeros(0, dtype=np.int64))
    return pool


@numba.njit(cache=True, inline="always")
def nodes_of(pool, s):
    return pool[0][s]


@numba.njit(cache=True, inline="always")
def size(pool, s):
    return pool[5][0][s, 0]


@numba.njit(cache=True, inline="always")
def sizes_of(pool):
    """``(n, 2)``: every set's size and robot count so far (read before the next :func:`intern`)."""
    return pool[5][0]


@numba.njit(cache=True)
def union(pool, a, b):
    """The id of the union of sets ``a`` and ``b``."""
    if a == b or b == EMPTY:
        return a
    if a == EMPTY:
        return b
    key = (min(a, b), max(a, b))
    unions = pool[4]
    if key in unions:
        return unions[key]
    x, y = pool[0][a], pool[0][b]
    out = np.empty(x.shape[0] + y.shape[0], dtype=np.int64)
    i = j = n = 0
    while i < x.shape[0] or j < y.shape[0]:
        if j == y.shape[0] or (i < x.shape[0] and x[i] < y[j]):
            out[n] = x[i]
            i += 1
        elif i == x.shape[0] or y[j] < x[i]:
            out[n] = y[j]
            j += 1
        else:
            out[n] = x[i]
            i += 1
            j += 1
        n += 1
    u = intern(pool, out[:n])
    unions[key] = u
    return u


@numba.njit(cache=True, inline="always")
def robots_in(pool, s, R):
    """How many of set ``s``'s nodes are robots (nodes ``< R``, the pool's robot count)."""
    return pool[5][0][s, 1]


@numba.njit(cache=True)
def targets_of(pool, s, R):
    """The id of set ``s`` without its robots."""
    t = pool[3][s]
    if t < 0:
        x = pool[0][s]
        r = np.searchsorted(x, R)
        t = s if r == 0 else intern(pool, x[r:])
        pool[3][s] = t
    return t


@numba.njit(cache=True)
def contains(pool, s, v):
    x = pool[0][s]
    i = np.searchsorted(x, v)
    return i < x.shape[0] and x[i] == v
