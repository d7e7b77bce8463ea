"""Coarse splits for groups larger than the chip (big worlds; beyond paper 5.3).

A split of ``m`` nodes needs ``m - 2`` free spins.  When that exceeds what the chip holds even
with spin-budget branching, the group's targets are first gathered into clusters (robots stay
single nodes, unless they alone would take more than half the chip: then neighbouring robots
are clustered too) and the split is solved on the clusters: the coarse weight of two clusters is
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

from dataclasses import dataclass, field

import numpy as np

from planners.ising.sharing.bundles import SharingFailure
from planners.ising.sharing.qubo import cut_value

__all__ = ["farthest_point_clusters", "coarsen", "expand_sides", "CoarseSplit", "coarse_split"]


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


def _clusters(w: np.ndarray, nodes: np.ndarray, k: int) -> list[np.ndarray]:
    sub = np.asarray(w, dtype=float)[np.ix_(nodes, nodes)]
    if len(nodes) > 1:
        low = sub[~np.eye(len(nodes), dtype=bool)].min()
        if low < 0:  # shifted split weights: back to a distance-like matrix (same order), zero diagonal
            sub = sub - low
            np.fill_diagonal(sub, 0.0)
    labels = farthest_point_clusters(sub, k)
    return [np.sort(nodes[labels == c]) for c in range(int(labels.max()) + 1) if (labels == c).any()]


def coarsen(w: np.ndarray, group: np.ndarray, n_robots: int, n_clusters: int, robot_clusters: int | None = None):
    """``(members, wc)``: the coarse nodes of ``group`` (robots first -- one each, or
    ``robot_clusters`` clusters of neighbouring robots --, then target clusters; arrays of global
    node indices) and their summed weight matrix (zero diagonal)."""
    group = np.asarray(group, dtype=np.int64)
    robots = group[group < n_robots]
    targets = group[group >= n_robots]
    if robot_clusters is None:
        members = [np.array([r], dtype=np.int64) for r in robots]
    else:
        members = _clusters(w, robots, robot_clusters)
    members += _clusters(w, targets, n_clusters)
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


@dataclass
class CoarseSplit:
    """A split solved on target clusters: its group and its expanded candidates, best cut first."""

    nodes: np.ndarray
    cands: list = field(default_factory=list)




def coarse_split(splits, w, R, g, kind, rng, stats) -> CoarseSplit:
    """The split of a group too large for the chip, solved on target clusters by ``splits`` (a
    :class:`~.splits.SplitSearch`): as many clusters as fit the chip without branching."""
    g = np.asarray(g, dtype=np.int64)
    n_spins = int(splits.chip.spec.n_spins)
    robots = int((g < R).sum())
    robot_clusters = None
    if n_spins + 2 - robots < max(1, n_spins // 2):
        # more robots than leave half the chip to target clusters: neighbouring robots are
        # clustered too (each side of the coarse split keeps whole robot clusters; the fine
        # groups below split them on the chip as usual)
        robot_clusters = max(2, (n_spins + 2) // 2)
        if robots < 2 or n_spins + 2 - robot_clusters < 1:
            raise SharingFailure(
                f"a group of {robots} robots and {len(g) - robots} targets cannot be coarsened onto the "
                f"chip: its split needs at least {robot_clusters - 1} free spins, the chip has {n_spins}")
    n_coarse_robots = robots if robot_clusters is None else min(robots, robot_clusters)
    n_clusters = n_spins + 2 - n_coarse_robots
    members, wc = coarsen(w, g, R, n_clusters, robot_clusters)
    robots = sum(1 for m in members if m[0] < R)  # coarse robot nodes (robot clusters keep robots only)
    outer, splits.memo = splits.memo, {}  # coarse node indices must not meet the fine memo
    try:
        (problem,) = splits.stage(wc, robots, [np.arange(len(members), dtype=np.int64)], kind, rng, stats)
    finally:
        splits.memo = outer
    cands = []
    for _cut, side0, side1, _ in problem.cands:
        f0, f1 = expand_sides(members, side0, side1)
        cands.append((cut_value(w, f0, f1), f0, f1, None))
    cands.sort(key=lambda c: -c[0])
    stats["coarse_splits"] = stats.get("coarse_splits", 0) + 1
    return CoarseSplit(nodes=g, cands=cands)

