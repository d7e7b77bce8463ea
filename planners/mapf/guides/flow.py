"""Traffic-flow guide paths for PIBT with turning (``pibt-flow``), compiled.

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
the turn starts again): a fixed count
where the start kit fills its time, so that a seed gives one run.  Memory: a path and a field per
robot over the free cells.  Measurements: ``docs/design/lifelong_turning.md``.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from planners.mapf.guides.guidance import spread
from planners.mapf.pibt.turning import DEFAULT_BFS_BUDGET, DEFAULT_FIELD_BYTES, TurningPIBT, _distance

__all__ = ["FlowPIBT", "FlowGuide", "AStarScratch", "GuideState", "flow_astar", "path_field", "replan_paths", "guide_bytes", "check_team",
           "DEFAULT_REPLAN_WORK"]

#: Free cells' worth of guide-path re-planning per call beyond new goals: ``replans`` defaults to this
#: // free cells, at most one per robot (every robot on RANDOM's 819 cells; 22 on CITY-01's 47,240).
DEFAULT_REPLAN_WORK = 1 << 20


class AStarScratch(NamedTuple):
    """:func:`flow_astar`'s scratch (:func:`astar_scratch`), per free cell but ``stamp`` and ``heap``."""

    g: np.ndarray  # moves from the start
    flow_cost: np.ndarray  # flow met on the way
    parent: np.ndarray
    pdir: np.ndarray  # the move into the cell
    seen: np.ndarray  # the call that reached the cell
    closed: np.ndarray  # the call that closed it
    stamp: np.ndarray  # (1,) the calls so far
    heap: tuple  # five columns: the key's three parts, the push order, the cell


class GuideState(NamedTuple):
    """The robots' guide paths that :func:`replan_paths` re-plans (compact cells)."""

    pos: np.ndarray
    goals: np.ndarray
    paths: np.ndarray  # (R, L) each robot's guide path
    lengths: np.ndarray
    fields: np.ndarray  # each robot's PIBT field along its path
    far: np.ndarray  # the fields' value off the paths


@numba.njit(cache=True, nogil=True)
def _before(heap, i, j) -> bool:
    """Heap entry ``i`` pops before ``j``: keys compared in order (flow cost + f, f, -2g + turned, push order)."""
    for a in heap[:4]:
        if a[i] != a[j]:
            return a[i] < a[j]
    return False


@numba.njit(cache=True, nogil=True)
def _swap(heap, i, j):
    for a in heap:
        a[i], a[j] = a[j], a[i]


@numba.njit(cache=True, nogil=True)
def _heap_push(heap, size, key, seq, v) -> int:
    heap[0][size], heap[1][size], heap[2][size], heap[3][size], heap[4][size] = key[0], key[1], key[2], seq, v
    i = size
    while i > 0:
        q = (i - 1) >> 1
        if not _before(heap, i, q):
            break
        _swap(heap, i, q)
        i = q
    return size + 1


@numba.njit(cache=True, nogil=True)
def _heap_pop(heap, size) -> int:
    """Remove the first entry (moved to index ``size - 1``); returns the new size."""
    size -= 1
    _swap(heap, 0, size)
    i = 0
    while True:
        c = 2 * i + 1
        if c >= size:
            break
        if c + 1 < size and _before(heap, c + 1, c):
            c += 1
        if not _before(heap, c, i):
            break
        _swap(heap, i, c)
        i = c
    return size


@numba.njit(cache=True, nogil=True)
def _vertex_flow(flow, v) -> int:
    return (flow[v, 0] + flow[v, 1] + flow[v, 2] + flow[v, 3]) // 2


