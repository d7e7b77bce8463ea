"""Windowed prioritized planning: space-time A* over a short window, one robot after another, compiled.

Each step, robots in decreasing priority (as :class:`~planners.mapf.pibt.grid.PIBT`:
steps since the goal was last reached, seeded ties) plan a path over the next
``window`` steps with A* over (cell, time) states, avoiding the cells and
the exchanges already reserved by higher-priority robots; beyond the window
the BFS distance to the goal is the cost to go (the rolling-horizon scheme of
windowed MAPF, e.g. Li et al., AAAI 2021).  Every plan spans the whole window
(cost = window + distance left; waiting on the goal is free), so a robot on
its goal steps aside when a higher-priority reservation needs the cell.  Only
the first move is executed; every step re-plans.

Safety of the executed move: while robot ``k`` plans, every robot not yet
planned keeps its current cell at time 1, so a lower-priority robot can always
stay; if its search finds no path it stays (reserving its cell).  Hence the
joint first move has no vertex and no swap conflict.  Among equal-cost paths
the one entering fewest cells other robots stand on now wins (so a robot does
not route through a robot resting on its goal when it can go round), then the
A* order (larger g, then insertion).
"""

from __future__ import annotations

import numba
import numpy as np

from planners.heap import pop, push
from planners.mapf.common import GoalFields, moves_to_actions, successor_table

__all__ = ["WindowedPlanner", "windowed_kernel", "DEFAULT_WINDOW", "MAX_WINDOW"]

DEFAULT_WINDOW = 8
MAX_WINDOW = 64
_FAR = 1 << 30
#: Cost unit of the A* key: cost * _SOFT + cells of other robots entered (a tie-break among equal costs).
_SOFT = 1024


@numba.njit(cache=True, nogil=True)
def _pop_unseen(heap, size, seen, stamp, parent) -> int:
    """Pop until an entry whose state this search (``stamp``) has not seen: it is marked seen, its parent
    recorded, and left at the returned index (the heap's new size); -1 when the heap runs out first."""
    while size > 0:
        size = pop(heap, size, 2, 4)
        s = heap[size, 2]
        if seen[s] != stamp:
            seen[s] = stamp
            parent[s] = heap[size, 3]
            return size
    return -1


