"""Classical tour construction baselines (paper section 6.1, tour layer).

Open routes from the robot (local node 0) through its targets: :class:`NearestNeighbourTour`, :class:`TwoOptTour`
(``free_end``), :class:`ThreeOptTour` (``moves="4"`` or ``"7"``) and :class:`BruteTour` (Held-Karp, at most
:data:`MAX_BRUTE_TARGETS` targets). A matrix with ``inf`` entries gives the nearest neighbour order with
``cost = inf`` and ``stats["infeasible"]``. Design notes: docs/design/classical_baselines.md#tour-construction.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.base import TourResult
from planners.held_karp import (MAX_BRUTE_TARGETS, _exact_route_cost, _held_karp, _held_karp_dp,  # noqa: F401
                                _held_karp_subsets, exact_route_cost)

__all__ = [
    "NearestNeighbourTour",
    "TwoOptTour",
    "ThreeOptTour",
    "BruteTour",
    "MAX_BRUTE_TARGETS",
    "THREE_OPT_MOVES",
    "route_cost",
    "held_karp_subset_costs",
]


#: The 3-opt move sets :class:`ThreeOptTour` offers.
THREE_OPT_MOVES = ("4", "7")

_EPS = 1e-9


# --------------------------------------------------------------------- kernels
@numba.njit(cache=True, nogil=True)
def _nn_kernel(d):
    m = d.shape[0]
    route = np.empty(m, dtype=np.int64)
    seen = np.zeros(m, dtype=np.bool_)
    route[0] = 0
    seen[0] = True
    cur = 0
    for pos in range(1, m):
        best = -1
        best_d = np.inf
        for x in range(1, m):
            if not seen[x] and (best < 0 or d[cur, x] < best_d):
                best = x
                best_d = d[cur, x]
        route[pos] = best
        seen[best] = True
        cur = best
    return route


@numba.njit(cache=True, nogil=True)
def _route_cost(d, route):
    total = 0.0
    for i in range(route.shape[0] - 1):
        total += d[route[i], route[i + 1]]
    return total


@numba.njit(cache=True, nogil=True)
def _reverse(t, lo, hi):
    """Reverse ``t[lo:hi]`` in place."""
    hi -= 1
    while lo < hi:
        x = t[lo]
        t[lo] = t[hi]
        t[hi] = x
        lo += 1
        hi -= 1


@numba.njit(cache=True, nogil=True)
def _two_opt_kernel(d, route, free_end):
    """First-improvement 2-opt on an open route with fixed start ``route[0]``."""
    n = route.shape[0] - 1
    jmax = n + 1 if free_end else n
    passes = 0
    improved = True
    while improved:
        improved = False
        passes += 1
        for i in range(1, n):
            for j in range(i + 1, jmax):
                a = route[i - 1]
                b = route[i]
                c = route[j]
                delta = d[a, c] - d[a, b]
                if j < n:
                    e = route[j + 1]
                    delta += d[b, e] - d[c, e]
                if delta < -1e-9:
                    _reverse(route, i, j + 1)
                    improved = True
    return passes


@numba.njit(cache=True, nogil=True)
def _apply_move(t, i, j, k, move, buf):
    """Apply reconnection ``move`` to cycle array ``t`` with B = t[i:j], C = t[j:k].

    moves: 1 B', 2 C', 3 (BC)', 4 B'C', 5 CB, 6 CB', 7 C'B.
    """
    if move == 1:
        _reverse(t, i, j)
    elif move == 2:
        _reverse(t, j, k)
    elif move == 3:
        _reverse(t, i, k)
    elif move == 4:
        _reverse(t, i, j)
        _reverse(t, j, k)
    else:
        nb = j - i
        nc = k - j
        for x in range(nb):
            buf[x] = t[i + x]
        for x in range(nc):
            t[i + x] = t[j + x]
        for x in range(nb):
            t[i + nc + x] = buf[x]
        # now t[i:i+nc] = C, t[i+nc:k] = B
        if move == 6:
            _reverse(t, i + nc, k)
        elif move == 7:
            _reverse(t, i, i + nc)


@numba.njit(cache=True, nogil=True)
def _three_opt_kernel(d, t, full):
    """3-opt on the cycle ``t`` (in place).  ``full``: 7 moves, else the common 4."""
    m = t.shape[0]
    buf = np.empty(m, dtype=np.int64)
    minseg = 1
    passes = 0
    improved = True
    while improved:
        improved = False
        passes += 1
        for i in range(m):
            for j in range(i + minseg, m):
                kmax = m + 1 if i > 0 else m
                for k in range(j + minseg, kmax):
                    a = t[i - 1] if i > 0 else t[m - 1]
                    b0 = t[i]
                    b1 = t[j - 1]
                    c0 = t[j]
                    c1 = t[k - 1]
                    f = t[k % m]
                    d0 = d[a, b0] + d[b1, c0] + d[c1, f]
                    move = 0
                    if full:
                        best = d0 - 1e-9
                        cand = d[a, b1] + d[b0, c0] + d[c1, f]
                        if cand < best:
                            best = cand
                            move = 1
                        cand = d[a, b0] + d[b1, c1] + d[c0, f]
                        if cand < best:
                            best = cand
                            move = 2
                        cand = d[a, c1] + d[c0, b1] + d[b0, f]
                        if cand < best:
                            best = cand
                            move = 3
                        cand = d[a, b1] + d[b0, c1] + d[c0, f]
                        if cand < best:
                            best = cand
                            move = 4
                        cand = d[a, c0] + d[c1, b0] + d[b1, f]
                        if cand < best:
                            best = cand
                            move = 5
                        cand = d[a, c0] + d[c1, b1] + d[b0, f]
                        if cand < best:
                            best = cand
                            move = 6
                        cand = d[a, c1] + d[c0, b0] + d[b1, f]
                        if cand < best:
                            best = cand
                            move = 7
                    else:
                        if d0 - (d[a, b1] + d[b0, c0] + d[c1, f]) > 1e-9:
                            move = 1
                        elif d0 - (d[a, b0] + d[b1, c1] + d[c0, f]) > 1e-9:
                            move = 2
                        elif d0 - (d[a, c1] + d[c0, b1] + d[b0, f]) > 1e-9:
                            move = 3
                        elif d0 - (d[a, c0] + d[c1, b0] + d[b1, f]) > 1e-9:
                            move = 5
                    if move > 0:
                        _apply_move(t, i, j, k, move, buf)
                        improved = True
    return passes


@numba.njit(cache=True, nogil=True)
def _three_opt_open(d, full):
    """NN route, closed with the dummy end node, 3-opt, reopened.  Returns (route, passes).

    ``route[0] != 0`` would flag a dummy node that left the route end (cannot
    happen with ``M`` above any open route; checked by the caller).
    """
    m = d.shape[0]
    n = m - 1
    route = _nn_kernel(d)
    big = 1.0
    for i in range(m):
        for j in range(m):
            if d[i, j] > big:
                big = d[i, j]
    big = 1.0 + big * (n + 1)
    ext = np.full((m + 1, m + 1), big)
    ext[:m, :m] = d
    ext[0, m] = 0.0
    ext[m, 0] = 0.0
    ext[m, m] = 0.0
    cycle = np.empty(m + 1, dtype=np.int64)
    cycle[:m] = route
    cycle[m] = m
    passes = _three_opt_kernel(ext, cycle, full)
    z = 0
    while cycle[z] != 0:
        z += 1
    out = np.empty(m, dtype=np.int64)
    # walk away from the dummy node D = m
    step = 1 if cycle[(z - 1) % (m + 1)] == m else -1
    for i in range(m):
        out[i] = cycle[(z + step * i) % (m + 1)]
    if cycle[(z + step * m) % (m + 1)] != m:
        out[0] = -1
    return out, passes


@numba.njit(cache=True, nogil=True)
def three_opt_route(d):
    """:func:`_three_opt_open` with the default moves (``moves="4"``): one compiled specialization for the
    tour layer and the sharing's pricing (a constant flag from compiled code is its own argument type)."""
    return _three_opt_open(d, False)


