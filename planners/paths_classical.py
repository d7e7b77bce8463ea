"""Classical grid pathfinding baselines (paper section 6.1): BFS, A*, GBFS.

:class:`BFSPath`, :class:`AStarPath` (Manhattan heuristic: shortest paths) and :class:`GreedyBestFirstPath` (not
optimal) search the 4-neighbour grid from ``start`` to ``goal`` and return the path, both ends included; an
unreachable or invalid goal is a failure :class:`~planners.base.PathResult`, never an invalid path.
Design notes (tie-breaking, stopping): docs/design/classical_baselines.md#grid-pathfinding.
"""

from __future__ import annotations

import heapq

import numba
import numpy as np

from mrmt_env.world import World
from planners.base import PathResult

__all__ = ["BFSPath", "AStarPath", "GreedyBestFirstPath", "grid_search"]

_BFS, _ASTAR, _GBFS = 0, 1, 2


@numba.njit(cache=True, nogil=True, inline="always")
def _neighbour(grid, cur, m):
    """Flat index of the free neighbour of cell ``cur`` in direction ``m`` (up, down, left, right), or -1."""
    h, w = grid.shape
    nr = cur // w + (-1, 1, 0, 0)[m]
    nc = cur % w + (0, 0, -1, 1)[m]
    if 0 <= nr < h and 0 <= nc < w and not grid[nr, nc]:
        return nr * w + nc
    return -1


@numba.njit(cache=True, nogil=True)
def _search(grid, sr, sc, gr, gc, mode):
    """Search from (sr, sc) to (gr, gc).  Returns (path (L+1, 2) int64, expanded).

    ``path`` has zero rows when the goal is unreachable.
    """
    h, w = grid.shape
    n = h * w
    parent = np.full(n, -1, dtype=np.int64)
    g = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    start = sr * w + sc
    goal = gr * w + gc
    g[start] = 0
    expanded = 0
    found = start == goal
    if mode == _BFS:
        queue = np.empty(n, dtype=np.int64)
        head = 0
        tail = 1
        queue[0] = start
        while head < tail and not found:
            cur = queue[head]
            head += 1
            expanded += 1
            for m in range(4):
                nxt = _neighbour(grid, cur, m)
                if nxt >= 0 and g[nxt] < 0:
                    g[nxt] = g[cur] + 1
                    parent[nxt] = cur
                    if nxt == goal:
                        found = True
                        break
                    queue[tail] = nxt
                    tail += 1
    else:
        # heap entries: (primary key, secondary key, insertion counter, cell)
        counter = 0
        hs = abs(sr - gr) + abs(sc - gc)
        heap = [(hs, 0, counter, start)]
        while len(heap) > 0 and not found:
            item = heapq.heappop(heap)
            cur = item[3]
            if closed[cur]:
                continue
            closed[cur] = True
            expanded += 1
            if cur == goal:
                found = True
                break
            for m in range(4):
                nxt = _neighbour(grid, cur, m)
                if nxt < 0 or closed[nxt]:
                    continue
                ng = g[cur] + 1
                if g[nxt] >= 0 and (mode == _GBFS or ng >= g[nxt]):
                    continue  # GBFS: first discovery fixes the parent
                g[nxt] = ng
                parent[nxt] = cur
                hn = abs(nxt // w - gr) + abs(nxt % w - gc)
                counter += 1
                if mode == _ASTAR:
                    heapq.heappush(heap, (ng + hn, -ng, counter, nxt))
                else:
                    heapq.heappush(heap, (hn, 0, counter, nxt))
    if not found:
        return np.empty((0, 2), dtype=np.int64), expanded
    length = g[goal]
    path = np.empty((length + 1, 2), dtype=np.int64)
    cur = goal
    for i in range(length, -1, -1):
        path[i, 0] = cur // w
        path[i, 1] = cur % w
        cur = parent[cur]
    return path, expanded


def _cell(x) -> tuple[int, int]:
    return int(x[0]), int(x[1])


def grid_search(grid: np.ndarray, start, goal, mode: int) -> PathResult:
    """Run one search on a bool obstacle grid (shared by the three classes)."""
    h, w = grid.shape
    (sr, sc), (gr, gc) = _cell(start), _cell(goal)
    for name, (r, c) in (("start", (sr, sc)), ("goal", (gr, gc))):
        if not (0 <= r < h and 0 <= c < w):
            return PathResult(None, failure=f"{name} cell [{r}, {c}] is off the {h}x{w} grid")
        if grid[r, c]:
            return PathResult(None, failure=f"{name} cell [{r}, {c}] is an obstacle")
    path, expanded = _search(grid, sr, sc, gr, gc, mode)
    stats = {"expanded": int(expanded)}
    if len(path) == 0:
        return PathResult(
            None,
            failure=f"no 4-neighbour path from [{sr}, {sc}] to [{gr}, {gc}] (goal unreachable)",
            stats=stats,
        )
    return PathResult(path, stats=stats)


class _GridSearch:
    name = ""
    _mode = _BFS

    def find_path(self, world: World, start, goal, rng: np.random.Generator | None = None) -> PathResult:
        """A 4-neighbour path on ``world.grid`` from ``start`` to ``goal`` (``rng`` unused)."""
        return grid_search(world.grid, start, goal, self._mode)

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class BFSPath(_GridSearch):
    """Breadth-first search: a shortest path (see module docstring)."""

    name = "bfs"
    _mode = _BFS


class AStarPath(_GridSearch):
    """A* with the Manhattan heuristic: a shortest path (see module docstring)."""

    name = "astar"
    _mode = _ASTAR


class GreedyBestFirstPath(_GridSearch):
    """Greedy best-first search on Manhattan distance: valid, not always shortest."""

    name = "gbfs"
    _mode = _GBFS
