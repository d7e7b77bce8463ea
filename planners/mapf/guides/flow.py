"""Traffic-flow guide paths for the planners with turning (option ``flow``; ``pibt-flow``), compiled.

Each robot keeps a guide path to its goal: A* over the free cells whose cost adds, to each move,
the traffic the other robots' guide paths already route (Chen, Harabor, Li and Stuckey, "Traffic
Flow Optimisation for Lifelong Multi-Agent Path Finding", AAAI 2024; the default planner of the
League of Robot Runners 2024 start kit).  ``flow[v, d]`` counts the paths leaving ``v`` in direction
``d``; a move ``u -> v`` in direction ``d`` adds ``(flow[u, d] + 1) * flow[v, d + 2]`` (contraflow)
and ``sum(flow[v]) // 2`` (vertex flow) to the path's flow cost.  A* pops the least flow cost + moves
+ distance left, then the least moves + distance left, then the most moves, then a straight move
before a turn, then the first pushed.  PIBT ranks a robot's cells by the moves to its guide path
plus the path's length left from the cell where it joins (a multi-source BFS whose sources are the
path's cells, the goal's end first).

Each call re-plans the paths of robots whose goal changed, then ``replans`` more in turn (robots off
their path first, then the longest since their last re-plan, then a seeded tie; past the last robot
the turn starts again): a fixed count where the start kit fills its time, so that a seed gives one run.
Re-planning stops once the call's A* expansions reach ``work`` (new goals first, the longest waiting
first) or, under a clock, at the planner's stop time; a robot whose goal has no guide path yet ranks
its cells by its goal's field meanwhile (the start kit: by its goal's heuristic table).  Memory: a
field per robot over the free cells, and paths as long as the longest.  Measurements:
``docs/design/lifelong_turning.md``.
"""

from __future__ import annotations

from typing import NamedTuple

import time

import numba
import numpy as np

from planners.heap import pop, push
from planners.mapf.guides.guidance import distance_bound, spread
from planners.mapf.common import move_grid
from planners.mapf.pibt.turning import _distance

__all__ = ["FlowGuide", "AStarScratch", "GuideState",
           "flow_astar", "path_field", "replan_paths", "guide_bytes", "field_dtype", "check_team",
           "DEFAULT_REPLAN_WORK", "DEFAULT_GUIDE_WORK"]

#: Free cells' worth of guide-path re-planning per call beyond new goals: ``replans`` defaults to this
#: // free cells, at most one per robot (every robot on RANDOM's 819 cells; 22 on CITY-01's 47,240).
DEFAULT_REPLAN_WORK = 1 << 20

#: A* expansions per call for guide paths: above every robot's path re-planned on a map of 1,000 robots x
#: 1,000 free cells (one search closes each cell at most once), about 0.7 s on the 10,000-robot warehouse.
DEFAULT_GUIDE_WORK = 1 << 20

#: Rows of a guide path when the robots are first seen (they grow to the longest path planned).
FIRST_PATH_CELLS = 256

#: Under a clock, guide paths stop this long before the step's deadline, beyond twice PIBT's last pass
#: (and no search starts that would end past it, at the pace of the call's longest search so far).
GUIDE_MARGIN_S = 0.03


class AStarScratch(NamedTuple):
    """:func:`flow_astar`'s scratch (:func:`astar_scratch`), per free cell but ``stamp`` and ``heap``."""

    g: np.ndarray  # moves from the start
    flow_cost: np.ndarray  # flow met on the way
    parent: np.ndarray
    pdir: np.ndarray  # the move into the cell
    seen: np.ndarray  # the call that reached the cell
    closed: np.ndarray  # the call that closed it
    stamp: np.ndarray  # (1,) the calls so far
    heap: np.ndarray  # (4n + 1, 5) planners.heap rows: flow cost + f, f, -2g + turned, push order (4 keys), cell
    expanded: np.ndarray  # (1,) the cells closed so far, over all calls
    path: np.ndarray  # (n,) the path found by the latest call