@numba.njit(cache=True, nogil=True)
def flow_astar(grid, flow, heuristic, start, goal, scratch, out) -> int:
    """Least-flow-cost path from compact ``start`` to ``goal`` into ``out`` (start first); returns its
    length in cells (1, the start alone, when the goal cannot be reached).  ``grid = (nbr, cell_of,
    width, cost)``, ``cost[v, d]`` the moves a forward move counts (lane guidance; all 1 without);
    ``heuristic = (fields, row)``: the goal's distance field row (-1: Manhattan distance);
    ``scratch`` from :func:`astar_scratch`."""
    nbr, cell_of, width, cost = grid
    fields, row = heuristic
    g, fc, parent, pdir = scratch.g, scratch.flow_cost, scratch.parent, scratch.pdir
    seen, closed, stamp, heap = scratch.seen, scratch.closed, scratch.stamp, scratch.heap
    stamp[0] += 1
    call = stamp[0]
    g[start], fc[start], parent[start], pdir[start], seen[start] = 0, 0, -1, -1, call
    h = _distance(fields, row, goal, start, cell_of, width)
    size = _heap_push(heap, 0, (h, h, 0), 0, start)
    pushes = 1
    found = False
    while size > 0:
        size = _heap_pop(heap, size)
        u = heap[4][size]
        if closed[u] == call:
            continue
        closed[u] = call
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
            size = _heap_push(heap, size, (nf + ng + h, ng + h, turned - 2 * ng), pushes, v)
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
    heap = tuple(np.zeros(m, dtype=np.int64) for _ in range(5))
    return AStarScratch(*(np.zeros(n, np.int64) for _ in range(6)), stamp=np.zeros(1, np.int64), heap=heap)


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
def replan_paths(grid, flow, goal_fields, state, who, scratch):
    """Re-plan the guide paths of robots ``who`` in order: each path's flow out, A* on the rest, its flow in,
    its PIBT field re-computed.  ``goal_fields = (fields, rows)`` with ``rows[k]`` robot ``k``'s goal row;
    ``state`` a :class:`GuideState`."""
    nbr = grid[0]
    gf, grow = goal_fields
    pos, goals, paths, lengths = state.pos, state.goals, state.paths, state.lengths
    fields, far = state.fields, state.far
    queue = np.empty(nbr.shape[0], dtype=np.int64)
    for k in who:
        _add_path(nbr, flow, paths[k], lengths[k], -1)
        lengths[k] = flow_astar(grid, flow, (gf, grow[k]), pos[k], goals[k], scratch, paths[k])
        _add_path(nbr, flow, paths[k], lengths[k], 1)
        path_field(nbr, paths[k], lengths[k], fields[k], far, queue)


@numba.njit(cache=True, nogil=True)
def _on_path(paths, lengths, pos, out):
    for k in range(pos.shape[0]):
        out[k] = False
        for i in range(lengths[k]):
            if paths[k, i] == pos[k]:
                out[k] = True
                break


def guide_bytes(n_free: int, n_robots: int, cost_max: int = 1) -> tuple[int, np.dtype]:
    """Bytes of the guide paths (int32) and fields of ``n_robots`` robots over ``n_free`` free cells, and
    the fields' dtype (uint16 while any value, at most ``2 * n_free * cost_max + 1``, fits)."""
    dtype = np.dtype(np.uint16 if 2 * n_free * cost_max + 2 < 65535 else np.uint32)
    return n_robots * n_free * (4 + dtype.itemsize), dtype


def check_team(n_free: int, n_robots: int, max_bytes: int, cost_max: int = 1) -> None:
    """``ValueError`` naming the numbers when the robots' paths and fields exceed ``max_bytes``."""
    need, _ = guide_bytes(n_free, n_robots, cost_max)
    if need > max_bytes:
        raise ValueError(f"pibt-flow keeps a path and a field per robot: {n_robots} robots x {n_free} free cells "
                         f"need {need:,} bytes, over field_bytes = {max_bytes:,} (use the executor pibt)")


