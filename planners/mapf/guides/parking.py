"""Parking places: robots without a goal leave the traffic and wait where few routes pass (issue 57, item 3).

Contract: ``ParkingPlaces(nbr, share, seed)`` over the compact grid ``nbr`` (``(n, 4)`` neighbours, -1 none).
:attr:`ParkingPlaces.traffic` is each cell's through-traffic: over :data:`PARKING_SOURCES` sources drawn from the
seed, the mean number of cells whose BFS-tree path from the source passes it (its BFS subtree's size, itself
included).  The ``share`` of free cells with the least traffic are the parking places (ties: the lower index
first); :attr:`ParkingPlaces.goal_of` ``[c]`` is the parking place nearest cell ``c`` by moves (a multi-source
BFS from all of them, ties by BFS order; ``c`` itself on a parking place; -1 where none is reachable).
A one-step planner with parking sends a robot whose goal is its own cell (no task) to ``goal_of`` its cell.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from planners.mapf.guides.guidance import spread

__all__ = ["ParkingPlaces", "PARKING_SOURCES"]

#: BFS sources of the through-traffic estimate.
PARKING_SOURCES = 32


@njit(cache=True)
def _subtree_traffic(nbr, sources, out):  # pragma: no cover - compiled
    n = nbr.shape[0]
    parent = np.empty(n, dtype=np.int64)
    order = np.empty(n, dtype=np.int64)
    size = np.empty(n, dtype=np.float64)
    for s in sources:
        parent[:] = -2
        parent[s] = -1
        order[0] = s
        head, tail = 0, 1
        while head < tail:
            u = order[head]
            head += 1
            for d in range(4):
                v = nbr[u, d]
                if v >= 0 and parent[v] == -2:
                    parent[v] = u
                    order[tail] = v
                    tail += 1
        for i in range(tail):
            size[order[i]] = 1.0
        for i in range(tail - 1, 0, -1):  # children before parents: each subtree's size
            u = order[i]
            size[parent[u]] += size[u]
        for i in range(tail):
            out[order[i]] += size[order[i]]


@njit(cache=True)
def _nearest(nbr, park, goal_of):  # pragma: no cover - compiled
    n = nbr.shape[0]
    queue = np.empty(n, dtype=np.int64)
    tail = 0
    for c in range(n):
        goal_of[c] = -1
        if park[c]:
            goal_of[c] = c
            queue[tail] = c
            tail += 1
    spread(nbr, goal_of, -1, queue, tail, 0)  # each cell the nearest place's cell


class ParkingPlaces:
    """The parking places of a compact grid (module docstring)."""

    def __init__(self, nbr: np.ndarray, share: float, seed: int = 0) -> None:
        if isinstance(share, bool) or not isinstance(share, (int, float)) or not 0 < share <= 1:
            raise ValueError(f"park = {share!r} must be the share of free cells that are parking places, in (0, 1]")
        nbr = np.ascontiguousarray(nbr, dtype=np.int64)
        n = nbr.shape[0]
        rng = np.random.default_rng(seed)
        sources = np.sort(rng.choice(n, size=min(PARKING_SOURCES, n), replace=False)).astype(np.int64)
        traffic = np.zeros(n, dtype=np.float64)
        _subtree_traffic(nbr, sources, traffic)
        self.traffic = traffic / len(sources)
        count = max(int(round(share * n)), 1)
        self.park = np.zeros(n, dtype=np.bool_)
        self.park[np.argsort(self.traffic, kind="stable")[:count]] = True
        self.goal_of = np.empty(n, dtype=np.int64)
        _nearest(nbr, self.park, self.goal_of)

    def goals(self, pos: np.ndarray, goals: np.ndarray, cid: np.ndarray, cell_of: np.ndarray) -> np.ndarray:
        """``goals`` (flat cells) with each robot whose goal is its own cell ``pos`` sent to the parking place
        nearest it (it stays where none is reachable); ``cid`` / ``cell_of`` map flat and compact cells."""
        idle = np.flatnonzero(goals == pos)
        if not len(idle):
            return goals
        place = self.goal_of[cid[pos[idle]]]
        out = goals.copy()
        out[idle] = np.where(place >= 0, cell_of[np.maximum(place, 0)], pos[idle])
        return out
