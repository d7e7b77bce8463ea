"""The one route form of the move searches: open routes as linked lists over the nodes (compiled).

Nodes are the robots ``0..R-1``, then the targets; ``nxt[x]`` / ``prv[x]`` link each route (-1 past
the end; a robot has no predecessor).  :func:`walk` gives each node's robot and position (robot 0,
its first target 1, ...); edge ``p`` of a route joins positions ``p`` and ``p + 1``, and the open end
costs 0 (:func:`edge`).  The tour (one robot, node 0) and the fleet search hold their routes this
way; each move kind prices and applies itself on it (:mod:`.kinds`).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["walk", "route_cost", "edge", "unlink", "insert_after", "turn", "linked", "route_of"]


@numba.njit(cache=True)
def walk(nxt, r):
    """``(owner, pos, length)``: each node's robot and position, and each route's target count."""
    m = nxt.shape[0]
    owner = np.full(m, -1, dtype=np.int64)
    pos = np.zeros(m, dtype=np.int64)
    length = np.zeros(r, dtype=np.int64)
    for k in range(r):
        x, p = k, 0
        while x >= 0:
            owner[x] = k
            pos[x] = p
            p += 1
            x = nxt[x]
        length[k] = p - 1
    return owner, pos, length


@numba.njit(cache=True, inline="always")
def edge(d, a, b):
    """The cost of the edge ``a -> b``; 0 past the open end (``b < 0``)."""
    return 0.0 if b < 0 else d[a, b]


@numba.njit(cache=True)
def route_cost(d, nxt, r):
    total = 0.0
    for k in range(r):
        x = k
        while nxt[x] >= 0:
            total += d[x, nxt[x]]
            x = nxt[x]
    return total


@numba.njit(cache=True, inline="always")
def unlink(nxt, prv, a, b):
    """Take the segment ``a .. b`` (one node when ``a == b``) out of its route (its own links are left as
    they were)."""
    p, n = prv[a], nxt[b]
    nxt[p] = n
    if n >= 0:
        prv[n] = p


@numba.njit(cache=True, inline="always")
def insert_after(nxt, prv, a, b, x):
    """Put the segment ``a .. b`` (linked from ``a`` to ``b``; one node when ``a == b``) right after node ``x``."""
    w = nxt[x]
    nxt[x] = a
    prv[a] = x
    nxt[b] = w
    if w >= 0:
        prv[w] = b


@numba.njit(cache=True, inline="always")
def turn(nxt, prv, a, b):
    """Turn the links of the segment ``a .. b`` around (its ends' outer links are left to the caller)."""
    x = a
    while True:
        nx = nxt[x]
        nxt[x] = prv[x]
        prv[x] = nx
        if x == b:
            break
        x = nx


@numba.njit(cache=True)
def linked(route):
    """``(nxt, prv)`` of one robot's route ``route = [0, t_1, ..., t_n]`` (a permutation of ``0..n``)."""
    m = route.shape[0]
    nxt = np.full(m, -1, dtype=np.int64)
    prv = np.full(m, -1, dtype=np.int64)
    for i in range(m - 1):
        nxt[route[i]] = route[i + 1]
        prv[route[i + 1]] = route[i]
    return nxt, prv


@numba.njit(cache=True)
def route_of(nxt):
    """Robot 0's route as ``[0, t_1, ...]`` (every node on it)."""
    route = np.empty(nxt.shape[0], dtype=np.int64)
    x, p = 0, 0
    while x >= 0:
        route[p] = x
        p += 1
        x = nxt[x]
    return route[:p]
