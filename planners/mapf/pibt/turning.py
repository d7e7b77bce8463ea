"""PIBT for the League of Robot Runners' action model with turning (MAPF_T), compiled.

A robot is a flat cell ``row * W + col`` and an orientation (0 east, 1 south,
2 west, 3 north); actions are 0 F (one cell ahead), 1 R (turn clockwise),
2 C (turn counter-clockwise), 3 W (wait).  One call of
:meth:`TurningPIBT.actions` returns one joint action, valid by construction:

1. PIBT (as :class:`~planners.mapf.pibt.grid.PIBT`: priority = steps since the robot
   last stood on its goal + a seeded tie-breaker, except that a step ending in a
   dead end -- a cell with one free neighbour -- off the goal counts 1 +
   :data:`DEAD_END_BONUS`, as in the start kit) picks each robot's next cell.
   Candidates sort by BFS distance to the goal, then by the turns needed to
   face the cell (0 ahead or staying, 1 to a side, 2 behind), then by
   ``mix(seed, step, robot, cell)``.
2. A robot whose next cell is ahead moves F; one whose next cell is to a side
   or behind turns towards it (R / C; behind turns R) and stays this step.
3. Vacate check: a forward move is kept only if the cell ahead is empty now
   or its robot keeps a forward move itself (chains are followed to their end;
   a closed rotation of three or more robots moves); otherwise the robot waits,
   and so does everything queued behind it.

Goal fields (:class:`TurnFields`): uint16 over the free cells only, in a cache
bounded in bytes (least recently used fields recomputed on demand), at most a
budget of BFS work per call (a goal still without a field goes by Manhattan
distance).  Design and measurements: ``docs/design/lifelong_turning.md``.
"""

from __future__ import annotations

import time

import numba
import numpy as np

from planners.compute import ComputeReport
from planners.mapf.common import TurnRobots, compact_grid, mix, move_grid, pibt_core, sort_options
from planners.mapf.guides.congestion import Congestion
from planners.mapf.guides.guidance import cost_rows, distance_bound, move_costs
from planners.mapf.guides.focus import active_count, active_goals, checked_rest
from planners.mapf.guides.parking import ParkingPlaces
from planners.mapf.pibt.options import (DEFAULT_BFS_BUDGET, DEFAULT_FIELD_BYTES, DEFAULT_GUIDANCE, DEFAULT_REFRESH,
                                       LaneOptions, TurningOptions, commits_option, congestion_options)

__all__ = ["TurningPIBT", "TurningOptions", "LaneOptions", "commits_option", "TurnFields", "turning_kernel",
           "vacate_check", "compact_grid",
           "FORWARD", "CLOCKWISE", "COUNTER", "WAIT", "DEFAULT_FIELD_BYTES", "DEFAULT_BFS_BUDGET",
           "DEAD_END_BONUS", "DEFAULT_GUIDANCE", "DEFAULT_REFRESH", "congestion_options", "FIELD_MARGIN_S"]

FORWARD, CLOCKWISE, COUNTER, WAIT = 0, 1, 2, 3
#: Extra priority per step spent in a dead end off the goal (the start kit's value; without it a robot
#: leaving a dead end and a higher-priority robot entering it block each other for good).
DEAD_END_BONUS = 10
#: BFS fields' worth of work of one guided field (bucketed Dijkstra: 2.7 ms against 0.5 ms for BFS on CITY-01's
#: 47,240 free cells), so that a call's field budget holds under guidance too.
GUIDED_WORK = 5
#: Under a clock, refreshes of goal fields stop this long before the step's deadline, beyond twice the last pass.
FIELD_MARGIN_S = 0.03


@numba.njit(cache=True, nogil=True)
def _bfs_rows(nbr, goals, rows, fields, far):
    """``fields[rows[i]]`` = moves to compact cell ``goals[i]`` (``far``, the dtype's maximum, where unreachable)."""
    n = nbr.shape[0]
    queue = np.empty(n, dtype=np.int32)
    for i in range(goals.shape[0]):
        f = fields[rows[i]]
        f[:] = far
        f[goals[i]] = 0
        queue[0] = goals[i]
        head, tail = 0, 1
        while head < tail:
            p = queue[head]
            head += 1
            nd = f[p] + 1
            for d in range(4):
                q = nbr[p, d]
                if q >= 0 and f[q] == far:
                    f[q] = nd
                    queue[tail] = q
                    tail += 1


