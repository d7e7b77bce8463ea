"""Node sets of the Ising target sharing: sorted node arrays interned in a pool, as integer ids.

Contract: a set is an ``int64`` id into a pool of one world; equal sets get the same id, so ids compare,
key memos and fill tables as the sets would, in worlds of any size.  Id :data:`EMPTY` is the empty set;
arrays handed out are views of the pool's arena, which callers never write to.
Design notes (layout, hashing): docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numba
import numpy as np
from numba import types
from numba.typed import List

from ising_backend import splitmix

__all__ = ["EMPTY", "new_pool", "intern", "nodes_of", "size", "union", "robots_in", "targets_of", "contains"]

EMPTY = 0
_ARENA, _TABLE, _COUNT, _HKEY, _HVAL, _UA, _UB, _UVAL = range(8)  # the pool's arrays
_START, _SIZE, _ROBOTS, _TARGETS = range(4)  # columns of the table, 4 entries per id
_SETS, _USED, _R, _HN, _UN = range(5)  # counts: ids, arena entries used, robots, hash entries, unions


@numba.njit(cache=True)
def _slot(keys, vals, key, start):
    """The slot of ``key`` in an open-addressing table (linear probing from ``start``), or of the first
    empty entry on its probe path (``vals == -1``)."""
    mask = keys.shape[0] - 1
    i = start & mask
    while vals[i] >= 0 and keys[i] != key:
        i = (i + 1) & mask
    return i


@numba.njit(cache=True)
def _grow_hash(pool):
    """Double the set-hash table (kept at most half full); entries re-inserted in slot order."""
    keys, vals = pool[_HKEY], pool[_HVAL]
    cap = 2 * keys.shape[0]
    k2 = np.zeros(cap, dtype=np.int64)
    v2 = np.full(cap, -1, dtype=np.int64)
    for i in range(keys.shape[0]):
        if vals[i] >= 0:
            j = _slot(k2, v2, keys[i], keys[i])
            k2[j] = keys[i]
            v2[j] = vals[i]
    pool[_HKEY] = k2
    pool[_HVAL] = v2


@numba.njit(cache=True)
def _find(pool, nodes, h):
    """The id of ``nodes`` (hash ``h``, as int64 bits) or -1, and the slot where it is or would go: ids
    with equal hashes sit in consecutive probe positions."""
    keys, vals = pool[_HKEY], pool[_HVAL]
    arena, table = pool[_ARENA], pool[_TABLE]
    n = nodes.shape[0]
    mask = keys.shape[0] - 1
    i = h & mask
    while vals[i] >= 0:
        if keys[i] == h:
            s = vals[i]
            if table[4 * s + _SIZE] == n:
                start = table[4 * s + _START]
                same = True
                for k in range(n):
                    if arena[start + k] != nodes[k]:
                        same = False
                        break
                if same:
                    return s, i
        i = (i + 1) & mask
    return -1, i


@numba.njit(cache=True)
def intern(pool, nodes):
    """The id of the sorted, distinct ``nodes`` (a new id, the nodes copied in, when first met)."""
    h = np.uint64(0)
    for v in nodes:
        h ^= splitmix(np.uint64(v))
    key = np.int64(h >> np.uint64(1))  # 63 bits: a non-negative int64 key
    found, slot = _find(pool, nodes, key)
    if found >= 0:
        return found
    count = pool[_COUNT]
    new = count[_SETS]
    n = nodes.shape[0]
    if 4 * (new + 1) > pool[_TABLE].shape[0]:
        grown = np.empty(2 * pool[_TABLE].shape[0], dtype=np.int64)
        grown[:4 * new] = pool[_TABLE][:4 * new]
        pool[_TABLE] = grown
    used = count[_USED]
    if used + n > pool[_ARENA].shape[0]:
        more = np.empty(max(2 * pool[_ARENA].shape[0], used + n), dtype=np.int64)
        more[:used] = pool[_ARENA][:used]
        pool[_ARENA] = more
    pool[_ARENA][used:used + n] = nodes
    table = pool[_TABLE]
    table[4 * new + _START] = used
    table[4 * new + _SIZE] = n
    table[4 * new + _ROBOTS] = np.searchsorted(nodes, count[_R])
    table[4 * new + _TARGETS] = -1
    pool[_HKEY][slot] = key
    pool[_HVAL][slot] = new
    count[_SETS] += 1
    count[_USED] += n
    count[_HN] += 1
    if 2 * count[_HN] > pool[_HKEY].shape[0]:
        _grow_hash(pool)
    return new


@numba.njit(cache=True)
def new_pool(R):
    """An empty pool holding :data:`EMPTY`, for a world of ``R`` robots."""
    pool = List.empty_list(types.int64[::1])
    pool.append(np.empty(1024, dtype=np.int64))  # arena
    pool.append(np.empty(4 * 128, dtype=np.int64))  # table
    pool.append(np.array([0, 0, R, 0, 0], dtype=np.int64))  # counts
    pool.append(np.zeros(256, dtype=np.int64))  # set hashes
    pool.append(np.full(256, -1, dtype=np.int64))
    pool.append(np.zeros(256, dtype=np.int64))  # unions: first id, second id, union
    pool.append(np.zeros(256, dtype=np.int64))
    pool.append(np.full(256, -1, dtype=np.int64))
    intern(pool, np.zeros(0, dtype=np.int64))
    return pool


@numba.njit(cache=True, inline="always")
def nodes_of(pool, s):
    start = pool[_TABLE][4 * s + _START]
    return pool[_ARENA][start:start + pool[_TABLE][4 * s + _SIZE]]


@numba.njit(cache=True, inline="always")
def size(pool, s):
    return pool[_TABLE][4 * s + _SIZE]


@numba.njit(cache=True, inline="always")
def robots_in(pool, s, R):
    """How many of set ``s``'s nodes are robots (nodes ``< R``, the pool's robot count)."""
    return pool[_TABLE][4 * s + _ROBOTS]


@numba.njit(cache=True)
def _union_slot(pool, a, b):
    """The slot of the union of ids ``a < b`` in the union table, found or empty."""
    ua, ub, uv = pool[_UA], pool[_UB], pool[_UVAL]
    mask = ua.shape[0] - 1
    i = np.int64(splitmix(np.uint64(a) * np.uint64(0x100000001B3) ^ np.uint64(b)) >> np.uint64(1)) & mask
    while uv[i] >= 0 and (ua[i] != a or ub[i] != b):
        i = (i + 1) & mask
    return i


@numba.njit(cache=True)
def _grow_unions(pool):
    """Double the union table (kept at most half full)."""
    ua, ub, uv = pool[_UA], pool[_UB], pool[_UVAL]
    cap = 2 * ua.shape[0]
    pool[_UA] = np.zeros(cap, dtype=np.int64)
    pool[_UB] = np.zeros(cap, dtype=np.int64)
    pool[_UVAL] = np.full(cap, -1, dtype=np.int64)
    for i in range(ua.shape[0]):
        if uv[i] >= 0:
            j = _union_slot(pool, ua[i], ub[i])
            pool[_UA][j] = ua[i]
            pool[_UB][j] = ub[i]
            pool[_UVAL][j] = uv[i]


@numba.njit(cache=True)
def union(pool, a, b):
    """The id of the union of sets ``a`` and ``b``."""
    if a == b or b == EMPTY:
        return a
    if a == EMPTY:
        return b
    lo, hi = min(a, b), max(a, b)
    slot = _union_slot(pool, lo, hi)
    if pool[_UVAL][slot] >= 0:
        return pool[_UVAL][slot]
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
    u = intern(pool, out[:n])  # interning never touches the union table: the slot is still free
    pool[_UA][slot] = lo
    pool[_UB][slot] = hi
    pool[_UVAL][slot] = u
    count = pool[_COUNT]
    count[_UN] += 1
    if 2 * count[_UN] > pool[_UA].shape[0]:
        _grow_unions(pool)
    return u


@numba.njit(cache=True)
def targets_of(pool, s, R):
    """The id of set ``s`` without its robots."""
    table = pool[_TABLE]
    t = table[4 * s + _TARGETS]
    if t < 0:
        r = table[4 * s + _ROBOTS]
        t = s if r == 0 else intern(pool, nodes_of(pool, s)[r:])
        pool[_TABLE][4 * s + _TARGETS] = t  # the table as it is after interning
    return t


@numba.njit(cache=True)
def contains(pool, s, v):
    x = nodes_of(pool, s)
    i = np.searchsorted(x, v)
    return i < x.shape[0] and x[i] == v