@numba.njit(cache=True, nogil=True)
def three_opt_cost(d):
    """Cost of :class:`ThreeOptTour`'s open route (``moves="4"``) over a finite ``d`` of 3 or more
    nodes: the sharing's compiled placement prices bundles of more than 13 targets with it."""
    route, _ = three_opt_route(d)
    return _route_cost(d, route)


# --------------------------------------------------------------------- helpers
def _check_dist(dist) -> np.ndarray:
    d = np.asarray(dist, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1] or d.shape[0] < 1:
        raise ValueError(f"tour dist must be a square (n+1, n+1) matrix with n >= 0, got shape {d.shape}")
    if np.isnan(d).any():
        raise ValueError("tour dist contains NaN")
    return np.ascontiguousarray(d)


def route_cost(dist: np.ndarray, order) -> float:
    """Cost of the open route ``0 -> order[0] -> order[1] -> ...`` under ``dist``."""
    route = np.concatenate([[0], np.asarray(order, dtype=np.int64)])
    return float(_route_cost(np.asarray(dist, dtype=np.float64), route))


def held_karp_subset_costs(dist: np.ndarray) -> np.ndarray:
    """``(2^n,)`` optimal open-route cost from node 0 over every subset of nodes 1..n."""
    d = _check_dist(dist)
    return _held_karp_subsets(d)


