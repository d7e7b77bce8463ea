"""Held-Karp dynamic programming over subsets: exact open routes (paper 6.1, the exact tour layer).

``_held_karp_dp`` fills the table ``dp[s, j]`` (cheapest open route from node 0 over the bitmask
``s`` ending at node ``j + 1``) in pull form over set bits; ``_held_karp`` reads the route back,
``_exact_route_cost`` prices a node list without a sub-matrix copy, ``_held_karp_subsets`` gives
every subset's optimum.  :class:`~planners.tours_classical.BruteTour` and the sharing layers'
exact bundle pricing use them.  Up to :data:`MAX_BRUTE_TARGETS` targets.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["MAX_BRUTE_TARGETS", "exact_route_cost"]

#: Largest target count :class:`~planners.tours_classical.BruteTour` accepts (2^13 x 13 DP states).
MAX_BRUTE_TARGETS = 13

# the lowest set bit of a positive int64 by a de Bruijn multiplication (portable, no compiler intrinsic)
_DEBRUIJN = np.uint64(0x03F79D71B4CB0A89)
_DEBRUIJN_BITS = np.zeros(64, dtype=np.int64)
for _i in range(64):
    _DEBRUIJN_BITS[((1 << _i) * 0x03F79D71B4CB0A89 % (1 << 64)) >> 58] = _i
del _i


@numba.njit(cache=True, nogil=True, inline="always")
def _lowest_bit(x):
    """Index of the lowest set bit of ``x > 0``."""
    return _DEBRUIJN_BITS[(np.uint64(x & -x) * _DEBRUIJN) >> np.uint64(58)]


@numba.njit(cache=True, nogil=True)
def _held_karp_dp(d, par, best):
    """Held-Karp table over nodes 1..n: ``dp[s, j]`` is the cheapest open route from
    node 0 visiting exactly the bitmask ``s`` (bit ``j`` = node ``j + 1``) and ending
    at node ``j + 1`` (defined for ``j`` in ``s``).  Parents go into ``par`` (same shape)
    unless it is ``None``; ``best[s] = min_j dp[s, j]`` (``best[0] = 0``) unless ``best``
    is ``None`` (a ``None`` argument compiles its branch away).

    Each entry is pulled from its predecessor set, whose members are walked by their set
    bits in increasing order; a strictly smaller sum wins, so the parent is the smallest
    ``j`` of least cost and every value is the same float sum as in any other order."""
    m = d.shape[0]
    n = m - 1
    size = 1 << n
    dp = np.empty((size, n))
    if best is not None:
        best[0] = 0.0
    for s in range(1, size):
        bs = np.inf
        xs = s
        while xs:
            x = _lowest_bit(xs)
            xs &= xs - 1
            prev = s ^ (1 << x)
            if prev == 0:
                v = d[0, x + 1]
            else:
                v = np.inf
                pj = -1
                js = prev
                while js:
                    j = _lowest_bit(js)
                    js &= js - 1
                    c = dp[prev, j] + d[j + 1, x + 1]
                    if c < v:
                        v = c
                        pj = j
                if par is not None and pj >= 0:
                    par[s, x] = pj
            dp[s, x] = v
            if v < bs:
                bs = v
        if best is not None:
            best[s] = bs
    return dp


@numba.njit(cache=True, nogil=True)
def _held_karp(d):
    """Exact open route from node 0 over nodes 1..n.  Returns (route, cost)."""
    m = d.shape[0]
    n = m - 1
    full = (1 << n) - 1
    par = np.full((1 << n, n), -1, dtype=np.int64)
    dp = _held_karp_dp(d, par, None)
    best = 0
    for j in range(1, n):
        if dp[full, j] < dp[full, best]:
            best = j
    route = np.empty(m, dtype=np.int64)
    route[0] = 0
    s = full
    j = best
    for pos in range(n, 0, -1):
        route[pos] = j + 1
        pj = par[s, j]
        s = s & ~(1 << j)
        j = pj
    return route, dp[full, best]


@numba.njit(cache=True, nogil=True)
def _exact_route_cost(dist, nodes):
    m = nodes.shape[0]
    n = m - 1
    if n <= 0:
        return 0.0
    d = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            d[i, j] = dist[nodes[i], nodes[j]]
    if n == 1:
        return d[0, 1]
    dp = _held_karp_dp(d, None, None)
    full = (1 << n) - 1
    best = dp[full, 0]
    for j in range(1, n):
        if dp[full, j] < best:
            best = dp[full, j]
    return best


def exact_route_cost(dist: np.ndarray, nodes) -> float:
    """Cost of the optimal open route from ``nodes[0]`` over ``nodes[1:]`` under ``dist`` (Held-Karp,
    no sub-matrix copy in Python): :class:`BruteTour`'s cost on ``dist[np.ix_(nodes, nodes)]``."""
    nodes = np.asarray(nodes, dtype=np.int64)
    if len(nodes) - 1 > MAX_BRUTE_TARGETS:
        raise ValueError(f"exact_route_cost: {len(nodes) - 1} targets > MAX_BRUTE_TARGETS = {MAX_BRUTE_TARGETS}")
    return float(_exact_route_cost(np.asarray(dist, dtype=np.float64), nodes))


@numba.njit(cache=True, nogil=True)
def _held_karp_subsets(d):
    """Optimal open-route cost from node 0 over every subset of nodes 1..n.

    Returns ``best[s]`` for each bitmask ``s`` of the ``n`` targets (bit ``j`` =
    node ``j + 1``); ``best[0] = 0``.
    """
    best = np.full(1 << (d.shape[0] - 1), np.inf)
    _held_karp_dp(d, None, best)
    return best
