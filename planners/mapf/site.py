"""What every planner with turning stands on: the map as compact cells (:class:`TurnSite`, with the check of a call's
robots) and PIBT's priorities (:class:`Priorities`: steps since the goal, a seeded tie-breaker, the step count).

Contract: ``TurnSite(grid)``; :meth:`TurnSite.check` ``(pos, orient, goals) -> int64 arrays`` or ``ValueError``
naming the robot and the value.  ``Priorities(seed, dead_end)``; :meth:`Priorities.order` ``(R) -> robots by
decreasing priority``; :meth:`Priorities.advance` ``(moved, gc)`` after a step.
"""

from __future__ import annotations

import numpy as np

from planners.mapf.common import compact_grid

__all__ = ["TurnSite", "Priorities", "DEAD_END_BONUS", "int_array"]

#: Extra priority per step spent in a dead end off the goal (the start kit's value; without it a robot
#: leaving a dead end and a higher-priority robot entering it block each other for good).
DEAD_END_BONUS = 10


def int_array(name: str, values) -> np.ndarray:
    """``values`` as a 1-d int64 array; ``ValueError`` naming ``name`` for another shape or non-integers."""
    a = np.asarray(values)
    if a.ndim != 1:
        raise ValueError(f"{name} must be a 1-d array of ints, got shape {a.shape}")
    if a.dtype.kind not in "iu":
        if a.size and not (a.dtype.kind == "f" and np.all(np.isfinite(a)) and np.all(a == np.round(a))):
            raise ValueError(f"{name} must hold integers, got dtype {a.dtype}")
        a = a.astype(np.int64)
    return np.ascontiguousarray(a, dtype=np.int64)


class TurnSite:
    """``grid`` (``(H, W)`` bool obstacles) as compact free cells: :attr:`cid` (flat -> compact, -1 blocked),
    :attr:`cell_of` (compact -> flat), :attr:`nbr` (``(n, 4)`` the cell ahead per orientation, -1 none),
    :attr:`dead_end` (cells with one free neighbour)."""

    def __init__(self, grid) -> None:
        self.grid = np.asarray(grid, dtype=bool)
        if self.grid.ndim != 2:
            raise ValueError(f"grid must be 2-d (H, W), got shape {self.grid.shape}")
        self.width = int(self.grid.shape[1])
        self.cid, self.cell_of, self.nbr = compact_grid(self.grid)
        self.dead_end = (self.nbr >= 0).sum(axis=1) == 1

    def check(self, pos, orient, goals):
        """The robots' flat cells, orientations and flat goals as int64 arrays; ``ValueError`` naming the first
        robot off the map, on a blocked cell, sharing a cell, or with an orientation outside 0..3."""
        pos, orient, goals = int_array("pos", pos), int_array("orient", orient), int_array("goals", goals)
        if not (len(pos) == len(orient) == len(goals)):
            raise ValueError(f"pos, orient and goals need one entry per robot, got lengths "
                             f"{len(pos)}, {len(orient)}, {len(goals)}")
        n = self.grid.size
        for name, cells in (("pos", pos), ("goals", goals)):
            bad = np.flatnonzero((cells < 0) | (cells >= n))
            if len(bad):
                k = int(bad[0])
                raise ValueError(f"{name}[{k}] = {cells[k]} is off the map (flat cells 0..{n - 1})")
            bad = np.flatnonzero(self.cid[cells] < 0)
            if len(bad):
                k = int(bad[0])
                r, c = divmod(int(cells[k]), self.width)
                raise ValueError(f"{name}[{k}] = {cells[k]} (row {r}, col {c}) is a blocked cell")
        bad = np.flatnonzero((orient < 0) | (orient > 3))
        if len(bad):
            k = int(bad[0])
            raise ValueError(f"orient[{k}] = {orient[k]} is not an orientation 0..3 (east, south, west, north)")
        if len(pos) > 1:
            s = np.sort(pos)
            dup = np.flatnonzero(s[1:] == s[:-1])
            if len(dup):
                cell = int(s[dup[0]])
                who = np.flatnonzero(pos == cell)[:2].tolist()
                raise ValueError(f"robots {who[0]} and {who[1]} share cell {cell}")
        return pos, orient, goals


class Priorities:
    """PIBT's priorities of a team: ``elapsed`` (steps since the robot last stood on its goal, 1 +
    :data:`DEAD_END_BONUS` for a step ending in a dead end) + a seeded tie-breaker ``tie``; ``t`` counts the steps.
    A call with another team size starts them afresh."""

    def __init__(self, seed: int, dead_end: np.ndarray) -> None:
        self.seed = int(seed) & ((1 << 63) - 1)
        self.dead_end = dead_end
        self.t = 0
        self.elapsed = np.zeros(0, dtype=np.int64)
        self.tie = np.zeros(0)

    def ensure(self, n_robots: int) -> bool:
        """Start afresh for ``n_robots`` robots unless the team has that size; whether it did."""
        if len(self.elapsed) == n_robots:
            return False
        self.elapsed = np.zeros(n_robots, dtype=np.int64)
        self.tie = np.random.default_rng(self.seed).random(n_robots)
        self.t = 0
        return True

    def order(self, n_robots: int) -> np.ndarray:
        """The ``n_robots`` robots by decreasing priority (``elapsed + tie``)."""
        self.ensure(n_robots)
        return np.lexsort((-self.tie, -self.elapsed)).astype(np.int64)

    def advance(self, moved: np.ndarray, gc: np.ndarray) -> None:
        """Priorities after the robots reach compact cells ``moved`` (goals ``gc``); the next call's step."""
        extra = DEAD_END_BONUS * self.dead_end[moved]
        self.elapsed = np.where(moved == gc, 0, self.elapsed + 1 + extra)
        self.t += 1
