"""Joint routing: a sharing layer that also orders each robot's targets, and the tour layer
that keeps that order.

A routing solver that assigns and sequences targets in one search (a vehicle routing
solver such as PyVRP, :mod:`planners.peers.pyvrp_routing`) is a *sharing* layer whose groups
come in visiting order; it says so with the class attribute ``orders_routes = True``.  The
pipeline then calls it even for a one-robot world (it otherwise skips sharing there), and the
tour layer ``keep`` (:class:`KeepOrderTour`) hands the given order on unchanged, so the
routes are the solver's and the tour layer costs nothing.

``keep`` after a sharing layer that does not order its groups keeps whatever order that layer
lists them in (target index order for PSA, insertion order for SSA): legal, rarely good.
"""

from __future__ import annotations

import numpy as np

from planners.base import TourResult

__all__ = ["KeepOrderTour"]


class KeepOrderTour:
    """Tour layer ``keep``: the open route visits nodes ``1..n`` in the order given."""

    name = "keep"

    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        d = np.asarray(dist, dtype=np.float64)
        if d.ndim != 2 or d.shape[0] != d.shape[1] or d.shape[0] < 1:
            raise ValueError(f"tour dist must be a square (n+1, n+1) matrix with n >= 0, got shape {d.shape}")
        n = d.shape[0] - 1
        route = np.arange(n + 1)
        return TourResult(order=tuple(range(1, n + 1)), cost=float(d[route[:-1], route[1:]].sum()))

    def __repr__(self) -> str:
        return "KeepOrderTour()"