class GuideState(NamedTuple):
    """The robots' guide paths that :func:`replan_paths` re-plans (compact cells)."""

    pos: np.ndarray
    goals: np.ndarray
    paths: np.ndarray  # (R, L) each robot's guide path
    lengths: np.ndarray
    fields: np.ndarray  # each robot's PIBT field along its path
    far: np.ndarray  # the fields' value off the paths
    room: int  # the most moves a path's field may count along it (its dtype's room above the map's distances)


@numba.njit(cache=True, nogil=True)
def _vertex_flow(flow, v) -> int:
    return (flow[v, 0] + flow[v, 1] + flow[v, 2] + flow[v, 3]) // 2


@numba.njit(cache=True, nogil=True)
def flow_astar(grid, flow, heuristic, start, goal, scratch, out) -> int:
    """Least-flow-cost path from compact ``start`` to ``goal`` into ``out`` (start first); returns its
    length in cells (1, the start alone, when the goal cannot be reached).  ``grid`` a
    :class:`~planners.mapf.common.MoveGrid`, ``cost[v, d]`` the moves a forward move counts (lanes; 1 without);
    ``heuristic = (fields, row)``: the goal's distance field row (-1: Manhattan distance);
    ``scratch`` from :func:`astar_scratch`."""
    nbr, cell_of, width, cost = grid.nbr, grid.cell_of, grid.width, grid.cost
    fields, row = heuristic
    g, fc, parent, pdir = scratch.g, scratch.flow_cost, scratch.parent, scratch.pdir
    seen, closed, stamp, heap = scratch.seen, scratch.closed, scratch.stamp, scratch.heap
    stamp[0] += 1
    call = stamp[0]
    g[start], fc[start], parent[start], pdir[start], seen[start] = 0, 0, -1, -1, call
    h = _distance(fields, row, goal, start, cell_of, width)
    size = push(heap, 0, (h, h, 0, 0, start), 4)
    pushes = 1
    found = False
    while size > 0:
        size = pop(heap, size, 4, 5)
        u = heap[size, 4]
        if closed[u] == call:
            continue
        closed[u] = call
        scratch.expanded[0] += 1
        if u == goal:
            found = True
            break
        for d in range(4):
            v = nbr[u, d]
            if v < 0 or closed[v] == call:
                continue
            ng = g[u] + cost[u, d]
            nf = fc[u] + (flow[u, d] + 1) * flow[v, (d + 2) & 3] + _vertex_flow(flow, v)
            if seen[v] == call and nf + ng >= fc[v] + g[v]:
                continue
            g[v], fc[v], parent[v], pdir[v], seen[v] = ng, nf, u, d, call
            h = _distance(fields, row, goal, v, cell_of, width)
            turned = 1 if (pdir[u] >= 0 and pdir[u] != d) else 0
            size = push(heap, size, (nf + ng + h, ng + h, turned - 2 * ng, pushes, v), 4)
            pushes += 1
    if not found:
        out[0] = start
        return 1
    n = 0
    v = goal
    while v != -1:
        out[n] = v
        n += 1
        v = parent[v]
    out[:n] = out[:n][::-1].copy()
    return n


def astar_scratch(n: int):
    """Scratch of :func:`flow_astar` for a map of ``n`` free cells (heap entries: at most 4 per cell)."""
    m = 4 * n + 1
    heap = np.zeros((m, 5), dtype=np.int64)
    g, flow_cost, parent, pdir, seen, closed = (np.zeros(n, np.int64) for _ in range(6))
    return AStarScratch(g, flow_cost, parent, pdir, seen, closed, stamp=np.zeros(1, np.int64), heap=heap,
                        expanded=np.zeros(1, np.int64), path=np.zeros(n, np.int64))