class FlowGuide:
    """The robots' guide paths, their flow and each robot's PIBT field (module docstring).

    Args:
        nbr, cell_of, width: the compact grid (:func:`~planners.mapf.pibt.turning.compact_grid`).
        cost: ``(n, 4)`` moves counted per forward move (lane guidance), ``None``: 1 each.
        replans: guide paths re-planned per call beyond those of new goals (``None``: one per robot, at
            most :data:`DEFAULT_REPLAN_WORK` // free cells).
        max_bytes: memory bound of the paths and fields of all robots.
        seed: the tie among robots equally due for a re-plan.
    """

    def __init__(self, nbr, cell_of, width, cost=None, replans=None, max_bytes=DEFAULT_FIELD_BYTES, seed=0):
        self.nbr, self.cell_of, self.width = nbr, cell_of, int(width)
        n = nbr.shape[0]
        self.cost = np.ones((n, 4), dtype=np.int64) if cost is None else np.asarray(cost, dtype=np.int64)
        self.dtype = guide_bytes(n, 0, int(self.cost.max()))[1]
        self.far = self.dtype.type(np.iinfo(self.dtype).max)
        self.replans = replans
        self.max_bytes = int(max_bytes)
        self.seed = int(seed)
        self.flow = np.zeros((n, 4), dtype=np.int64)
        self.scratch = astar_scratch(n)
        self.robots = -1
        self.calls = 0
        self.replanned = 0  # guide paths planned so far

    def _ensure(self, r: int) -> None:
        if r == self.robots:
            return
        n = self.nbr.shape[0]
        check_team(n, r, self.max_bytes, int(self.cost.max()))
        self.robots = r
        self.paths = np.zeros((r, n), dtype=np.int32)
        self.lengths = np.zeros(r, dtype=np.int64)
        self.fields = np.zeros((r, n), dtype=self.dtype)
        self.last = np.full(r, -1, dtype=np.int64)
        self.flow[:] = 0

    def update(self, pc, gc, goal_fields, goal_rows) -> np.ndarray:
        """Re-plan (new goals, then ``replans`` more) for robots at compact ``pc`` heading to compact
        ``gc``; returns the robots re-planned, in order."""
        r = len(pc)
        self._ensure(r)
        self.calls += 1
        ends = self.paths[np.arange(r), np.maximum(self.lengths - 1, 0)]
        new = np.flatnonzero((self.lengths == 0) | (ends != gc))
        on = np.empty(r, dtype=np.bool_)
        _on_path(self.paths, self.lengths, pc, on)
        tie = np.random.default_rng((self.seed, self.calls)).random(r)
        rest = np.setdiff1d(np.arange(r), new)
        rest = rest[np.lexsort((tie[rest], self.last[rest], on[rest]))]
        n = self.nbr.shape[0]
        extra = min(len(rest), max(DEFAULT_REPLAN_WORK // n, 1)) if self.replans is None else int(self.replans)
        who = np.concatenate([new, np.resize(rest, extra if len(rest) else 0)]).astype(np.int64)  # cyclic passes
        replan_paths((self.nbr, self.cell_of, self.width, self.cost), self.flow, (goal_fields, goal_rows),
                     GuideState(pc, gc, self.paths, self.lengths, self.fields, self.far), who, self.scratch)
        self.last[who] = self.calls
        self.replanned += len(who)
        return who


class FlowPIBT(TurningPIBT):
    """PIBT with turning that follows traffic-flow guide paths (module docstring).

    Args:
        grid, seed, guidance: as :class:`~planners.mapf.pibt.turning.TurningPIBT` (guidance, default 0 here,
            adds lane costs to the guide paths' moves).
        replans: guide paths re-planned per call beyond those of new goals (default: one per robot, at most
            :data:`DEFAULT_REPLAN_WORK` // free cells).
        field_bytes: memory bound of the goal fields, and of the paths and fields of the robots.
        bfs_budget, commits: as :class:`~planners.mapf.pibt.turning.TurningPIBT`; commitments on by default
            here (as in the start kit).
    """

    name = "pibt-flow"

    def __init__(self, grid, seed: int = 0, guidance: int = 0, *, replans: int | None = None,
                 field_bytes: int = DEFAULT_FIELD_BYTES, bfs_budget: int = DEFAULT_BFS_BUDGET,
                 commits: bool = True) -> None:
        super().__init__(grid, seed, guidance, field_bytes=field_bytes, bfs_budget=bfs_budget, commits=commits)
        if replans is not None and (isinstance(replans, bool) or not isinstance(replans, (int, np.integer))
                                    or replans < 0):
            raise ValueError(f"replans must be an integer >= 0 (guide paths re-planned per call), got {replans!r}")
        self.guide = FlowGuide(self.nbr, self.cell_of, self.width, self.move_cost, replans, field_bytes, self.seed)

    @staticmethod
    def check_team(grid, n_robots: int, field_bytes: int = DEFAULT_FIELD_BYTES) -> None:
        """``ValueError`` when ``n_robots`` robots' paths and fields on ``grid`` exceed ``field_bytes``."""
        check_team(int((~np.asarray(grid, dtype=bool)).sum()), int(n_robots), int(field_bytes))

    def _heuristic(self, pc, gc, order):
        rows = self.fields.rows(gc, order)
        self.guide.update(pc, gc, self.fields.fields, rows)
        return self.guide.fields, np.arange(len(pc), dtype=np.int64)
