"""Compiled host kernels of the clustered Ising tour (paper 5.2): model builders and decoders.

Contract: :func:`onehot_ising` / :func:`maxcut_ising` build the Ising form of the one-hot open-path QUBO
(eq. 1) and of the max-cut split (eq. 7) directly; :func:`expand_branches` puts a branching's frozen spins
back into every read; :func:`best_onehot` decodes every read and keeps the cheapest valid order;
:func:`dist_flags` / :func:`route_cost` check the input and price the route.
Oracle: ``tests/tour_qubo_reference.py``; design notes: docs/design/ising_tour_qubo.md.
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend.mapping.numeric import ising_of_qubo, pairwise_sum

__all__ = ["onehot_ising", "maxcut_ising", "expand_branches", "best_onehot", "cluster_distances",
           "dist_flags", "route_cost"]


@numba.njit(cache=True)
def onehot_ising(d, entry, exit_, A, B):
    """Ising ``(h, J, offset)`` of the one-hot open path over ``s`` items (variable ``i * s + p``)."""
    s = d.shape[0]
    n = s * s
    q = np.full(n, -2.0 * A)
    for i in range(s):
        q[i * s] += B * entry[i]
    for i in range(s):
        q[i * s + s - 1] += B * exit_[i]
    Q = np.zeros((n, n))
    for a in range(n):
        ia, pa = a // s, a % s
        for b in range(a + 1, n):
            ib, pb = b // s, b % s
            if ia == ib or pa == pb:
                Q[a, b] = 2.0 * A
            elif pb == pa + 1:
                Q[a, b] = B * d[ia, ib]
            elif pa == pb + 1:
                Q[a, b] = B * d[ib, ia]
    return ising_of_qubo(q, Q, 2.0 * s * A)


@numba.njit(cache=True)
def maxcut_ising(w):
    """Ising ``(h, J, offset)`` whose energy is ``-cut`` of eq. (7) for weights ``w``."""
    n = w.shape[0]
    q = np.zeros(n)
    Q = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            if i != j:
                ws = 0.5 * (w[i, j] + w[j, i])
                q[i] -= ws
                if j > i:
                    Q[i, j] = 2.0 * ws
    return ising_of_qubo(q, Q, 0.0)


@numba.njit(cache=True)
def expand_branches(spins, free, frozen, n):
    """Bits ``(B * R, n)`` uint8 (``x = (1 + s) / 2``) of the reads ``spins (B, R, >= nf)`` of the
    branches of :func:`ising_backend.mapping.branching.branch_stack` (program-major, frozen spins set per branch)."""
    B, R = spins.shape[0], spins.shape[1]
    k = frozen.shape[0]
    out = np.empty((B * R, n), dtype=np.uint8)
    for m in range(B):
        for r in range(R):
            row = out[m * R + r]
            for a in range(free.shape[0]):
                row[free[a]] = 1 if spins[m, r, a] > 0 else 0
            for t in range(k):
                row[frozen[t]] = (m >> t) & 1
    return out


@numba.njit(cache=True)
def best_onehot(bits, s, d, entry, exit_):
    """One-hot decode of every row of ``bits (m, s*s)`` (``order[p]`` = the item at position ``p``)
    and the first valid row of lowest ``entry + exit + internal`` cost.

    Returns ``(valid (m,) bool, best row (-1: none), orders (m, s) int64)``.
    """
    m = bits.shape[0]
    valid = np.zeros(m, dtype=np.bool_)
    orders = np.zeros((m, s), dtype=np.int64)
    best = -1
    best_cost = np.inf
    for r in range(m):
        ok = True
        for i in range(s):  # each item exactly once
            c = 0
            for p in range(s):
                c += bits[r, i * s + p] != 0
            if c != 1:
                ok = False
                break
        if ok:
            for p in range(s):  # each position exactly once
                c = 0
                item = 0
                for i in range(s):
                    if bits[r, i * s + p] != 0:
                        c += 1
                        item = i
                if c != 1:
                    ok = False
                    break
                orders[r, p] = item
        if not ok:
            continue
        valid[r] = True
        internal = 0.0
        for p in range(s - 1):
            internal += d[orders[r, p], orders[r, p + 1]]
        cost = entry[orders[r, 0]] + exit_[orders[r, s - 1]] + internal
        if cost < best_cost:
            best_cost = cost
            best = r
    return valid, best, orders


@numba.njit(cache=True)
def cluster_distances(dist, flat, ptr, mean):
    """``(K, K)`` cluster-to-cluster distances of clusters ``flat[ptr[k]:ptr[k + 1]]``: the minimum
    (single linkage) or, with ``mean``, the mean (numpy's ``block.mean()`` bits) over member pairs."""
    K = ptr.shape[0] - 1
    D = np.zeros((K, K))
    buf = np.empty(flat.shape[0] * flat.shape[0])
    for a in range(K):
        for b in range(K):
            if a == b:
                continue
            m = 0
            best = np.inf
            for i in range(ptr[a], ptr[a + 1]):
                for j in range(ptr[b], ptr[b + 1]):
                    v = dist[flat[i], flat[j]]
                    buf[m] = v
                    m += 1
                    if v < best:
                        best = v
            D[a, b] = pairwise_sum(buf, 0, m) / m if mean else best
    return D


@numba.njit(cache=True)
def dist_flags(dist):
    """``(code, r, c)``: code 1 if an entry is NaN or negative; else 2 if one is infinite, ``(r, c)``
    the first in row-major order; else 0."""
    ir = -1
    ic = -1
    for i in range(dist.shape[0]):
        for j in range(dist.shape[1]):
            v = dist[i, j]
            if not v >= 0.0:
                return 1, i, j
            if ir < 0 and v == np.inf:
                ir = i
                ic = j
    return (2, ir, ic) if ir >= 0 else (0, -1, -1)


@numba.njit(cache=True)
def route_cost(dist, order):
    """Cost of the open route ``0, order[0], order[1], ...`` under ``dist`` (``np.sum``'s bits)."""
    n = order.shape[0]
    legs = np.empty(n)
    prev = 0
    for i in range(n):
        legs[i] = dist[prev, order[i]]
        prev = order[i]
    return pairwise_sum(legs, 0, n)
