"""Classical target-sharing baselines (paper section 6.1, sharing layer).

Each splits the ``N`` targets among ``R`` robots from the world's ``(R+N, R+N)`` BFS distance matrix, every target
once: :class:`RoundRobinSharing`, :class:`PSASharing` (parallel auction), :class:`SSASharing` (sequential auction,
``bid="insertion"`` or ``"tour"``) and :class:`ExactSharing` (the min-sum optimum, at most
:data:`MAX_EXACT_TARGETS` targets). Design notes: docs/design/classical_baselines.md#target-sharing.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.base import SharingResult, TourSolver
from planners.held_karp import _held_karp_subsets

__all__ = [
    "RoundRobinSharing",
    "PSASharing",
    "SSASharing",
    "ExactSharing",
    "MAX_EXACT_TARGETS",
    "SSA_BIDS",
]

#: Largest target count :class:`ExactSharing` accepts (2^16 x 16 states per robot).
MAX_EXACT_TARGETS = 16

#: Bid rules of :class:`SSASharing`.
SSA_BIDS = ("insertion", "tour")


def _check(dist, n_robots: int) -> tuple[np.ndarray, int, int]:
    d = np.asarray(dist, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise ValueError(f"sharing dist must be a square (R+N, R+N) matrix, got shape {d.shape}")
    r = int(n_robots)
    if r != n_robots or r < 1 or r > d.shape[0]:
        raise ValueError(f"n_robots must be an integer in 1..{d.shape[0]} (matrix size), got {n_robots!r}")
    return np.ascontiguousarray(d), r, d.shape[0] - r


def _result(groups, **stats) -> SharingResult:
    return SharingResult(assignment=tuple(tuple(int(t) for t in g) for g in groups), stats=stats)


class RoundRobinSharing:
    """Target ``t`` to robot ``t mod R`` (distances ignored)."""

    name = "round_robin"

    def assign(self, dist, n_robots: int, tour: TourSolver | None = None, rng=None) -> SharingResult:
        _, r, n = _check(dist, n_robots)
        return _result([range(k, n, r) for k in range(r)])

    def __repr__(self) -> str:
        return "RoundRobinSharing()"


class PSASharing:
    """Parallel single-item auction: each target to its nearest robot."""

    name = "psa"

    def assign(self, dist, n_robots: int, tour: TourSolver | None = None, rng=None) -> SharingResult:
        d, r, n = _check(dist, n_robots)
        winners = np.argmin(d[:r, r:], axis=0) if n else np.zeros(0, dtype=np.int64)
        return _result([np.flatnonzero(winners == k) for k in range(r)])

    def __repr__(self) -> str:
        return "PSASharing()"


@numba.njit(cache=True, nogil=True)
def _ssa_insertion(d, r):
    """SSA with cheapest-insertion MiniSum bids.  Returns (owner, paths, lengths)."""
    m = d.shape[0]
    n = m - r
    paths = np.full((r, n + 1), -1, dtype=np.int64)  # node ids (start first)
    lengths = np.ones(r, dtype=np.int64)
    for k in range(r):
        paths[k, 0] = k
    allocated = np.zeros(n, dtype=np.bool_)
    owner = np.full(n, -1, dtype=np.int64)
    for _ in range(n):
        best = np.inf
        best_k = -1
        best_t = -1
        best_pos = -1
        for k in range(r):
            length = lengths[k]
            for t in range(n):
                if allocated[t]:
                    continue
                node = r + t
                # append at the end
                cost = d[paths[k, length - 1], node]
                pos = length
                # insert between stops p-1 and p
                for p in range(1, length):
                    a = paths[k, p - 1]
                    b = paths[k, p]
                    c = d[a, node] + d[node, b] - d[a, b]
                    if c < cost:
                        cost = c
                        pos = p
                if cost < best:
                    best = cost
                    best_k = k
                    best_t = t
                    best_pos = pos
        if best_k < 0:  # every remaining bid is infinite: give to the first robot
            for t in range(n):
                if not allocated[t]:
                    best_k = 0
                    best_t = t
                    best_pos = lengths[0]
                    break
        length = lengths[best_k]
        for p in range(length, best_pos, -1):
            paths[best_k, p] = paths[best_k, p - 1]
        paths[best_k, best_pos] = r + best_t
        lengths[best_k] = length + 1
        allocated[best_t] = True
        owner[best_t] = best_k
    return owner, paths, lengths


class SSASharing:
    """Sequential single-item auction with MiniSum bids (see module docstring)."""

    name = "ssa"

    def __init__(self, bid: str = "insertion") -> None:
        if bid not in SSA_BIDS:
            raise ValueError(f"SSA bid must be one of {SSA_BIDS}, got {bid!r}")
        self.bid = bid

    def assign(self, dist, n_robots: int, tour: TourSolver | None = None, rng=None) -> SharingResult:
        d, r, n = _check(dist, n_robots)
        if self.bid == "insertion":
            _, paths, lengths = _ssa_insertion(d, r)
            # groups in the auction's path order (the tour layer reorders them)
            groups = [paths[k, 1 : lengths[k]] - r for k in range(r)]
            return _result(groups)
        if tour is None:
            raise ValueError("SSA with bid='tour' needs the downstream tour solver (tour=None given)")
        return self._assign_tour_bids(d, r, n, tour, rng)

    @staticmethod
    def _assign_tour_bids(d, r, n, tour, rng) -> SharingResult:
        owned: list[list[int]] = [[] for _ in range(r)]
        costs = [0.0] * r
        cache: dict[tuple[int, frozenset], float] = {}
        unallocated = list(range(n))
        solves = 0

        def price(k: int, targets: list[int]) -> float:
            nonlocal solves
            key = (k, frozenset(targets))
            if key not in cache:
                idx = [k] + [r + t for t in sorted(targets)]
                cache[key] = float(tour.solve(d[np.ix_(idx, idx)], rng).cost)
                solves += 1
            return cache[key]

        while unallocated:
            best = (np.inf, -1, -1)
            for k in range(r):
                for t in unallocated:
                    bid = price(k, owned[k] + [t]) - costs[k]
                    if bid < best[0]:
                        best = (bid, k, t)
            _, k, t = best
            if k < 0:  # only infinite bids remain
                k, t = 0, unallocated[0]
            owned[k].append(t)
            costs[k] = price(k, owned[k])
            unallocated.remove(t)
        return _result(owned, tour_solves=solves)

    def __repr__(self) -> str:
        return f"SSASharing(bid={self.bid!r})"


@numba.njit(cache=True, nogil=True)
def _combine(costs):
    """Min-sum over robots of subset costs.  ``costs``: (R, 2^N).  Returns (total, masks)."""
    r, size = costs.shape
    full = size - 1
    f = costs[0].copy()
    choice = np.zeros((r, size), dtype=np.int64)  # subset given to robot k at state S
    for s in range(size):
        choice[0, s] = s
    for k in range(1, r):
        g = np.full(size, np.inf)
        ck = costs[k]
        for s in range(size):
            # enumerate T subset of S for robot k (T = 0 included)
            t = s
            while True:
                v = f[s ^ t] + ck[t]
                if v < g[s]:
                    g[s] = v
                    choice[k, s] = t
                if t == 0:
                    break
                t = (t - 1) & s
        f = g
    masks = np.zeros(r, dtype=np.int64)
    s = full
    for k in range(r - 1, -1, -1):
        masks[k] = choice[k, s]
        s = s ^ masks[k]
    return f[full], masks


class ExactSharing:
    """Min-sum optimal assignment with optimal routes, by subset DP (N <= 16)."""

    name = "exact"

    def assign(self, dist, n_robots: int, tour: TourSolver | None = None, rng=None) -> SharingResult:
        d, r, n = _check(dist, n_robots)
        if n > MAX_EXACT_TARGETS:
            raise ValueError(
                f"exact sharing: {n} targets exceeds the limit of {MAX_EXACT_TARGETS} "
                f"(subset DP needs 2^n route costs per robot); use 'ssa' for larger instances"
            )
        if n == 0:
            return _result([[] for _ in range(r)], optimum=0.0)
        costs = np.empty((r, 1 << n))
        targets = np.arange(r, r + n)
        for k in range(r):
            idx = np.concatenate([[k], targets])
            costs[k] = _held_karp_subsets(np.ascontiguousarray(d[np.ix_(idx, idx)]))
        total, masks = _combine(costs)
        groups = [[t for t in range(n) if (int(mask) >> t) & 1] for mask in masks]
        return _result(groups, optimum=float(total))

    def __repr__(self) -> str:
        return "ExactSharing()"