@numba.njit(cache=True, nogil=True)
def _add_path(nbr, flow, path, length, sign):
    """Add ``sign`` to the flow of each move of ``path[:length]``."""
    for i in range(length - 1):
        u, v = path[i], path[i + 1]
        for d in range(4):
            if nbr[u, d] == v:
                flow[u, d] += sign


@numba.njit(cache=True, nogil=True)
def path_field(nbr, path, length, field, far, queue):
    """``field[v]`` = moves from compact ``v`` to the nearest cell of ``path[:length]`` + the path's
    moves left from there (BFS from every path cell, the goal's end first; ``far`` where unreachable)."""
    field[:] = far
    tail = 0
    for i in range(length - 1, -1, -1):
        p = path[i]
        if field[p] == far:
            field[p] = length - 1 - i
            queue[tail] = p
            tail += 1
    spread(nbr, field, far, queue, tail)


@numba.njit(cache=True, nogil=True)
def replan_paths(grid, flow, goal_fields, state, who, scratch, work):
    """Re-plan the guide paths of robots ``who`` in order: each path's flow out, A* on the rest, its flow in,
    its PIBT field re-computed.  ``goal_fields = (fields, rows)`` with ``rows[k]`` robot ``k``'s goal row;
    ``state`` a :class:`GuideState`.  Stops before a robot once this call's expansions reach ``work``
    (< 0: no bound), or at a path longer than ``state.paths``' rows or than the fields' ``room`` (that
    robot's path left as it was); returns the robots re-planned (a prefix of ``who``) and the cells of the
    path that did not fit (0: none)."""
    nbr = grid.nbr
    gf, grow = goal_fields
    pos, goals, paths, lengths = state.pos, state.goals, state.paths, state.lengths
    fields, far = state.fields, state.far
    queue = np.empty(nbr.shape[0], dtype=np.int64)
    found = scratch.path
    first = scratch.expanded[0]
    for i in range(who.shape[0]):
        if work >= 0 and scratch.expanded[0] - first >= work:
            return i, 0
        k = who[i]
        _add_path(nbr, flow, paths[k], lengths[k], -1)
        m = flow_astar(grid, flow, (gf, grow[k]), pos[k], goals[k], scratch, found)
        if m > paths.shape[1] or m - 1 > state.room:
            _add_path(nbr, flow, paths[k], lengths[k], 1)
            return i, m
        paths[k, :m] = found[:m]
        lengths[k] = m
        _add_path(nbr, flow, paths[k], m, 1)
        path_field(nbr, paths[k], m, fields[k], far, queue)
    return who.shape[0], 0


@numba.njit(cache=True, nogil=True)
def copy_rows(src, src_rows, dst, dst_rows):
    """``dst[dst_rows[i]] = src[src_rows[i]]`` for each ``i`` (row by row, no temporary)."""
    for i in range(src_rows.shape[0]):
        dst[dst_rows[i]] = src[src_rows[i]]


@numba.njit(cache=True, nogil=True)
def _on_path(paths, lengths, pos, out):
    for k in range(pos.shape[0]):
        out[k] = False
        for i in range(lengths[k]):
            if paths[k, i] == pos[k]:
                out[k] = True
                break


def guide_bytes(n_free: int, n_robots: int, itemsize: int = 2) -> int:
    """Bytes of the PIBT fields of ``n_robots`` robots over ``n_free`` free cells (``itemsize`` bytes a value)
    and of their first guide paths (int32, :data:`FIRST_PATH_CELLS` cells each; they grow with the longest)."""
    return n_robots * (n_free * itemsize + 4 * min(n_free, FIRST_PATH_CELLS))


def field_dtype(nbr: np.ndarray) -> tuple[np.dtype, int]:
    """The fields' first dtype and the map's distance bound: uint16 while a value of a path of up to
    ``2 ** 15`` cells fits above the bound (any path of a map under ``2 ** 15`` free cells), else uint32;
    a longer path widens them (:meth:`FlowGuide._widen`)."""
    bound = distance_bound(nbr, np.ones((nbr.shape[0], 4), dtype=np.int64), 1)
    return np.dtype(np.uint16 if bound + min(nbr.shape[0], 1 << 15) < 65535 else np.uint32), bound


