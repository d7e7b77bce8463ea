"""Steps 1-2 of the clustered Ising tour (paper 5.2): distance-Ising clustering and cluster ordering.

A component of :class:`~planners.ising.tour.IsingTour` (``Clusters(config, onehot)``, on its
:class:`~.onehot.OneHotSolver`): recursive max-cut splits (eq. 7) until
clusters hold at most ``local_limit`` targets, refinement up to ``max_clusters``, then the
nearest cluster first and a one-hot ordering model for the rest (hierarchical above the
ordering limit).  Choices: docs/design/ising_tour.md.
"""

from __future__ import annotations

import numpy as np

from ising_backend import CallLedger, MeteredSolver

from planners.ising.tour.kernels import cluster_distances, maxcut_ising

__all__ = ["TourFailure", "Clusters"]


def cut_value(w: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``cut(x)`` of eq. (7), vectorised over leading axes of ``x``."""
    w = np.asarray(w, dtype=np.float64)
    ws = 0.5 * (w + w.T)
    np.fill_diagonal(ws, 0.0)
    x = np.asarray(x, dtype=np.float64)
    # sum_{i<j} w_ij [x_i != x_j] = 1/2 sum_{i,j} w_ij (x_i + x_j - 2 x_i x_j)
    deg = ws.sum(axis=1)
    return x @ deg - np.einsum("...i,ij,...j->...", x, ws, x)


class _Run:
    """Per-solve bookkeeping of :class:`~planners.ising.tour.IsingTour`: the rng, statistics, the
    solve's charge and its metered solvers (``ising_backend.MeteredSolver`` of the tour's logical
    solver and chip, made on first use, both charging ``charged``)."""

    __slots__ = ("rng", "stats", "charged", "_tour", "_solver", "_chip")

    def __init__(self, rng: np.random.Generator, stats: dict, tour=None):
        self.rng = rng
        self.stats = stats
        self.charged = CallLedger()
        self._tour = tour
        self._solver = None
        self._chip = None

    @property
    def solver(self) -> MeteredSolver:
        if self._solver is None:
            self._solver = MeteredSolver(self._tour.solver, self.charged, decision="tour_split")
        return self._solver

    @property
    def chip(self) -> MeteredSolver:
        if self._chip is None:
            self._chip = MeteredSolver(self._tour.chip, self.charged, decision="tour_split")
        return self._chip


class TourFailure(RuntimeError):
    """Raised internally when a construction subproblem never decodes valid."""


class Clusters:
    """Clustering and ordering steps on the programs of ``onehot`` (module docstring)."""

    def __init__(self, config, onehot):
        self.config = config
        self.onehot = onehot

    # ------------------------------------------------------------------ 1. clustering
    def cluster(self, dist: np.ndarray, run: _Run) -> list[list[int]]:
        n = dist.shape[0] - 1
        clusters: list[list[int]] = [list(range(1, n + 1))]
        # split every cluster above the local limit (largest first, ties by index)
        while True:
            big = [k for k, c in enumerate(clusters) if len(c) > self.config.local_limit]
            if not big:
                break
            k = max(big, key=lambda j: (len(clusters[j]), -j))
            clusters[k:k + 1] = self.split(dist, clusters[k], run)
        # refinement up to the ordering limit
        while len(clusters) < self.config.max_clusters:
            sizes = np.array([len(c) for c in clusters])
            if sizes.max() < 2:
                break
            if self.config.refine == "spare_first" and len(clusters) > 1:
                near = int(np.argmin([dist[0, c].min() for c in clusters]))
                others = sizes.copy()
                others[near] = 0
                k = int(np.argmax(others)) if others.max() >= 2 else near
            else:
                k = int(np.argmax(sizes))  # largest, ties by lowest index
            clusters[k:k + 1] = self.split(dist, clusters[k], run)
            run.stats["refinement_splits"] += 1
        run.stats["clusters"] = [len(c) for c in clusters]
        return clusters

    def split(self, dist: np.ndarray, members: list[int], run: _Run) -> list[list[int]]:
        """Max-cut split (eq. 7) of ``members`` by the Ising solver."""
        run.stats["cluster_splits"] += 1
        s = len(members)
        if s == 2:  # the only non-degenerate cut: no decision to make
            return [[members[0]], [members[1]]]
        limit = self.onehot.budget + self.config.max_branch_bits
        drawn = np.asarray(members)
        if s > limit:
            drawn = np.sort(run.rng.choice(drawn, size=self.onehot.budget, replace=False))
        w = np.ascontiguousarray(dist[np.ix_(drawn, drawn)], dtype=np.float64)
        if not np.all(np.isfinite(w)):
            raise ValueError("weight matrix has non-finite entries (targets in different components?)")
        h, J, off = maxcut_ising(w)
        for _attempt in range(self.config.max_retries + 1):
            bits = self.onehot.sample(h, J, off, run)
            sizes = bits.sum(axis=1)
            ok = (sizes > 0) & (sizes < len(drawn))
            if np.any(ok):
                cand = bits[ok]
                cuts = cut_value(w, cand)
                x = cand[int(np.argmax(cuts))]
                break
        else:
            raise TourFailure(f"max-cut split of {s} targets gave only degenerate samples "
                              f"after {self.config.max_retries + 1} attempts")
        side = {int(t): int(b) for t, b in zip(drawn, x)}
        if s > limit:  # undrawn members join the side of their nearest drawn member
            for t in members:
                if t not in side:
                    near = drawn[int(np.argmin(dist[t, drawn]))]
                    side[t] = side[int(near)]
        a = [t for t in members if side[t] == 0]
        b = [t for t in members if side[t] == 1]
        return [a, b]

    # ------------------------------------------------------------------ 2. cluster order
    def cluster_dist(self, dist: np.ndarray, clusters: list[list[int]]) -> np.ndarray:
        """Cluster-to-cluster distances (``cluster_distance``): the closest or mean pair
        (:func:`.kernels.cluster_distances`), or the distance between the clusters' medoids."""
        if self.config.cluster_distance == "medoid":
            med = [c[int(np.argmin(dist[np.ix_(c, c)].sum(axis=1)))] for c in clusters]
            D = dist[np.ix_(med, med)].astype(np.float64)
            np.fill_diagonal(D, 0.0)
            return D
        flat = np.array([t for c in clusters for t in c], dtype=np.int64)
        ptr = np.cumsum([0] + [len(c) for c in clusters]).astype(np.int64)
        return cluster_distances(np.ascontiguousarray(dist, dtype=np.float64), flat, ptr,
                                 self.config.cluster_distance == "mean")

    def order(self, dist: np.ndarray, clusters: list[list[int]], run: _Run) -> list[list[int]]:
        K = len(clusters)
        to_robot = np.array([dist[0, c].min() for c in clusters])
        first = int(np.argmin(to_robot))  # ties by lowest index
        rest = [k for k in range(K) if k != first]
        if len(rest) <= 1:
            return [clusters[first]] + [clusters[k] for k in rest]
        D = self.cluster_dist(dist, clusters)
        order = self.order_items(D, rest, first, run)
        return [clusters[first]] + [clusters[k] for k in order]

    def order_items(self, D: np.ndarray, items: list[int], prev: int, run: _Run) -> list[int]:
        """Open path over cluster indices ``items`` entered from cluster ``prev``.

        Up to ``max_clusters - 1`` items: one one-hot ordering model.  More
        (only when the clusters of at most ``local_limit`` targets number more
        than ``max_clusters``): hierarchical -- a max-cut split of the items on
        ``D``, the part nearer to ``prev`` first (the paper's nearest-first
        rule one level up), each part ordered recursively.
        """
        if len(items) <= 1:
            return list(items)
        if len(items) <= self.config.max_clusters - 1:
            d = D[np.ix_(items, items)]
            entry = D[prev, items]
            order = self.onehot.solve_path(d, entry, np.zeros(len(items)), run, "ordering")
            if order is None:
                raise TourFailure(f"cluster ordering ({len(items)}^2 = {len(items) ** 2} variables) gave no valid "
                                  f"permutation after {self.config.max_retries + 1} attempts")
            return [items[i] for i in order]
        run.stats["ordering_splits"] += 1
        a, b = self.split(D, list(items), run)
        if D[prev, b].min() < D[prev, a].min():
            a, b = b, a
        left = self.order_items(D, a, prev, run)
        return left + self.order_items(D, b, left[-1], run)
