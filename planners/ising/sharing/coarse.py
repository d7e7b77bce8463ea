"""Coarse splits for groups larger than the chip (big worlds; beyond paper 5.3).

A split of ``m`` nodes needs ``m - 2`` free spins.  When that exceeds what the chip holds even
with spin-budget branching, the group's targets are first gathered into clusters (robots stay
single nodes) and the split is solved on the clusters: the coarse weight of two clusters is
the sum of the fine weights between their members, so the coarse cut of a partition equals the
fine cut of the partition that keeps every cluster whole.  The coarse problem goes through the
same anchored QUBO, mapping portfolio and chip as any split; its candidates are expanded to
the group's nodes and re-scored on the fine weights.

Clusters: farthest-point centres (the first is the target with the largest total weight to
the rest; ties to the lowest index), each target joins its nearest centre.  Deterministic,
O(targets x clusters), and compact (no member farther from its centre than twice the best
possible radius for that many clusters).  Measurements: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numpy as np

__all__ = ["farthest_point_clusters", "coarsen", "expand_sides"]


def farthest_point_clusters(w: np.ndarray, k: int) -> np.ndarray:
    """Labels ``0..k-1`` of the ``n`` points of the symmetric weight (distance-like) matrix ``w``."""
    n = w.shape[0]
    if k >= n:
        return np.arange(n, dtype=np.int64)
    centres = [int(np.argmax(w.sum(axis=1)))]
    nearest = w[centres[0]].copy()
    for _ in range(1, k):
        nxt = int(np.argmax(nearest))
        centres.append(nxt)
        nearest = np.minimum(nearest, w[nxt])
    return np.argmin(w[np.ix_(np.arange(n), centres)], axis=1).astype(np.int64)


def coarsen(w: np.ndarray, group: np.ndarray, n_robots: int, n_clusters: int):
    """``(members, wc)``: the coarse nodes of ``group`` (robots first, one each, then target
    clusters; arrays of global node indices) and their summed weight matrix (zero diagonal)."""
    group = np.asarray(group, dtype=np.int64)
    robots = group[group < n_robots]
    targets = group[group >= n_robots]
    labels = farthest_point_clusters(np.asarray(w, dtype=float)[np.ix_(targets, targets)], n_clusters)
    members = [np.array([r], dtype=np.int64) for r in robots]
    members += [np.sort(targets[labels == c]) for c in range(int(labels.max()) + 1) if (labels == c).any()]
    index = np.concatenate([np.full(len(m), i, dtype=np.int64) for i, m in enumerate(members)])
    order = np.concatenate(members)
    onehot = np.zeros((len(order), len(members)))
    onehot[np.arange(len(order)), index] = 1.0
    wc = onehot.T @ np.asarray(w, dtype=float)[np.ix_(order, order)] @ onehot
    np.fill_diagonal(wc, 0.0)
    return members, wc


def expand_sides(members, side0, side1) -> tuple[np.ndarray, np.ndarray]:
    """Coarse sides (coarse node indices) -> the fine sides (sorted global node indices)."""
    def grow(side):
        parts = [members[int(i)] for i in side]
        return np.sort(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)
    return grow(side0), grow(side1)