def check_team(n_free: int, n_robots: int, max_bytes: int, itemsize: int = 2) -> None:
    """``ValueError`` naming the numbers when the robots' fields and first paths exceed ``max_bytes``."""
    need = guide_bytes(n_free, n_robots, itemsize)
    if need > max_bytes:
        raise ValueError(f"pibt-flow keeps a field and a path per robot: {n_robots} robots x {n_free} free cells "
                         f"need {need:,} bytes, over field_bytes = {max_bytes:,} (use the executor pibt)")


def check_work(work) -> int | None:
    """``work`` as an int (``None`` kept: no bound); ``ValueError`` naming it unless an integer >= 1."""
    if work is None:
        return None
    if isinstance(work, bool) or not isinstance(work, (int, np.integer)) or work < 1:
        raise ValueError(f"guide_work must be an integer >= 1 (A* expansions per call for guide paths) or None, "
                         f"got {work!r}")
    return int(work)


class FlowGuide:
    """The robots' guide paths, their flow and each robot's PIBT field (module docstring).

    Args:
        nbr, cell_of, width: the compact grid (:func:`~planners.mapf.common.compact_grid`).
        cost: ``(n, 4)`` moves counted per forward move (lane guidance), ``None``: 1 each.
        replans: guide paths re-planned per call beyond those of new goals (``None``: one per robot, at
            most :data:`DEFAULT_REPLAN_WORK` // free cells).
        max_bytes: memory bound of the fields and first paths of all robots.
        seed: the tie among robots equally due for a re-plan.
        work: A* expansions per call (:data:`DEFAULT_GUIDE_WORK`; ``None``: no bound).
    """

    def __init__(self, nbr, cell_of, width, cost=None, replans=None, max_bytes=1 << 30, seed=0,
                 work=DEFAULT_GUIDE_WORK):
        self.nbr, self.cell_of, self.width = nbr, cell_of, int(width)
        n = nbr.shape[0]
        self.move_grid = move_grid(nbr, cell_of, width, cost)
        self.dtype, self.bound = field_dtype(nbr)
        self.far = self.dtype.type(np.iinfo(self.dtype).max)
        self.replans = replans
        self.max_bytes = int(max_bytes)
        self.seed = int(seed)
        self.work = check_work(work)
        self.flow = np.zeros((n, 4), dtype=np.int64)
        self.scratch = astar_scratch(n)
        self.robots = -1
        self.calls = 0
        self.replanned = 0  # guide paths planned so far
        self.late = 0  # robot-calls in which a robot with a new goal waited for its path (work or clock)

    def _ensure(self, r: int) -> None:
        if r == self.robots:
            return
        n = self.nbr.shape[0]
        check_team(n, r, self.max_bytes, self.dtype.itemsize)
        self.robots = r
        self.paths = np.zeros((r, min(n, FIRST_PATH_CELLS)), dtype=np.int32)
        self.lengths = np.zeros(r, dtype=np.int64)
        self.fields = np.zeros((r, n), dtype=self.dtype)
        self.last = np.full(r, -1, dtype=np.int64)
        self.since = np.full(r, -1, dtype=np.int64)  # the call since which a robot wants a path (-1: it has one)
        self.fresh = np.zeros(r, dtype=np.bool_)  # its row holds its path's field for its goal
        self.copied = np.full(r, -1, dtype=np.int64)  # else the goal whose field its row holds (-1: none)
        self.flow[:] = 0

    def _grow(self, cells: int) -> None:
        """Room for a path of ``cells`` cells: longer path rows, wider fields when its values would not fit."""
        if cells > self.paths.shape[1]:
            paths = np.zeros((self.robots, max(cells, 2 * self.paths.shape[1])), dtype=np.int32)
            paths[:, :self.paths.shape[1]] = self.paths
            self.paths = paths
        if cells - 1 > self._room():
            far = self.fields == self.far
            self.dtype = np.dtype(np.uint32)
            self.far = self.dtype.type(np.iinfo(self.dtype).max)
            self.fields = np.where(far, self.far, self.fields.astype(self.dtype))

    def _room(self) -> int:
        return int(self.far) - 1 - self.bound

    def update(self, pc, gc, goal_fields, goal_rows, stop: float | None = None) -> np.ndarray:
        """Re-plan (new goals, then ``replans`` more; within :attr:`work` and, given, until the
        ``time.perf_counter()`` time ``stop``) for robots at compact ``pc`` heading to compact ``gc``;
        returns each robot's row of :attr:`fields` (its own; -1: no field yet, Manhattan distance)."""
        r = len(pc)
        self._ensure(r)
        self.calls += 1
        ends = self.paths[np.arange(r), np.maximum(self.lengths - 1, 0)]
        need = (self.lengths == 0) | (ends != gc)
        self.since = np.where(need, np.where(self.since < 0, self.calls, self.since), -1)
        self.fresh &= ~need
        new = np.flatnonzero(need)
        new = new[np.argsort(self.since[new], kind="stable")]  # the longest waiting first, then by index
        on = np.empty(r, dtype=np.bool_)
        _on_path(self.paths, self.lengths, pc, on)
        tie = np.random.default_rng((self.seed, self.calls)).random(r)
        rest = np.setdiff1d(np.arange(r), new)
        rest = rest[np.lexsort((tie[rest], self.last[rest], on[rest]))]
        n = self.nbr.shape[0]
        extra = min(len(rest), max(DEFAULT_REPLAN_WORK // n, 1)) if self.replans is None else int(self.replans)
        who = np.concatenate([new, np.resize(rest, extra if len(rest) else 0)]).astype(np.int64)  # cyclic passes
        rows = self._rows(gc, goal_fields, goal_rows)  # first: the re-plans then fill the time left
        done = self._replan(pc, gc, (goal_fields, goal_rows), who, stop)
        served = who[:done]
        self.last[served] = self.calls
        self.since[served] = -1
        self.fresh[served] = True
        self.copied[served] = -1
        rows[served] = served
        self.replanned += done
        self.late += int(np.count_nonzero(self.since >= 0))
        return rows

    def _replan(self, pc, gc, goal_fields, who, stop) -> int:
        """Run :func:`replan_paths` over ``who`` within the work and the clock; returns the robots done."""
        grid = self.move_grid
        first = int(self.scratch.expanded[0])
        chunk = len(who) if stop is None else 1
        done = 0
        longest = 0.0  # under a clock: the longest search so far; the next one must end before the stop
        while done < len(who):
            left = -1 if self.work is None else self.work - (int(self.scratch.expanded[0]) - first)
            now = time.perf_counter()
            if (self.work is not None and left <= 0) or (stop is not None and now + longest >= stop):
                break
            part = who[done:done + chunk]
            state = GuideState(pc, gc, self.paths, self.lengths, self.fields, self.far, self._room())
            k, cells = replan_paths(grid, self.flow, goal_fields, state, part, self.scratch, left)
            longest = max(longest, time.perf_counter() - now)
            done += k
            if cells:
                self._grow(cells)
            elif k < len(part):
                break  # the work is spent
        return done

    def _rows(self, gc, goal_fields, goal_rows) -> np.ndarray:
        """Each robot's row: its own, holding its path's field, or else a copy of its goal's field (-1 without)."""
        rows = np.arange(self.robots, dtype=np.int64)
        wait = np.flatnonzero(~self.fresh)
        if len(wait):
            has = goal_rows[wait] >= 0
            copy = wait[has & (self.copied[wait] != gc[wait])]
            copy_rows(goal_fields, goal_rows[copy], self.fields, copy)
            self.copied[copy] = gc[copy]
            rows[wait[~has]] = -1
        return rows