@numba.njit(cache=True, nogil=True)
def windowed_kernel(succ, pos, goals, fields, rows, order, window, nxt, occ, seen, parent, stamp) -> int:
    """Plan every robot's window in ``order``; ``nxt[k]`` = its first move.  ``occ ((W+1)*HW)`` holds
    the robot reserving each (time, cell), -1 free; ``seen`` / ``parent`` are A* scratch over the same
    states, ``stamp`` the last stamp used (returned, incremented once per search)."""
    n_robots = pos.shape[0]
    hw = succ.shape[0]
    w = window
    cap = 5 * (w + 1) * hw + 1
    heap = np.empty((cap, 4), dtype=np.int64)  # planners.heap rows: f, -g (the key); state, parent
    soft = np.zeros((w + 1) * hw, dtype=np.int64)
    hold = np.full(hw, -1, dtype=np.int64)  # robots not planned yet keep their cell at time 1
    start = np.full(hw, -1, dtype=np.int64)  # every robot's cell now: crossing it is a soft cost
    for k in range(n_robots):
        hold[pos[k]] = k
        start[pos[k]] = k
    path = np.empty(w + 1, dtype=np.int64)
    for idx in range(n_robots):
        k = order[idx]
        field = fields[rows[k]]
        hold[pos[k]] = -1
        stamp += 1
        s0 = pos[k]  # state = t * hw + cell
        h0 = field[pos[k]]
        size = push(heap, 0, ((_FAR if h0 < 0 else h0) * _SOFT, 0, s0, -1), 2)
        best = -1
        while size > 0:
            size = _pop_unseen(heap, size, seen, stamp, parent)
            if size < 0:
                break
            f, s = heap[size, 0], heap[size, 2]
            soft[s] = f % _SOFT
            t, cell = s // hw, s % hw
            if t == w:  # every plan spans the window: a robot at its goal moves aside if a reservation needs it
                best = s
                break
            for m in range(5):
                v = succ[cell, m]
                if m > 0 and v == cell:
                    continue
                s2 = (t + 1) * hw + v
                if seen[s2] == stamp or occ[s2] != -1:
                    continue
                if t == 0 and hold[v] != -1:
                    continue
                j = occ[(t + 1) * hw + cell]  # the robot coming into my cell ...
                if j != -1 and v != cell and occ[t * hw + v] == j:  # ... from the cell I go to: a swap
                    continue
                sv = soft[s] + (1 if start[v] != -1 and start[v] != k and v != cell else 0)
                hv = field[v]
                f2 = (t + 1 + (_FAR if hv < 0 else hv)) * _SOFT + min(sv, _SOFT - 1)
                size = push(heap, size, (f2, -(t + 1), s2, s), 2)
        if best == -1:  # no path: stay, keep the cell where it is free
            for t in range(1, w + 1):
                if occ[t * hw + pos[k]] == -1:
                    occ[t * hw + pos[k]] = k
            nxt[k] = pos[k]
            continue
        s = best
        while s != -1:
            path[s // hw] = s % hw
            s = parent[s]
        for t in range(1, w + 1):
            occ[t * hw + path[t]] = k
        nxt[k] = path[1]
    return stamp


class WindowedPlanner:
    """Windowed prioritized planning on one grid (see the module docstring).

    Args:
        grid: ``(H, W)`` bool obstacles.
        seed: priority tie-breaks.
        window: planning horizon in steps (1..64, default 8).
    """

    name = "windowed"

    def __init__(self, grid: np.ndarray, seed: int = 0, window: int = DEFAULT_WINDOW) -> None:
        if isinstance(window, bool) or int(window) != window or not 1 <= window <= MAX_WINDOW:
            raise ValueError(f"window must be an integer in 1..{MAX_WINDOW}, got {window!r}")
        self.grid = np.asarray(grid, dtype=bool)
        self.window = int(window)
        self.succ = successor_table(self.grid)
        self.fields = GoalFields(self.grid)
        self.seed = int(seed) & ((1 << 63) - 1)
        self.elapsed = np.zeros(0, dtype=np.int64)
        self.tie = np.zeros(0)
        states = (self.window + 1) * self.grid.size
        self._occ = np.full(states, -1, dtype=np.int64)
        self._seen = np.zeros(states, dtype=np.int64)
        self._parent = np.zeros(states, dtype=np.int64)
        self._stamp = 0

    def _ensure(self, n_robots: int) -> None:
        if len(self.elapsed) != n_robots:
            self.elapsed = np.zeros(n_robots, dtype=np.int64)
            self.tie = np.random.default_rng(self.seed).random(n_robots)

    def step(self, pos, goals) -> np.ndarray:
        """Next cells ``(R,)`` (flat) of robots at ``pos`` heading to ``goals``; advances the priorities."""
        pos = np.ascontiguousarray(pos, dtype=np.int64)
        goals = np.ascontiguousarray(goals, dtype=np.int64)
        self._ensure(len(pos))
        rows = self.fields.rows(goals)
        order = np.lexsort((-self.tie, -self.elapsed)).astype(np.int64)
        nxt = np.empty(len(pos), dtype=np.int64)
        self._occ[:] = -1
        self._stamp = windowed_kernel(self.succ, pos, goals, self.fields.fields, rows, order, self.window, nxt,
                                      self._occ, self._seen, self._parent, self._stamp)
        self.elapsed = np.where(nxt == goals, 0, self.elapsed + 1)
        return nxt

    def actions(self, pos, goals) -> np.ndarray:
        """:meth:`step` as env actions (0 stay, 1 up, 2 down, 3 left, 4 right)."""
        pos = np.asarray(pos, dtype=np.int64)
        return moves_to_actions(self.succ, pos, self.step(pos, goals))
