"""PIBT: priority inheritance with backtracking (Okumura, Machida, Defago, Tamura, IJCAI 2019), compiled.

One call plans one conflict-free joint move (no two robots in one cell, no two exchange cells):
:meth:`PIBT.step` ``(pos, goals) -> next cells`` (flat cells ``r * W + c``), :meth:`PIBT.actions` the same as env
actions 0..4. The Python oracle in ``tests/test_mapf.py`` is the recursive form and must give the same moves.
Design notes (priorities, ties): docs/design/lifelong.md#pibt-on-the-grid.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.mapf.common import GoalFields, mix, moves_to_actions, pibt_core, sort_options, successor_table

__all__ = ["PIBT", "pibt_kernel", "candidates"]

_FAR = np.int64(1 << 40)


@numba.njit(cache=True, nogil=True)
def candidates(succ, pos_a, field, seed, t, a, out) -> int:
    """Distinct cells robot ``a`` may take from ``pos_a`` (stay included), nearest to its goal first,
    ties by ``mix(seed, t, a, cell)``; written to ``out[:n]``, returns ``n``."""
    keys = np.empty(5, dtype=np.int64)
    ties = np.empty(5, dtype=np.uint64)
    n = 0
    for m in range(5):
        v = succ[pos_a, m]
        dup = False
        for i in range(n):
            if out[i] == v:
                dup = True
        if dup:
            continue
        d = field[v]
        keys[n] = _FAR if d < 0 else d
        ties[n] = mix(seed, t, a, v)
        out[n] = v
        n += 1
    sort_options(n, out, keys, np.zeros(5, dtype=np.int64), ties)
    return n


@numba.njit(cache=True, nogil=True)
def pibt_kernel(succ, pos, fields, rows, order, seed, t, nxt, occ_now, occ_next) -> None:
    """One PIBT step: ``nxt[k]`` = robot ``k``'s next cell.  ``fields[rows[k]]`` is robot ``k``'s goal
    distance field, ``order`` the robots by decreasing priority; ``occ_now`` / ``occ_next`` are
    scratch arrays over cells, all -1 on entry and on return."""
    r = pos.shape[0]
    cand = np.empty((r, 5), dtype=np.int64)
    ncand = np.empty(r, dtype=np.int64)
    for k in range(r):
        occ_now[pos[k]] = k
        nxt[k] = -1
        ncand[k] = candidates(succ, pos[k], fields[rows[k]], seed, t, k, cand[k])
    pibt_core(pos, order, (cand, ncand), nxt, (occ_now, occ_next))
    for k in range(r):
        occ_now[pos[k]] = -1
        occ_next[nxt[k]] = -1


class PIBT:
    """PIBT on one grid (see the module docstring).

    Args:
        grid: ``(H, W)`` bool obstacles.
        seed: tie-breaks (robot priorities and equal-distance cells).
    """

    name = "pibt"

    def __init__(self, grid: np.ndarray, seed: int = 0) -> None:
        self.grid = np.asarray(grid, dtype=bool)
        self.succ = successor_table(self.grid)
        self.fields = GoalFields(self.grid)
        self.seed = int(seed) & ((1 << 63) - 1)
        self.t = 0
        self.elapsed = np.zeros(0, dtype=np.int64)
        self.tie = np.zeros(0)
        n = self.grid.size
        self._occ_now = np.full(n, -1, dtype=np.int64)
        self._occ_next = np.full(n, -1, dtype=np.int64)

    def _ensure(self, n_robots: int) -> None:
        if len(self.elapsed) != n_robots:
            self.elapsed = np.zeros(n_robots, dtype=np.int64)
            rng = np.random.default_rng(self.seed)
            self.tie = rng.random(n_robots)
            self.t = 0

    def order(self, n_robots: int) -> np.ndarray:
        """The ``n_robots`` robots by decreasing priority (``elapsed + tie``)."""
        self._ensure(n_robots)
        return np.lexsort((-self.tie, -self.elapsed)).astype(np.int64)

    def step(self, pos, goals) -> np.ndarray:
        """Next cells ``(R,)`` of robots at flat cells ``pos`` heading to flat ``goals`` (a robot without
        a task takes its own cell as goal); advances the priorities."""
        pos = np.ascontiguousarray(pos, dtype=np.int64)
        goals = np.ascontiguousarray(goals, dtype=np.int64)
        self._ensure(len(pos))
        rows = self.fields.rows(goals)
        nxt = np.empty(len(pos), dtype=np.int64)
        pibt_kernel(self.succ, pos, self.fields.fields, rows, self.order(len(pos)), self.seed, self.t, nxt,
                    self._occ_now, self._occ_next)
        self.elapsed = np.where(nxt == goals, 0, self.elapsed + 1)
        self.t += 1
        return nxt

    def actions(self, pos, goals) -> np.ndarray:
        """:meth:`step` as env actions (0 stay, 1 up, 2 down, 3 left, 4 right)."""
        pos = np.asarray(pos, dtype=np.int64)
        return moves_to_actions(self.succ, pos, self.step(pos, goals))
