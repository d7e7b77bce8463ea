"""Sharing and tours solved jointly by OR-Tools' vehicle routing solver, the second classical peer.

PyVRP's model (:mod:`planners.peers.pyvrp_routing`), the arc costs one transit matrix; a first solution by
``PATH_CHEAPEST_ARC``, then guided local search, within ``seconds`` and/or ``solutions``. A classical layer
(CPU x 15 W, one thread). Design notes: docs/design/pyvrp.md#the-or-tools-layers-contract.
"""

from __future__ import annotations

import time

import numpy as np

try:
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2
except ImportError as exc:  # pragma: no cover - exercised in a subprocess without ortools
    raise ImportError("OR-Tools is not installed: pip install 'mrmt-ising[peers]'") from exc

from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport
from planners.peers.common import check_budget, routing_input

__all__ = ["ORToolsSharing", "DEFAULT_SECONDS", "FORBIDDEN"]

#: Default time budget of one solve (seconds).
DEFAULT_SECONDS = 1.0
#: Cost of an arc between cells of different components (above any route of a reachable plan).
FORBIDDEN = 1 << 40


class ORToolsSharing:
    """Sharing layer ``ortools``: OR-Tools routing (guided local search) on the whole problem.

    Args:
        seconds: time budget (``> 0``, at most one hour), or None for none.
        solutions: solution budget (``>= 1``: the first solution and the improvements after it),
            or None for none.  At least one is required.
    """

    name = "ortools"
    #: groups come in visiting order (:mod:`planners.joint_routing`; use tour layer ``keep``)
    orders_routes = True

    def __init__(self, seconds: float | None = DEFAULT_SECONDS, solutions: int | None = None) -> None:
        self.seconds, self.solutions = check_budget("ortools", seconds, "solutions", solutions)

    def _parameters(self):
        params = pywrapcp.DefaultRoutingSearchParameters()
        params.first_solution_strategy = routing_enums_pb2.FirstSolutionStrategy.PATH_CHEAPEST_ARC
        params.local_search_metaheuristic = routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
        if self.seconds is not None:
            params.time_limit.FromMicroseconds(int(round(self.seconds * 1e6)))
        if self.solutions is not None:
            params.solution_limit = self.solutions
        return params

    def assign(self, dist: np.ndarray, n_robots: int, tour: TourSolver | None = None,
               rng: np.random.Generator | None = None) -> SharingResult:
        d, r, done = routing_input(dist, n_robots)
        if done is not None:
            return done
        empty = tuple(() for _ in range(r))
        size = d.shape[0] + 1  # nodes: robots 0..R-1, targets R..R+N-1, the dummy end R+N
        m = np.zeros((size, size), dtype=np.int64)
        m[:-1, :-1] = np.where(np.isfinite(d), d, FORBIDDEN).astype(np.int64)
        m[:, -1] = 0
        manager = pywrapcp.RoutingIndexManager(size, r, list(range(r)), [size - 1] * r)
        routing = pywrapcp.RoutingModel(manager)
        routing.SetArcCostEvaluatorOfAllVehicles(routing.RegisterTransitMatrix(m.tolist()))
        t0 = time.perf_counter()
        solution = routing.SolveWithParameters(self._parameters())
        ran_out = self.seconds is not None and time.perf_counter() - t0 >= 0.99 * self.seconds
        stats = {"solver": {"name": "ortools", "stopped_by": "time" if ran_out or self.solutions is None
                            else "solutions", "cost": None}}
        if solution is None:
            return SharingResult(assignment=empty, stats=stats, failure=f"OR-Tools found no solution "
                                                                        f"(status {routing.status()})")
        groups = []
        for k in range(r):
            idx, group = solution.Value(routing.NextVar(routing.Start(k))), []
            while not routing.IsEnd(idx):
                group.append(manager.IndexToNode(idx) - r)
                idx = solution.Value(routing.NextVar(idx))
            groups.append(tuple(group))
        cost = int(solution.ObjectiveValue())
        stats["solver"]["cost"] = cost
        if cost >= FORBIDDEN:
            return SharingResult(assignment=empty, stats=stats,
                                 failure=f"OR-Tools found no solution without a forbidden arc (cost {cost})")
        return SharingResult(assignment=tuple(groups), compute=ComputeReport(), stats=stats)

    def __repr__(self) -> str:
        return f"ORToolsSharing(seconds={self.seconds!r}, solutions={self.solutions!r})"