class TurnFields:
    """BFS distance fields to goal cells over the free cells only (least guided cost under ``cost``),
    uint16 (uint32 when a distance may reach 65,535: a map of that many free cells, or under ``cost``
    a bound on the map's diameter that high; the dtype's maximum = unreachable), in a cache bounded by
    ``max_bytes``: when full, the fields least recently asked for make room and are recomputed on
    demand (the goals of one call always fit: the cache grows past the bound for them).  One call
    computes at most ``bfs_budget // free cells`` new fields (a fifth of that under guidance costs,
    :data:`GUIDED_WORK`; at least one), for the goals of the
    highest-priority robots first; the others get row -1 (the kernel then uses Manhattan distance).
    A subclass may keep :attr:`per_cell` entries per free cell (it then names its own kernels)."""

    #: Entries of a field per free cell (a distance is below the field's length: uint16 while it is < 65,535).
    per_cell = 1

    def __init__(self, nbr: np.ndarray, max_bytes: int = DEFAULT_FIELD_BYTES,
                 bfs_budget: int = DEFAULT_BFS_BUDGET, cost: np.ndarray | None = None) -> None:
        self.nbr = nbr
        self.cost = cost  # (n, 4) forward-move costs (guidance), None: every action costs 1
        n = nbr.shape[0]
        size = n * self.per_cell
        top = size if cost is None else distance_bound(nbr, cost, self.per_cell)  # above any finite distance
        self.dtype = np.dtype(np.uint16 if top < 65535 else np.uint32)
        self.far = int(np.iinfo(self.dtype).max)
        self.capacity = max(min(int(max_bytes) // (max(size, 1) * self.dtype.itemsize), n), 1)
        self.per_call = max(int(bfs_budget) // (max(size, 1) * (1 if cost is None else GUIDED_WORK)), 1)
        self.fields = np.empty((0, size), dtype=self.dtype)
        self.row_of = np.full(n, -1, dtype=np.int64)  # compact goal -> row
        self.goal_of = np.empty(0, dtype=np.int64)  # row -> compact goal
        self.stamp = np.empty(0, dtype=np.int64)  # row -> last call that asked for it
        self.filled = np.empty(0, dtype=np.int64)  # row -> the call that last computed it
        self.used = 0
        self.calls = 0
        self.computed = 0  # fields computed so far (recomputations included)

    def _grow(self, rows: int) -> None:
        # the first allocation reserves the whole bound (pages are only committed as rows are written);
        # past the bound (one call's goals do not fit) it grows by a quarter, never past one row per cell
        size = max(rows, min(max(self.capacity, self.fields.shape[0] * 5 // 4), self.nbr.shape[0]))
        fields = np.empty((size, self.fields.shape[1]), dtype=self.dtype)
        fields[:self.used] = self.fields[:self.used]
        self.fields = fields
        self.goal_of = np.concatenate([self.goal_of[:self.used], np.full(size - self.used, -1, np.int64)])
        self.stamp = np.concatenate([self.stamp[:self.used], np.full(size - self.used, -1, np.int64)])
        self.filled = np.concatenate([self.filled[:self.used], np.full(size - self.used, -1, np.int64)])

    def rows(self, goals: np.ndarray, order: np.ndarray) -> np.ndarray:
        """Row of :attr:`fields` of each compact goal cell (-1: not computed yet, over the budget);
        ``order`` = the robots by decreasing priority."""
        self.calls += 1
        rows = self.row_of[goals]
        self.stamp[rows[rows >= 0]] = self.calls
        if (rows >= 0).all():
            return rows
        wanted = goals[order]
        wanted = wanted[self.row_of[wanted] < 0]
        uniq, first = np.unique(wanted, return_index=True)
        miss = uniq[np.argsort(first, kind="stable")][:self.per_call]
        fresh = min(len(miss), max(self.capacity - self.used, 0))
        evict = len(miss) - fresh
        victims = np.empty(0, dtype=np.int64)
        if evict:
            old = np.flatnonzero(self.stamp[:self.used] < self.calls)
            victims = old[np.argsort(self.stamp[old], kind="stable")[:evict]]
            self.row_of[self.goal_of[victims]] = -1
            fresh += evict - len(victims)  # not enough to evict: grow past the bound
        if self.used + fresh > self.fields.shape[0]:
            self._grow(self.used + fresh)
        new = np.concatenate([victims, np.arange(self.used, self.used + fresh, dtype=np.int64)])
        self.used += fresh
        self.goal_of[new] = miss
        self.stamp[new] = self.calls
        self.row_of[miss] = new
        self._fill(miss, new)
        self.filled[new] = self.calls
        self.computed += len(miss)
        return self.row_of[goals]

    def refill(self, rows: np.ndarray) -> None:
        """Recompute the fields in ``rows`` under the costs now (:mod:`planners.mapf.guides.congestion`)."""
        self._fill(self.goal_of[rows], rows)
        self.filled[rows] = self.calls
        self.computed += len(rows)

    #: the kernels that fill fields: by BFS (every action costs 1) and by Dijkstra under ``cost``
    plain_kernel = staticmethod(_bfs_rows)
    cost_kernel = staticmethod(cost_rows)

    def _fill(self, goals: np.ndarray, rows: np.ndarray) -> None:
        """Compute the fields of compact ``goals`` into ``rows`` (BFS, or Dijkstra under guidance costs)."""
        if self.cost is None:
            self.plain_kernel(self.nbr, goals, rows, self.fields, self.dtype.type(self.far))
        else:
            self.cost_kernel(self.nbr, self.cost, goals, rows, self.fields, self.far)


@numba.njit(cache=True, nogil=True)
def _distance(fields, row, goal, v, cell_of, width) -> int:
    """Moves from compact ``v`` to compact ``goal``: its field, or Manhattan distance without one."""
    if row >= 0:
        return fields[row, v]
    a, b = cell_of[v], cell_of[goal]
    return abs(a // width - b // width) + abs(a % width - b % width)


@numba.njit(cache=True, nogil=True)
def _candidates(grid, robots, heuristic, stamp, a, out, buf) -> int:
    """Robot ``a``'s cells from its compact cell (itself first, then the free neighbours) into ``out``,
    sorted by (distance, turns to face the cell, ``mix(seed, t, a, flat cell)``); records as
    :func:`turning_kernel`, ``buf = (keys, turns, ties)`` scratch."""
    nbr, cell_of, width = grid.nbr, grid.cell_of, grid.width
    pos, orient, goals = robots.pos, robots.orient, robots.goals
    fields, rows = heuristic
    seed, t = stamp
    keys, turns, ties = buf
    p, o, row, goal = pos[a], orient[a], rows[a], goals[a]
    out[0], turns[0] = p, 0
    keys[0] = _distance(fields, row, goal, p, cell_of, width)
    ties[0] = mix(seed, t, a, cell_of[p])
    n = 1
    for d in range(4):
        v = nbr[p, d]
        if v < 0:
            continue
        out[n] = v
        keys[n] = _distance(fields, row, goal, v, cell_of, width)
        turns[n] = 0 if d == o else (2 if d == (o + 2) % 4 else 1)
        ties[n] = mix(seed, t, a, cell_of[v])
        n += 1
    sort_options(n, out, keys, turns, ties)
    return n


@numba.njit(cache=True, nogil=True)
def _pibt(grid, robots, heuristic, order, stamp, nxt, occ):
    """PIBT (:func:`~planners.mapf.common.pibt_core`) over every robot's cells of :func:`_candidates`; a
    robot with ``nxt`` set on entry (a commitment) is neither planned nor pushed."""
    pos = robots.pos
    r = pos.shape[0]
    cand = np.empty((r, 5), dtype=np.int64)
    ncand = np.empty(r, dtype=np.int64)
    buf = (np.empty(5, dtype=np.int64), np.empty(5, dtype=np.int64), np.empty(5, dtype=np.uint64))
    for k in range(r):
        ncand[k] = _candidates(grid, robots, heuristic, stamp, k, cand[k], buf)
    pibt_core(pos, order, (cand, ncand), nxt, occ)


@numba.njit(cache=True, nogil=True)
def vacate_check(pos, nxt, act, occ_now):
    """The vacate check: a forward move (``act`` F towards ``nxt``) is kept only if the cell ahead is empty now
    (``occ_now[cell]`` the robot on it, -1 none) or its robot keeps a forward move itself (chains followed to
    their end; a closed rotation of three or more moves); otherwise it waits, with all queued behind it."""
    r = pos.shape[0]
    state = np.zeros(r, dtype=np.int8)  # 0 open, 1 on the chain being followed, 2 moves, 3 waits
    chain = np.empty(r, dtype=np.int64)
    for k in range(r):
        if act[k] != FORWARD or state[k] != 0:
            continue
        top = 0
        cur = k
        while True:
            state[cur] = 1
            chain[top] = cur
            top += 1
            j = occ_now[nxt[cur]]
            if j == -1:
                ok = True
                break
            if act[j] != FORWARD or state[j] == 3 or nxt[j] == pos[cur]:  # stays, or a swap (never from PIBT)
                ok = False
                break
            if state[j] != 0:  # moves, or closes a rotation (three or more robots)
                ok = True
                break
            cur = j
        for i in range(top):
            state[chain[i]] = 2 if ok else 3
            if not ok:
                act[chain[i]] = WAIT


@numba.njit(cache=True, nogil=True)
def turning_kernel(grid, robots, heuristic, order, stamp, out, occ):
    """One joint action into ``out = (nxt, act)``: ``nxt[k]`` robot ``k``'s PIBT cell, ``act[k]`` its action.
    ``grid`` a :class:`~planners.mapf.common.MoveGrid` (its costs unread); ``robots`` a :class:`TurnRobots`;
    ``heuristic = (fields, rows)``, ``rows[k]``
    the row of ``fields`` robot ``k`` goes by (-1: Manhattan distance to its goal); ``stamp = (seed, t)``;
    ``occ = (occ_now, occ_next)`` scratch over compact cells, all -1 on entry and on return."""
    nbr = grid.nbr
    pos, orient, commit = robots.pos, robots.orient, robots.commit
    nxt, act = out
    occ_now, occ_next = occ
    r = pos.shape[0]
    for k in range(r):
        occ_now[pos[k]] = k
        nxt[k] = -1
    for k in range(r):
        if commit[k] >= 0 and commit[k] != pos[k]:
            nxt[k] = commit[k]
            occ_next[commit[k]] = k
    _pibt(grid, robots, heuristic, order, stamp, nxt, occ)
    for k in range(r):
        p, v, o = pos[k], nxt[k], orient[k]
        act[k] = WAIT
        if v == p or occ_next[v] != k:  # staying, or a commitment a robot that could not move took back
            continue
        for d in range(4):
            if nbr[p, d] == v:
                act[k] = FORWARD if d == o else (COUNTER if d == (o + 3) % 4 else CLOCKWISE)
    vacate_check(pos, nxt, act, occ_now)
    for k in range(r):
        occ_now[pos[k]] = -1
        occ_next[nxt[k]] = -1


def _int_array(name: str, values) -> np.ndarray:
    a = np.asarray(values)
    if a.ndim != 1:
        raise ValueError(f"{name} must be a 1-d array of ints, got shape {a.shape}")
    if a.dtype.kind not in "iu":
        if a.size and not (a.dtype.kind == "f" and np.all(np.isfinite(a)) and np.all(a == np.round(a))):
            raise ValueError(f"{name} must hold integers, got dtype {a.dtype}")
        a = a.astype(np.int64)
    return np.ascontiguousarray(a, dtype=np.int64)


class TurningPIBT:
    """PIBT with turning on one grid (see the module docstring).

    Args:
        grid: ``(H, W)`` bool obstacles.
        seed: tie-breaks (robot priorities and equal cells).
        options: the fields of :attr:`Options` (:class:`TurningOptions`), checked; the record is :attr:`options`.
    """

    name = "pibt"
    Options = TurningOptions
    #: the chip charge of the latest step (none here; a subclass that decides on a chip sets it)
    last_compute = ComputeReport()
    kernel_s = 0.0
    #: whether :meth:`steer` hands the robots at work to ``keep_at_work(pos, goals, pc, rows, way)`` (a subclass's)
    decides_work = False

    def __init__(self, grid: np.ndarray, seed: int = 0, **options) -> None:
        self.options = opts = type(self).Options.from_dict(options, self.name)
        self.grid = np.asarray(grid, dtype=bool)
        if self.grid.ndim != 2:
            raise ValueError(f"grid must be 2-d (H, W), got shape {self.grid.shape}")
        self.width = int(self.grid.shape[1])
        self.cid, self.cell_of, self.nbr = compact_grid(self.grid)
        self.guidance, self.corridors, self.commits = opts.guidance, opts.corridors, getattr(opts, "commits", False)
        self.move_cost = move_costs(self.nbr, self.cell_of, self.width, self.guidance, self.corridors)
        self.move_grid = move_grid(self.nbr, self.cell_of, self.width, self.move_cost)
        self.congestion, field_cost = None, self.move_cost
        if getattr(opts, "congestion", 0):
            base = np.ones((len(self.cell_of), 4), np.int64) if self.move_cost is None else self.move_cost
            self.congestion = Congestion(self.nbr, base, opts.congestion, opts.refresh)
            field_cost = self.congestion.bound()  # the fields' dtype holds the costliest moves
        self.fields = TurnFields(self.nbr, opts.field_bytes, opts.bfs_budget, cost=field_cost)
        park = getattr(opts, "park", 0.0)
        self.parking = ParkingPlaces(self.nbr, park, seed) if park else None
        self.active = getattr(opts, "active", 1.0)
        #: whether :meth:`actions` wants ``rest`` (each robot's task beyond its goal: ``active_by="task"``)
        self.takes_rest = self.active < 1 and getattr(opts, "active_by", "goal") == "task"
        self.deadline: float | None = None  # the step's deadline under a clock (perf_counter seconds)
        self.dead_end = (self.nbr >= 0).sum(axis=1) == 1  # per compact cell
        self.seed = int(seed) & ((1 << 63) - 1)
        self.t = 0
        self.elapsed = np.zeros(0, dtype=np.int64)
        self.commit = np.zeros(0, dtype=np.int64)  # per robot: the compact cell it keeps claiming, -1 none
        self.tie = np.zeros(0)
        self.targets = np.zeros(0, dtype=np.int64)  # the last call's PIBT cells (flat)
        n = len(self.cell_of)
        self._occ_now = np.full(n, -1, dtype=np.int64)
        self._occ_next = np.full(n, -1, dtype=np.int64)

    @staticmethod
    def check_team(grid, n_robots: int, field_bytes: int = DEFAULT_FIELD_BYTES) -> None:
        """``ValueError`` when the executor cannot take ``n_robots`` robots on ``grid`` within ``field_bytes`` (any
        number here: the goal fields' cache makes room; :class:`~planners.mapf.guides.flow.FlowPIBT` bounds a
        field per robot)."""

    def _ensure(self, n_robots: int) -> None:
        if len(self.elapsed) != n_robots:
            self.elapsed = np.zeros(n_robots, dtype=np.int64)
            self.commit = np.full(n_robots, -1, dtype=np.int64)
            self.tie = np.random.default_rng(self.seed).random(n_robots)
            self.t = 0

    def order(self, n_robots: int) -> np.ndarray:
        """The ``n_robots`` robots by decreasing priority (``elapsed + tie``; ``elapsed`` counts steps
        since the goal, 1 + :data:`DEAD_END_BONUS` for a step ending in a dead end)."""
        self._ensure(n_robots)
        return np.lexsort((-self.tie, -self.elapsed)).astype(np.int64)

    def _check(self, pos, orient, goals):
        pos, orient, goals = _int_array("pos", pos), _int_array("orient", orient), _int_array("goals", goals)
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

    def actions(self, pos, orient, goals, deadline: float | None = None, rest=None) -> np.ndarray:
        """``(R,)`` int64 actions (0 F, 1 R, 2 C, 3 W) of robots at flat cells ``pos`` facing ``orient``
        heading to flat ``goals`` (a robot without a task takes its own cell); always a valid joint
        action.  Advances the priorities, assuming the actions are executed.  ``deadline``: the step's
        ``time.perf_counter()`` deadline under a clock, or ``None``; PIBT is one pass and does not need it.
        ``rest``: each robot's task beyond its goal in moves (:func:`mrmt_env.lorr.tasks.rest_under`), needed
        when :attr:`takes_rest`, else unused."""
        self.deadline = deadline
        pos, orient, goals = self._check(pos, orient, goals)
        goals = self.steer(pos, goals, rest)
        r = len(pos)
        order = self.order(r)
        pc = self.cid[pos]
        gc = self.cid[goals]
        fields, rows = self._heuristic(pc, gc, order)
        nxt = np.empty(r, dtype=np.int64)
        act = np.empty(r, dtype=np.int64)
        commit = self.commit if self.commits else np.full(r, -1, dtype=np.int64)
        t0 = time.perf_counter()
        turning_kernel(self.move_grid, TurnRobots(pc, orient, gc, commit), (fields, rows), order,
                       (self.seed, self.t), (nxt, act), (self._occ_now, self._occ_next))
        self.kernel_s = time.perf_counter() - t0  # the host rule's own seconds (a refinement's audit compares them)
        self._refine(pc, orient, gc, rows, order, nxt, act)
        self.targets = self.cell_of[nxt]
        moved = np.where(act == FORWARD, nxt, pc)
        if self.commits:  # a robot keeps claiming its cell until it stands on it
            self.commit = np.where(moved == nxt, -1, nxt)
        self._advance(moved, gc)
        return act

    def steer(self, pos, goals, rest=None) -> np.ndarray:
        """The flat goals a step heads for: under ``active`` < 1 only the robots at work keep theirs, those of least
        way to it by their goal fields (Manhattan distance without one; :mod:`planners.mapf.guides.focus`), plus
        ``rest`` under ``active_by="task"``; with ``park`` a robot without a goal heads for the nearest parking
        place."""
        if self.takes_rest:
            rest = checked_rest(rest, len(pos))
        if self.active < 1 or self.decides_work:
            pc, gc = self.cid[pos], self.cid[goals]
            rows = self.fields.rows(gc, self.order(len(pos)))
            way = self.field_distance(pc, gc, rows) + (rest if self.takes_rest else 0)
            goals = active_goals(pos, goals, way, active_count(self.active, len(pos)))
            if self.decides_work:
                goals = self.keep_at_work(pos, goals, pc, rows, way)
        if self.parking is not None:
            goals = self.parking.goals(pos, goals, self.cid, self.cell_of)
        return goals

    def field_distance(self, pc, gc, rows) -> np.ndarray:
        """Each robot's way from compact ``pc`` to ``gc`` by its goal field's row (Manhattan distance for row -1)."""
        a, b = self.cell_of[pc], self.cell_of[gc]
        way = np.abs(a // self.width - b // self.width) + np.abs(a % self.width - b % self.width)
        has = np.flatnonzero(rows >= 0)
        way[has] = self.fields.fields[rows[has], pc[has] * self.fields.per_cell].astype(np.int64)
        return way

    def _advance(self, moved, gc) -> None:
        """Priorities after the robots reach compact cells ``moved`` (goals ``gc``); the next call's step."""
        extra = DEAD_END_BONUS * self.dead_end[moved]
        self.elapsed = np.where(moved == gc, 0, self.elapsed + 1 + extra)
        self.t += 1

    def _heuristic(self, pc, gc, order):
        """``(fields, rows)``: PIBT ranks robot ``k``'s cells by ``fields[rows[k]]`` (here its goal's field;
        row -1: Manhattan distance)."""
        rows = self.goal_rows(pc, gc, order)  # first: it may grow the cache (a new array)
        return self.fields.fields, rows

    def goal_rows(self, pc, gc, order) -> np.ndarray:
        """The goal fields' rows of robots at compact ``pc`` heading to ``gc`` (:meth:`TurnFields.rows`); under
        ``congestion`` the fields take the crowd's costs now and up to ``refresh`` of them are recomputed (under a
        clock, stopping in time for the plans: :data:`FIELD_MARGIN_S` + twice the last pass before the deadline)."""
        if self.congestion is None:
            return self.fields.rows(gc, order)
        self.fields.cost = self.congestion.costs(pc)
        rows = self.fields.rows(gc, order)
        stop = None if self.deadline is None else self.deadline - FIELD_MARGIN_S - 2 * self.kernel_s
        self.congestion.update(self.fields, rows, stop)
        return rows

    def _refine(self, pc, orient, gc, rows, order, nxt, act) -> None:
        """Hook for subclasses: may change the claims ``nxt`` (compact cells; kept distinct and swap-free)
        and their actions ``act`` in place before they are applied (here: nothing)."""

    def step(self, pos, orient, goals):
        """:meth:`actions` applied: ``(next pos, next orient)``."""
        pos, orient = _int_array("pos", pos), _int_array("orient", orient)
        act = self.actions(pos, orient, goals)
        nxt = np.where(act == FORWARD, self.targets, pos)
        turn = np.where(act == CLOCKWISE, 1, np.where(act == COUNTER, 3, 0))
        return nxt, (orient + turn) % 4
