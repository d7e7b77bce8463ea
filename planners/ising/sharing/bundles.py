"""Bundle pricing of Ising target sharing (paper 5.3, last step) -- host side.

Contract: :class:`BundlePricer` prices robots' target sets with any pricing tour other than ``"auto"``
(a callback of the compiled search, which prices ``"auto"`` itself: Held-Karp up to 13 targets, a host
3-opt tour beyond), memoised per (robot, set), its compute reports summed so nothing is hidden.
Design notes: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import numpy as np

from planners.compute import ComputeReport
from planners.held_karp import MAX_BRUTE_TARGETS, _exact_route_cost

__all__ = ["SharingFailure", "BundlePricer"]


class SharingFailure(RuntimeError):
    """Internal: a split could not be mapped or solved (becomes a failure result)."""


class BundlePricer:
    """Route cost of robot ``k`` over a set of global target nodes, by the pricing tour (cached)."""

    def __init__(self, dist: np.ndarray, tour, pricing_tour, rng: np.random.Generator, stats: dict):
        self.dist = dist
        self.rng = rng
        self.stats = stats
        self.compute = ComputeReport()
        self._cache: dict = {}
        self._exact = pricing_tour == "auto"  # Held-Karp up to MAX_BRUTE_TARGETS, host 3-opt beyond
        if pricing_tour == "auto":
            from planners import registry

            beyond = registry.create("tour", "3opt")
            self._pricer = lambda n: beyond  # noqa: E731
        elif pricing_tour == "downstream":
            self._pricer = lambda n: tour  # noqa: E731
        else:
            if isinstance(pricing_tour, str):
                from planners import registry

                pricing_tour = registry.create("tour", pricing_tour)
            self._pricer = lambda n: pricing_tour  # noqa: E731

    def cost(self, k: int, targets) -> float:
        """Route cost of robot ``k`` over ``targets`` (global node indices)."""
        mask = 0
        for t in targets:
            mask |= 1 << t
        return self.cost_mask(k, mask, targets)

    def cost_mask(self, k: int, mask: int, targets) -> float:
        """:meth:`cost` for a caller that keeps the set's bit mask (``sum(1 << t)``) itself."""
        key = (k, mask)
        hit = self._cache.get(key)
        if hit is None:
            if not targets:
                hit = 0.0
            elif self._exact and len(targets) <= MAX_BRUTE_TARGETS:  # exact_route_cost's kernel, dist is float64
                hit = float(_exact_route_cost(self.dist, np.array([k] + sorted(targets), dtype=np.int64)))
                self.stats["tour_solves"] += 1
            else:
                nodes = [k] + sorted(targets)
                res = self._pricer(len(targets)).solve(self.dist[np.ix_(nodes, nodes)], self.rng)
                self.compute = self.compute + res.compute
                self.stats["tour_solves"] += 1
                if getattr(res, "failure", None):
                    raise SharingFailure(f"tour solver failed while pricing a bundle: {res.failure}")
                hit = float(res.cost)
            self._cache[key] = hit
        return hit
