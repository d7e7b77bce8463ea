"""Sharing on worlds of several connected components (host side of Ising target sharing).

Each component's targets are shared among that component's robots by the same Ising search; a
target no robot can reach, or a distance matrix that does not split into components, is a
failure naming the node.
"""

from __future__ import annotations

import numpy as np

from planners.base import SharingResult
from planners.compute import ComputeReport

__all__ = ["assign_components"]


def assign_components(assign, dist, R: int, tour, rng, stats) -> SharingResult:
    """Sharing on a world of several connected components (infinite distances between them):
    each component's targets are shared among that component's robots, one after another
    (a component with one robot takes all its targets, no chip call) by ``assign(dist, R, tour,
    rng)``, the sharing's own call.  A target no robot
    can reach is a failure naming it."""
    n = dist.shape[0]
    comp = np.full(n, -1, dtype=np.int64)
    for v in range(n):
        if comp[v] < 0:
            comp[np.isfinite(dist[v])] = v  # finite BFS distance: same component
    assignment: list[list[int]] = [[] for _ in range(R)]
    compute = ComputeReport()
    empty = tuple(() for _ in range(R))
    same = comp[:, None] == comp[None, :]
    if (same != np.isfinite(dist)).any():  # reachability must split the nodes into components
        i, j = (int(v) for v in np.argwhere(~np.isfinite(dist))[0])
        msg = (f"node {i} cannot reach node {j} (distance {dist[i, j]}), but the other distances join them: "
               "the distance matrix does not split into connected components")
        return SharingResult(assignment=empty, compute=compute, stats=stats, failure=msg)
    for c in np.unique(comp):
        robots = [v for v in range(R) if comp[v] == c]
        targets = [v for v in range(R, n) if comp[v] == c]
        if not targets:
            continue
        if not robots:
            msg = (f"target(s) {[t - R for t in targets]} cannot be reached by any robot "
                   f"(node {targets[0]} has infinite distance to every robot)")
            return SharingResult(assignment=empty, compute=compute, stats=stats, failure=msg)
        nodes = robots + targets
        res = assign(dist[np.ix_(nodes, nodes)], len(robots), tour, rng)
        compute = compute + res.compute
        _add_counts(stats, res.stats)
        if res.failure is not None:
            return SharingResult(assignment=empty, compute=compute, stats=stats,
                                 failure=f"component of robots {robots}: {res.failure}")
        for k, group in zip(robots, res.assignment):
            assignment[k].extend(targets[t] - R for t in group)
    stats["components"] = int(len(np.unique(comp)))
    return SharingResult(assignment=tuple(tuple(sorted(g)) for g in assignment), compute=compute, stats=stats)


def _add_counts(into: dict, new: dict) -> None:
    """Add the counters of ``new`` (numbers, nested dicts of numbers) into ``into``."""
    for key, value in new.items():
        if isinstance(value, dict):
            _add_counts(into.setdefault(key, {}), value)
        elif isinstance(value, (int, float)) and not isinstance(value, bool):
            into[key] = into.get(key, 0) + value
