"""Shared pieces of the one-step MAPF executors: the move table, goal distance fields and tie-break hashes.

* :func:`successor_table` -- ``succ[p, a]``: the flat cell action ``a`` (0 stay, 1 up, 2 down,
  3 left, 4 right; :data:`mrmt_env.distances.MOVES`) leads to from cell ``p`` (``p`` itself when blocked).
* :class:`GoalFields` -- BFS distance fields to goal cells, computed once per goal with the compiled
  BFS of :mod:`mrmt_env.distances` and kept in one ``(F, H*W)`` array (cleared when full).
* :func:`mix` -- SplitMix64 of four integers: the executors' seeded tie-breaks, reproducible by
  the Python oracles in ``tests/``.
"""

from __future__ import annotations

import numba
import numpy as np

from mrmt_env.distances import bfs_flat

__all__ = ["successor_table", "GoalFields", "mix", "moves_to_actions", "compact_grid"]

_DR = (0, 1, 0, -1)  # east, south, west, north
_DC = (1, 0, -1, 0)

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


@numba.njit(cache=True, nogil=True)
def _splitmix(z):
    z = z + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@numba.njit(cache=True, nogil=True)
def mix(seed, a, b, c):
    """A 64-bit hash of ``(seed, a, b, c)`` (non-negative ints), chained SplitMix64."""
    z = _splitmix(np.uint64(seed))
    z = _splitmix(z ^ np.uint64(a))
    z = _splitmix(z ^ np.uint64(b))
    return _splitmix(z ^ np.uint64(c))


@numba.njit(cache=True, nogil=True)
def _succ(flat_grid, width, out):
    n = flat_grid.shape[0]
    h = n // width
    for p in range(n):
        r, c = p // width, p % width
        out[p, 0] = p
        for m in range(4):
            nr = r + (-1, 1, 0, 0)[m]
            nc = c + (0, 0, -1, 1)[m]
            if 0 <= nr < h and 0 <= nc < width and not flat_grid[nr * width + nc]:
                out[p, m + 1] = nr * width + nc
            else:
                out[p, m + 1] = p


def successor_table(grid: np.ndarray) -> np.ndarray:
    """``(H*W, 5)`` int64: the cell each action leads to (blocked moves stay)."""
    grid = np.ascontiguousarray(grid, dtype=np.bool_)
    out = np.empty((grid.size, 5), dtype=np.int64)
    _succ(grid.reshape(-1), grid.shape[1], out)
    return out


@numba.njit(cache=True, nogil=True)
def _fill(flat_grid, width, goals, rows, fields):
    queue = np.empty(flat_grid.shape[0], dtype=np.int64)
    for i in range(goals.shape[0]):
        f = fields[rows[i]]
        f[:] = -1
        f[goals[i]] = 0
        queue[0] = goals[i]
        bfs_flat(flat_grid, width, f, queue, 1)


class GoalFields:
    """Distance fields to goal cells of one grid: ``rows(goals)`` gives each goal's row of :attr:`fields`
    (``fields[row, p]`` = moves from ``p`` to the goal, -1 unreachable)."""

    def __init__(self, grid: np.ndarray, capacity: int = 1024) -> None:
        self.grid = np.ascontiguousarray(grid, dtype=np.bool_).reshape(-1)
        self.width = int(np.asarray(grid).shape[1])
        self.capacity = max(int(capacity), 1)
        self.fields = np.empty((self.capacity, self.grid.size), dtype=np.int32)
        self._row: dict[int, int] = {}

    def rows(self, goals: np.ndarray) -> np.ndarray:
        """Row of each goal cell (flat), computing the missing fields in one compiled call."""
        goals = np.asarray(goals, dtype=np.int64)
        uniq = np.unique(goals).tolist()
        if len(uniq) > self.capacity:
            self.capacity = 2 * len(uniq)
            self.fields = np.empty((self.capacity, self.grid.size), dtype=np.int32)
            self._row.clear()
        missing = [g for g in uniq if g not in self._row]
        if len(self._row) + len(missing) > self.capacity:  # full: keep only the goals asked for now
            keep = [g for g in uniq if g in self._row]
            old = self.fields[[self._row[g] for g in keep]] if keep else None
            self._row = {g: i for i, g in enumerate(keep)}
            if keep:
                self.fields[:len(keep)] = old
        if missing:
            start = len(self._row)
            for i, g in enumerate(missing):
                self._row[g] = start + i
            _fill(self.grid, self.width, np.array(missing, dtype=np.int64),
                  np.arange(start, start + len(missing), dtype=np.int64), self.fields)
        return np.array([self._row[g] for g in goals.tolist()], dtype=np.int64)


@numba.njit(cache=True, nogil=True)
def _actions(succ, pos, nxt, out):
    for k in range(pos.shape[0]):
        out[k] = 0
        for a in range(1, 5):
            if succ[pos[k], a] == nxt[k] and nxt[k] != pos[k]:
                out[k] = a


def moves_to_actions(succ: np.ndarray, pos: np.ndarray, nxt: np.ndarray) -> np.ndarray:
    """``(R,)`` int64 actions taking each robot from ``pos`` to ``nxt`` (flat cells, equal or neighbours)."""
    out = np.empty(len(pos), dtype=np.int64)
    _actions(succ, np.asarray(pos, dtype=np.int64), np.asarray(nxt, dtype=np.int64), out)
    return out


@numba.njit(cache=True, nogil=True)
def _neighbours(flat_grid, width, cid, nbr):
    h = flat_grid.shape[0] // width
    for p in range(flat_grid.shape[0]):
        i = cid[p]
        if i < 0:
            continue
        r, c = p // width, p % width
        for d in range(4):
            nr, nc = r + _DR[d], c + _DC[d]
            nbr[i, d] = -1
            if 0 <= nr < h and 0 <= nc < width:
                q = nr * width + nc
                if not flat_grid[q]:
                    nbr[i, d] = cid[q]


def compact_grid(grid: np.ndarray):
    """``(cid, cell_of, nbr)``: compact index of each flat cell (-1 blocked), the flat cell of each
    compact index, and ``nbr[i, d]`` the compact neighbour of ``i`` in direction ``d`` (0 east,
    1 south, 2 west, 3 north; -1 off the map or blocked -- a row end does not wrap)."""
    flat = np.ascontiguousarray(grid, dtype=np.bool_).reshape(-1)
    cell_of = np.flatnonzero(~flat).astype(np.int64)
    cid = np.full(flat.size, -1, dtype=np.int64)
    cid[cell_of] = np.arange(len(cell_of))
    nbr = np.empty((len(cell_of), 4), dtype=np.int32)
    _neighbours(flat, int(np.asarray(grid).shape[1]), cid, nbr)
    return cid, cell_of, nbr
