"""Sharing and tours solved jointly by PyVRP, the vehicle routing solver a user would pick.

One vehicle per robot starting at its cell, a shared dummy end depot (open routes), the world's BFS distances as
integer edges; a budget of ``seconds`` and/or ``iterations`` (stopped by iterations, a plan is the same on any
machine), the one that stopped the search in ``stats["solver"]``. A classical layer (CPU x 15 W, one thread).
Design notes: docs/design/pyvrp.md#the-pyvrp-layers-contract.
"""

from __future__ import annotations

import numpy as np

try:
    import pyvrp
    from pyvrp.constants import MAX_VALUE
    from pyvrp.stop import MaxIterations, MaxRuntime, MultipleCriteria
except ImportError as exc:  # pragma: no cover - exercised in a subprocess without pyvrp
    raise ImportError("PyVRP is not installed: pip install 'mrmt-ising[peers]'") from exc

from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport
from planners.peers.common import check_budget, routing_input

__all__ = ["PyVRPSharing", "routing_data", "DEFAULT_SECONDS"]

#: Default time budget of one solve (seconds).
DEFAULT_SECONDS = 1.0


def routing_data(dist: np.ndarray, n_robots: int) -> "pyvrp.ProblemData":
    """PyVRP's problem data of the open multi-depot routing problem (module docstring).

    Locations: robots ``0..R-1`` (start depots), the dummy end depot ``R``, targets
    ``R+1..R+N`` (clients ``0..N-1``).
    """
    d = np.asarray(dist, dtype=np.float64)
    r = int(n_robots)
    n = d.shape[0] - r
    size = r + 1 + n
    m = np.full((size, size), MAX_VALUE, dtype=np.int64)
    idx = np.concatenate([np.arange(r), r + 1 + np.arange(n)])
    finite = np.isfinite(d)
    sub = np.where(finite, d, MAX_VALUE).astype(np.int64)
    m[np.ix_(idx, idx)] = sub
    m[:, r] = 0              # anything -> dummy end depot: free (open routes)
    m[r, :] = MAX_VALUE      # the dummy depot is a dead end
    m[:, :r] = MAX_VALUE     # nothing enters a start depot
    np.fill_diagonal(m, 0)
    locations = [pyvrp.Location(x=0, y=0) for _ in range(size)]
    depots = [pyvrp.Depot(location=i) for i in range(r + 1)]
    clients = [pyvrp.Client(location=r + 1 + j) for j in range(n)]
    vehicles = [pyvrp.VehicleType(num_available=1, start_depot=k, end_depot=r) for k in range(r)]
    return pyvrp.ProblemData(locations, clients, depots, vehicles, [m], [np.zeros_like(m)])


class PyVRPSharing:
    """Sharing layer ``pyvrp``: PyVRP's iterated local search on the whole routing problem.

    Args:
        seconds: time budget of the search (``> 0``, at most one hour), or None for none.
        iterations: iteration budget (``>= 1``), or None for none.  At least one is required.
    """

    name = "pyvrp"
    #: groups come in visiting order (:mod:`planners.joint_routing`; use tour layer ``keep``)
    orders_routes = True

    def __init__(self, seconds: float | None = DEFAULT_SECONDS, iterations: int | None = None) -> None:
        self.seconds, self.iterations = check_budget("pyvrp", seconds, "iterations", iterations)

    def _stop(self):
        criteria = []
        if self.iterations is not None:
            criteria.append(MaxIterations(self.iterations))
        if self.seconds is not None:
            criteria.append(MaxRuntime(self.seconds))
        return criteria[0] if len(criteria) == 1 else MultipleCriteria(criteria)

    def assign(self, dist: np.ndarray, n_robots: int, tour: TourSolver | None = None,
               rng: np.random.Generator | None = None) -> SharingResult:
        d, r, done = routing_input(dist, n_robots)
        if done is not None:
            return done
        n = d.shape[0] - r
        empty = tuple(() for _ in range(r))
        rng = rng if rng is not None else np.random.default_rng()
        seed = int(rng.integers(0, 2**31 - 1))
        result = pyvrp.solve(routing_data(d, r), stop=self._stop(), seed=seed, collect_stats=False, display=False)
        cost = int(result.cost()) if result.is_feasible() else None
        stopped = ("iterations" if self.iterations is not None and result.num_iterations >= self.iterations
                   else "time")
        stats = {"solver": {"name": "pyvrp", "stopped_by": stopped, "iterations": int(result.num_iterations),
                            "cost": cost}}
        groups: list[tuple[int, ...]] = [() for _ in range(r)]
        for route in result.best.routes():
            groups[route.vehicle_type()] = tuple(int(a.idx) for a in route if a.is_client())
        if cost is None or cost >= MAX_VALUE or sum(map(len, groups)) != n:
            return SharingResult(assignment=empty, stats=stats,
                                 failure=f"PyVRP found no solution without a forbidden arc (cost {result.cost()})")
        return SharingResult(assignment=tuple(groups), compute=ComputeReport(), stats=stats)

    def __repr__(self) -> str:
        return f"PyVRPSharing(seconds={self.seconds!r}, iterations={self.iterations!r})"
