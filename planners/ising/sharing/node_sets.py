"""Node sets of the compiled Ising target sharing: sorted node arrays interned in a pool.

A set is an ``int64`` id into a pool of one world (``R`` robots): its sorted nodes are stored
back to back in one arena, and a table holds per id the start in the arena, the size, the robot
count (nodes ``< R``), the next id with the same hash (-1: none) and the id of its targets (-1:
not yet known); a dict maps a set's hash (XOR of a splitmix64 of each node) to the first id with
that hash, another the unions made so far.  Equal sets get the same id, so ids compare, key memos
and fill tables as the sets would, in worlds of any size.  Id :data:`EMPTY` is the empty set.
Arrays handed out are views of the arena: callers never write to them.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.typed import Dict, List

__all__ = ["EMPTY", "new_pool", "intern", "nodes_of", "size", "sizes_of", "union", "robots_in", "targets_of",
           "contains"]

EMPTY = 0
_PAIR = types.UniTuple(types.int64, 2)
START, SIZE, ROBOTS, CHAIN, TARGETS = range(5)  # columns of the table


@numba.njit(cache=True, inline="always")
def _mix(x):
    z = x + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


@numba.njit(cache=True)
def intern(pool, nodes):
    """The id of the sorted, distinct ``nodes`` (a new id, the nodes copied in, when first met)."""
    arena_of, index, table_of, _unions, R, count = pool
    n = nodes.shape[0]
    h = np.uint64(0)
    for v in nodes:
        h ^= _mix(np.uint64(v))
    new = count[0]
    table = table_of[0]
    arena = arena_of[0]
    if h in index:
        i = index[h]
        while True:
            if table[i, SIZE] == n:
                start = table[i, START]
                same = True
                for k in range(n):
                    if arena[start + k] != nodes[k]:
                        same = False
                        break
                if same:
                    return i
            if table[i, CHAIN] < 0:
                break
            i = table[i, CHAIN]
        table[i, CHAIN] = new
    else:
        index[h] = new
    if new >= table.shape[0]:
        grown = np.empty((2 * table.shape[0], 5), dtype=np.int64)
        grown[:new] = table[:new]
        table_of[0] = grown
        table = grown
    used = count[1]
    if used + n > arena.shape[0]:
        more = np.empty(max(2 * arena.shape[0], used + n), dtype=np.int64)
        more[:used] = arena[:used]
        arena_of[0] = more
        arena = more
    arena[used:used + n] = nodes
    table[new, START] = used
    table[new, SIZE] = n
    table[new, ROBOTS] = np.searchsorted(nodes, R)
    table[new, CHAIN] = -1
    table[new, TARGETS] = -1
    count[0] += 1
    count[1] += n
    return new


@numba.njit(cache=True)
def new_pool(R):
    """An empty pool holding :data:`EMPTY`, for a world of ``R`` robots."""
    arena = List.empty_list(types.int64[::1])
    arena.append(np.empty(1024, dtype=np.int64))
    table = List.empty_list(types.int64[:, ::1])
    table.append(np.empty((128, 5), dtype=np.int64))
    pool = (arena, Dict.empty(key_type=types.uint64, value_type=types.int64), table,
            Dict.empty(key_type=_PAIR, value_type=types.int64), np.int64(R), np.zeros(2, dtype=np.int64))
    intern(pool, np.zeros(0, dtype=np.int64))
    return pool


@numba.njit(cache=True, inline="always")
def nodes_of(pool, s):
    row = pool[2][0][s]
    return pool[0][0][row[START]:row[START] + row[SIZE]]


@numba.njit(cache=True, inline="always")
def size(pool, s):
    return pool[2][0][s, SIZE]


@numba.njit(cache=True, inline="always")
def sizes_of(pool):
    """The table (columns :data:`SIZE`, :data:`ROBOTS`, ...) of every set so far; read it before the
    next :func:`intern`, which may grow it."""
    return pool[2][0]


@numba.njit(cache=True)
def union(pool, a, b):
    """The id of the union of sets ``a`` and ``b``."""
    if a == b or b == EMPTY:
        return a
    if a == EMPTY:
        return b
    key = (min(a, b), max(a, b))
    unions = pool[3]
    if key in unions:
        return unions[key]
    x, y = nodes_of(pool, a), nodes_of(pool, b)
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
    return pool[2][0][s, ROBOTS]


@numba.njit(cache=True)
def targets_of(pool, s, R):
    """The id of set ``s`` without its robots."""
    t = pool[2][0][s, TARGETS]
    if t < 0:
        r = pool[2][0][s, ROBOTS]
        t = s if r == 0 else intern(pool, nodes_of(pool, s)[r:])
        pool[2][0][s, TARGETS] = t
    return t


@numba.njit(cache=True)
def contains(pool, s, v):
    x = nodes_of(pool, s)
    i = np.searchsorted(x, v)
    return i < x.shape[0] and x[i] == v