def _result(d: np.ndarray, route: np.ndarray, **stats) -> TourResult:
    return TourResult(order=tuple(int(x) for x in route[1:]), cost=float(_route_cost(d, route)), stats=stats)


def _trivial(d: np.ndarray) -> TourResult | None:
    """Result for n <= 2 nodes (no choice to make beyond NN / exhaustive)."""
    n = d.shape[0] - 1
    if n == 0:
        return TourResult(order=(), cost=0.0)
    if n == 1:
        return TourResult(order=(1,), cost=float(d[0, 1]))
    return None


def _infeasible(d: np.ndarray) -> TourResult | None:
    if np.isfinite(d).all():
        return None
    return _result(d, _nn_kernel(d), infeasible=True)


# --------------------------------------------------------------------- solvers
class NearestNeighbourTour:
    """Nearest neighbour open route from node 0 (see module docstring)."""

    name = "nn"

    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        d = _check_dist(dist)
        return _trivial(d) or _result(d, _nn_kernel(d))

    def __repr__(self) -> str:
        return "NearestNeighbourTour()"


class TwoOptTour:
    """Nearest neighbour + first-improvement 2-opt (``free_end``: also reverse suffixes)."""

    name = "2opt"

    def __init__(self, free_end: bool = False) -> None:
        self.free_end = bool(free_end)

    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        d = _check_dist(dist)
        done = _trivial(d) or _infeasible(d)
        if done is not None:
            return done
        route = _nn_kernel(d)
        passes = _two_opt_kernel(d, route, self.free_end)
        return _result(d, route, passes=int(passes))

    def __repr__(self) -> str:
        return f"TwoOptTour(free_end={self.free_end})"


class ThreeOptTour:
    """Nearest neighbour + 3-opt; ``moves="4"`` (common variant) or ``"7"`` (all reconnections)."""

    name = "3opt"

    def __init__(self, moves: str = "4") -> None:
        moves = str(moves)
        if moves not in THREE_OPT_MOVES:
            raise ValueError(f"3-opt moves must be one of {THREE_OPT_MOVES}, got {moves!r}")
        self.moves = moves

    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        d = _check_dist(dist)
        done = _trivial(d) or _infeasible(d)
        if done is not None:
            return done
        route, passes = three_opt_route(d) if self.moves == "4" else _three_opt_open(d, True)
        if route[0] != 0:  # pragma: no cover - guaranteed by the choice of M
            raise RuntimeError("3-opt dummy end node left the route end")
        return _result(d, route, passes=int(passes))

    def __repr__(self) -> str:
        return f"ThreeOptTour(moves={self.moves!r})"


class BruteTour:
    """Exact open route by Held-Karp dynamic programming (n <= 13)."""

    name = "brute"

    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        d = _check_dist(dist)
        n = d.shape[0] - 1
        if n > MAX_BRUTE_TARGETS:
            raise ValueError(
                f"brute tour: {n} targets exceeds the limit of {MAX_BRUTE_TARGETS} "
                f"(Held-Karp needs 2^n x n states); use tour '3opt' for larger bundles"
            )
        done = _trivial(d) or _infeasible(d)
        if done is not None:
            return done
        route, _ = _held_karp(d)
        return _result(d, route)

    def __repr__(self) -> str:
        return "BruteTour()"
