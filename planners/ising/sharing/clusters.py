"""The clusters of a coarse split (big worlds; beyond paper 5.3): compiled steps.

Contract: :meth:`.stages.SplitStages.coarse_split` splits a group too large for the chip even with
spin-budget branching as ``coarse_split`` of ``tests/sharing_search_reference.py`` (its oracle) does:
targets in farthest-point clusters (:func:`coarsen`), the split solved on the clusters' summed weights,
every candidate expanded and re-scored on the fine weights (:func:`expand_candidates`).
Design notes: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend.mapping.numeric import pairwise_sum
from planners.ising.sharing.node_sets import intern, nodes_of

__all__ = ["farthest_point_labels", "coarsen", "fine_cut", "expand_candidates"]


@numba.njit(cache=True)
def farthest_point_labels(w, k):
    """``farthest_point_clusters`` (the oracle): labels ``0..k-1`` of the points of ``w``."""
    n = w.shape[0]
    if k >= n:
        return np.arange(n)
    total = np.empty(n)
    for i in range(n):
        total[i] = pairwise_sum(w[i], 0, n)
    centres = np.empty(k, dtype=np.int64)
    centres[0] = np.argmax(total)
    nearest = w[centres[0]].copy()
    for c in range(1, k):
        centres[c] = np.argmax(nearest)
        for i in range(n):
            nearest[i] = min(nearest[i], w[centres[c], i])
    labels = np.empty(n, dtype=np.int64)
    for i in range(n):
        best = 0
        for c in range(1, k):
            if w[i, centres[c]] < w[i, centres[best]]:
                best = c
        labels[i] = best
    return labels


@numba.njit(cache=True)
def _clusters(w, nodes, k, out, start, n_out):
    """Append the clusters of ``nodes`` (sorted global indices) to ``out`` / ``start``, as
    ``_clusters`` (the oracle); returns the new cluster count."""
    n = nodes.shape[0]
    sub = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            sub[i, j] = w[nodes[i], nodes[j]]
    if n > 1:
        low = np.inf
        for i in range(n):
            for j in range(n):
                if i != j:
                    low = min(low, sub[i, j])
        if low < 0:  # shifted split weights: back to a distance-like matrix (same order), zero diagonal
            for i in range(n):
                for j in range(n):
                    sub[i, j] = 0.0 if i == j else sub[i, j] - low
    labels = farthest_point_labels(sub, k)
    pos = start[n_out]
    for c in range(labels.max() + 1):
        first = True
        for i in range(n):
            if labels[i] == c:
                out[pos] = nodes[i]
                pos += 1
                first = False
        if not first:
            n_out += 1
            start[n_out] = pos
    return n_out


@numba.njit(cache=True)
def coarsen(w, group, n_robots, n_clusters, robot_clusters):
    """``coarsen`` (the oracle): ``(members (len(group),), start (m + 1,), wc (m, m))``, coarse node
    ``c`` holding ``members[start[c]:start[c + 1]]`` (robots first: one each, or ``robot_clusters``
    clusters when that is positive; then the target clusters), ``wc`` their summed weights
    (numpy's sum of each block, zero diagonal)."""
    n = group.shape[0]
    nr = np.searchsorted(group, n_robots)
    members = np.empty(n, dtype=np.int64)
    start = np.zeros(n + 1, dtype=np.int64)
    m = 0
    if robot_clusters <= 0:
        for i in range(nr):
            members[i] = group[i]
            m += 1
            start[m] = i + 1
    else:
        m = _clusters(w, group[:nr], robot_clusters, members, start, m)
    m = _clusters(w, group[nr:], n_clusters, members, start, m)
    wc = np.zeros((m, m))
    block = np.empty(n * n)
    for a in range(m):
        for b in range(m):
            if a == b:
                continue
            t = 0
            for i in range(start[a], start[a + 1]):
                for j in range(start[b], start[b + 1]):
                    block[t] = w[members[i], members[j]]
                    t += 1
            wc[a, b] = pairwise_sum(block, 0, t)
    return members, start[:m + 1], wc


@numba.njit(cache=True)
def expand(pool, coarse_side, members, start):
    """The id of the fine set of coarse side ``coarse_side`` (a set id of coarse nodes)."""
    side = nodes_of(pool, coarse_side)
    n = 0
    for c in side:
        n += start[c + 1] - start[c]
    out = np.empty(n, dtype=np.int64)
    t = 0
    for c in side:
        for i in range(start[c], start[c + 1]):
            out[t] = members[i]
            t += 1
    return intern(pool, np.sort(out))


@numba.njit(cache=True)
def fine_cut(w, pool, side0, side1):
    """``cut_value`` (the oracle) of two sides (set ids): numpy's sum of the block, 0 for an empty side."""
    s0 = nodes_of(pool, side0)
    s1 = nodes_of(pool, side1)
    if s0.shape[0] == 0 or s1.shape[0] == 0:
        return 0.0
    block = np.empty(s0.shape[0] * s1.shape[0])
    t = 0
    for i in s0:
        for j in s1:
            block[t] = w[i, j]
            t += 1
    return pairwise_sum(block, 0, t)


@numba.njit(cache=True)
def expand_candidates(w, pool, store, scratch, row, members, start):
    """The candidates of the coarse split in store row ``scratch`` expanded to fine sets and re-scored
    on ``w`` (:func:`fine_cut`) into row ``row``, best cut first (ties in candidate order)."""
    c_cut, c_m0, c_m1, c_n = store.cut, store.side0, store.side1, store.count
    n = c_n[scratch]
    cut = np.empty(n)
    f0 = np.empty(n, dtype=np.int64)
    f1 = np.empty(n, dtype=np.int64)
    for j in range(n):
        f0[j] = expand(pool, c_m0[scratch, j], members, start)
        f1[j] = expand(pool, c_m1[scratch, j], members, start)
        cut[j] = fine_cut(w, pool, f0[j], f1[j])
    order = np.argsort(-cut, kind="mergesort")
    for j in range(n):
        c_cut[row, j] = cut[order[j]]
        c_m0[row, j] = f0[order[j]]
        c_m1[row, j] = f1[order[j]]
    c_n[row] = n
