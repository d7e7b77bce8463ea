"""Joint routing: a sharing layer that also orders each robot's targets, and the tour layer that keeps that order.

A sharing layer with ``orders_routes = True`` (a vehicle routing solver, :mod:`planners.peers.pyvrp_routing`)
gives its groups in visiting order; the tour layer ``keep`` (:class:`KeepOrderTour`) hands that order on
unchanged. Design notes: docs/design/pyvrp.md#joint-routing.
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
