"""Shared pieces of the one-step MAPF executors: the move table, goal distance fields and tie-break hashes.

* :func:`successor_table` -- ``succ[p, a]``: the flat cell action ``a`` (0 stay, 1 up, 2 down,
  3 left, 4 right; :data:`mrmt_env.distances.MOVES`) leads to from cell ``p`` (``p`` itself when blocked).
* :class:`GoalFields` -- BFS distance fields to goal cells, computed once per goal with the compiled
  BFS of :mod:`mrmt_env.distances` and kept in one ``(F, H*W)`` array (cleared when full).
* :func:`mix` -- SplitMix64 of four integers: the executors' seeded tie-breaks, reproducible by
  the Python oracles in ``tests/``.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ising_backend import splitmix
from mrmt_env.distances import bfs_flat

__all__ = ["successor_table", "GoalFields", "mix", "moves_to_actions", "compact_grid", "sort_options",
           "pibt_core", "int_in", "machine_for", "GroupBatch", "MoveGrid", "move_grid", "TurnRobots"]


class MoveGrid(NamedTuple):
    """The compact grid the turning kernels move on (:func:`compact_grid`), handed to them as one record."""

    nbr: np.ndarray      # (n, 4) the compact cell ahead from each cell facing each orientation (-1: none)
    cell_of: np.ndarray  # (n,) each compact cell's flat cell (row x width + column)
    width: int           # the map's width
    cost: np.ndarray     # (n, 4) int64, a forward move's cost from each cell facing each orientation (lanes)


def move_grid(nbr: np.ndarray, cell_of: np.ndarray, width: int, cost=None) -> MoveGrid:
    """A :class:`MoveGrid`; ``cost`` ``None``: every forward move costs 1."""
    n = nbr.shape[0]
    cost = np.ones((n, 4), dtype=np.int64) if cost is None else np.asarray(cost, dtype=np.int64)
    return MoveGrid(nbr, cell_of, int(width), cost)


class TurnRobots(NamedTuple):
    """The robots of one PIBT-with-turning call, in compact cells."""

    pos: np.ndarray     # (R,) each robot's cell
    orient: np.ndarray  # (R,) its orientation (0 east, 1 south, 2 west, 3 north)
    goals: np.ndarray   # (R,) its goal's cell (its own cell: no goal)
    commit: np.ndarray  # (R,) a cell it keeps claiming (-1: none)


class GroupBatch(NamedTuple):
    """One step's groups of robots for a chip decision (the League planners' group programs): group ``g`` is
    slots ``gstart[g]:gstart[g + 1]``, slot ``i`` robot ``members[i]`` with options ``ostart[i]:ostart[i + 1]``
    of ``opt`` (each planner's own option layout)."""

    ng: int
    gstart: np.ndarray
    members: np.ndarray
    ostart: np.ndarray
    opt: np.ndarray

_DR = (0, 1, 0, -1)  # east, south, west, north
_DC = (1, 0, -1, 0)

@numba.njit(cache=True, nogil=True)
def mix(seed, a, b, c):
    """A 64-bit hash of ``(seed, a, b, c)`` (non-negative ints), chained SplitMix64."""
    z = splitmix(np.uint64(seed))
    z = splitmix(z ^ np.uint64(a))
    z = splitmix(z ^ np.uint64(b))
    return splitmix(z ^ np.uint64(c))


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
        self._free: list[int] = []  # rows given back by keep(), reused first (no field is copied)
        self._next = 0  # rows below it were handed out

    def has(self, goal: int) -> bool:
        """Whether the field of ``goal`` (a flat cell) is built."""
        return int(goal) in self._row

    def keep(self, goals) -> None:
        """Drop every field but those of ``goals`` (flat cells); their rows are reused by later goals."""
        keep = {int(g) for g in goals}
        for g in [g for g in self._row if g not in keep]:
            self._free.append(self._row.pop(g))

    def __len__(self) -> int:
        return len(self._row)

    def rows(self, goals: np.ndarray) -> np.ndarray:
        """Row of each goal cell (flat), computing the missing fields in one compiled call."""
        goals = np.asarray(goals, dtype=np.int64)
        uniq = np.unique(goals).tolist()
        if len(uniq) > self.capacity:
            self.capacity = 2 * len(uniq)
            self.fields = np.empty((self.capacity, self.grid.size), dtype=np.int32)
            self._row.clear()
            self._free.clear()
            self._next = 0
        missing = [g for g in uniq if g not in self._row]
        if len(self._row) + len(missing) > self.capacity:  # full: keep only the goals asked for now
            self.keep(uniq)
        if missing:
            rows = []
            for g in missing:
                if self._free:
                    row = self._free.pop()
                else:
                    row, self._next = self._next, self._next + 1
                self._row[g] = row
                rows.append(row)
            _fill(self.grid, self.width, np.array(missing, dtype=np.int64), np.array(rows, dtype=np.int64),
                  self.fields)
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


@numba.njit(cache=True, nogil=True)
def sort_options(n, out, keys, turns, ties) -> None:
    """Insertion sort of ``out[:n]`` by (``keys``, ``turns``, ``ties``), the arrays permuted alike."""
    for i in range(1, n):
        j = i
        while j > 0 and (keys[j - 1] > keys[j] or (keys[j - 1] == keys[j] and (
                turns[j - 1] > turns[j] or (turns[j - 1] == turns[j] and ties[j - 1] > ties[j])))):
            keys[j - 1], keys[j] = keys[j], keys[j - 1]
            turns[j - 1], turns[j] = turns[j], turns[j - 1]
            ties[j - 1], ties[j] = ties[j], ties[j - 1]
            out[j - 1], out[j] = out[j], out[j - 1]
            j -= 1


@numba.njit(cache=True, nogil=True)
def pibt_core(pos, order, options, nxt, occ) -> None:
    """PIBT on an explicit stack (the recursion of the tests' oracles): robots in ``order`` with ``nxt``
    -1 claim the first free cell of ``cand[a, :ncand[a]]`` (``options = (cand, ncand)``, fixed for the
    step), pushing the robot standing there, which may not take its pusher's cell; a robot left
    without a cell stays, taking its cell back.  A robot whose ``nxt`` is set on entry is neither
    planned nor pushed.  ``occ = (occ_now, occ_next)``: the robot on each cell now and each cell's
    claimant (-1 none)."""
    cand, ncand = options
    occ_now, occ_next = occ
    r = pos.shape[0]
    st_a = np.empty(r, dtype=np.int64)
    st_b = np.empty(r, dtype=np.int64)
    st_i = np.empty(r, dtype=np.int64)
    for idx in range(r):
        a0 = order[idx]
        if nxt[a0] != -1:
            continue
        st_a[0], st_b[0], st_i[0] = a0, -1, 0
        top = 1
        returned = False  # the frame on top gets a child's result
        result = False
        while top > 0:
            f = top - 1
            a, b = st_a[f], st_b[f]
            if returned and result:  # the pushed robot moved away: a keeps its cell
                top -= 1
                continue
            returned = False
            pushed = False
            done = False
            while st_i[f] < ncand[a]:
                v = cand[a, st_i[f]]
                st_i[f] += 1
                if occ_next[v] != -1 or (b != -1 and v == pos[b]):
                    continue
                occ_next[v] = a
                nxt[a] = v
                c = occ_now[v]
                if c != -1 and nxt[c] == -1:
                    st_a[top], st_b[top], st_i[top] = c, a, 0
                    top += 1
                    pushed = True
                else:
                    done = True
                break
            if pushed:
                continue
            if not done:  # nowhere to go: stay (taking the cell back from whoever claimed it)
                occ_next[pos[a]] = a
                nxt[a] = pos[a]
            top -= 1
            returned = True
            result = done


def int_in(name: str, value, lo: int, hi: int) -> int:
    """``value`` as an int when it is an integer in ``[lo, hi]``; else ``ValueError`` naming it and the range."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise ValueError(f"{name} = {value!r} must be an integer in [{lo}, {hi}]")
    return int(value)


def machine_for(machine, seed: int):
    """An executor's Ising machine: ``machine`` as :func:`ising_backend.as_machine` takes it, the emulated chip
    seeded with ``seed`` for ``None``; ``ValueError`` for anything that is not a machine."""
    from ising_backend import as_machine

    try:
        return as_machine(machine, seed=seed)
    except TypeError as exc:
        raise ValueError(str(exc)) from None
