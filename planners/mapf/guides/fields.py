"""Where a planner's cost-to-go comes from (a part of every planner with turning): goal fields over the free cells
(:class:`TurnFields`, a cache bounded in bytes and in BFS work per call), priced by lanes and one-way corridors
(:mod:`planners.mapf.guides.guidance`) and, with ``congestion``, by the crowd (:mod:`planners.mapf.guides.congestion`),
or, with ``flow``, each robot's field along its traffic-flow guide path (:class:`~planners.mapf.guides.flow.FlowGuide`).

Contract: ``FieldSource(site, FieldOptions, seed)``; :meth:`FieldSource.heuristic` ``(pc, gc, order, deadline,
last_s) -> (fields, rows)`` (robot ``k`` goes by ``fields[rows[k]]``, row -1: Manhattan distance);
:meth:`FieldSource.distance` ``(pc, gc, rows)``; :meth:`FieldSource.check_team` bounds the guide paths' memory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from planners.mapf.common import move_grid
from planners.mapf.guides.congestion import Congestion
from planners.mapf.guides.flow import (DEFAULT_GUIDE_WORK, GUIDE_MARGIN_S, FlowGuide, check_team, field_dtype)
from planners.mapf.guides.guidance import MAX_GUIDANCE, cost_rows, distance_bound, move_costs
from planners.options import Options, option

__all__ = ["FieldSource", "FieldOptions", "TurnFields", "DEFAULT_FIELD_BYTES", "DEFAULT_BFS_BUDGET",
           "DEFAULT_GUIDANCE", "DEFAULT_REFRESH", "FIELD_MARGIN_S", "GUIDED_WORK"]

#: Default memory bound of the goal-field cache (the fields of the goals asked for in one call are always kept).
DEFAULT_FIELD_BYTES = 1 << 30
#: Default BFS work of one call, in cells: new goal fields per call = this // free cells.
DEFAULT_BFS_BUDGET = 1 << 24
#: Extra cost of a move against its lane of PIBT with turning, by default: chosen on RANDOM-01..05 (0, 2 and 4 tried,
#: three seeds; docs/design/lifelong_turning.md).  The EPIBT planners and the guide paths default to 0.
DEFAULT_GUIDANCE = 2
#: Goal fields recomputed per call under ``congestion`` by default.
DEFAULT_REFRESH = 64
#: BFS fields' worth of work of one guided field (bucketed Dijkstra: 2.7 ms against 0.5 ms for BFS on CITY-01's
#: 47,240 free cells), so that a call's field budget holds under guidance too.
GUIDED_WORK = 5
#: Under a clock, refreshes of goal fields stop this long before the step's deadline, beyond twice the last pass.
FIELD_MARGIN_S = 0.03


@dataclass(frozen=True)
class FieldOptions(Options):
    """The cost-to-go's options (module docstring)."""

    guidance: int = option(DEFAULT_GUIDANCE, int, 0, MAX_GUIDANCE, meaning="extra cost of a forward move against "
                           "its lane (crisscross lanes, planners.mapf.guides.guidance; 0 = plain BFS distances)")
    corridors: int = option(0, int, 0, MAX_GUIDANCE, meaning="extra cost of a move against a one-way corridor "
                            "(corridors one cell wide, open at both ends, alternate their ways; 0 = off)")
    congestion: int = option(0, int, 0, MAX_GUIDANCE, meaning="extra cost of a move into a cell a robot stands on "
                             "now, in goal fields refreshed each call (the 2024 winner's dynamic heuristic; 0 = off; "
                             "needs flow=false)")
    refresh: int = option(DEFAULT_REFRESH, int, 0, 1 << 20, meaning="with congestion: goal fields recomputed per call "
                          "at most, first those with the most robots heading there x calls since computed")
    flow: bool = option(False, bool, meaning="rank by traffic-flow guide paths (FlowGuide) instead of the goal fields")
    replans: int | None = option(None, int, 0, 1 << 24, none=True, meaning="with flow: guide paths re-planned per "
                                 "call beyond those of new goals (null: one per robot, at most DEFAULT_REPLAN_WORK // "
                                 "free cells)")
    guide_work: int | None = option(DEFAULT_GUIDE_WORK, int, 1, 1 << 40, none=True, meaning="with flow: A* expansions "
                                    "per call for guide paths (null: no bound); under a clock they also stop "
                                    "GUIDE_MARGIN_S + twice the last pass before the deadline")
    field_bytes: int = option(DEFAULT_FIELD_BYTES, int, 1, 1 << 40, meaning="memory bound of the goal-field cache "
                              "(TurnFields; with flow, of the robots' fields and first paths)")
    bfs_budget: int = option(DEFAULT_BFS_BUDGET, int, 1, 1 << 40, meaning="BFS work per call in cells (new goal "
                             "fields per call = this // free cells; a goal without a field goes by Manhattan distance)")


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
        self.dtype: np.dtype = np.dtype(np.uint16 if top < 65535 else np.uint32)
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




class FieldSource:
    """The cost-to-go of one planner on ``site`` (a :class:`~planners.mapf.site.TurnSite`) under ``opts``
    (:class:`FieldOptions`; module docstring); ``ValueError`` for ``congestion`` with ``flow``."""

    def __init__(self, site, opts: FieldOptions, seed: int) -> None:
        if opts.congestion and opts.flow:
            raise ValueError(f"congestion = {opts.congestion} needs flow=false (the guide paths' A* takes the goal "
                             f"fields for its heuristic, which the crowd's costs would overestimate)")
        self.site, self.guidance = site, opts.guidance
        nbr, cell_of, width = site.nbr, site.cell_of, site.width
        self.move_cost = move_costs(nbr, cell_of, width, opts.guidance, opts.corridors)
        self.move_grid = move_grid(nbr, cell_of, width, self.move_cost)
        self.congestion, field_cost = None, self.move_cost
        if opts.congestion:
            base = np.ones((len(cell_of), 4), np.int64) if self.move_cost is None else self.move_cost
            self.congestion = Congestion(nbr, base, opts.congestion, opts.refresh)
            field_cost = self.congestion.bound()  # the fields' dtype holds the costliest moves
        self.fields = TurnFields(nbr, opts.field_bytes, opts.bfs_budget, cost=field_cost)
        self.guide = FlowGuide(nbr, cell_of, width, self.move_cost, opts.replans, opts.field_bytes, seed,
                               work=opts.guide_work) if opts.flow else None

    @staticmethod
    def check_team(grid, n_robots: int, opts: FieldOptions) -> None:
        """``ValueError`` when ``n_robots`` robots' guide paths and fields on ``grid`` exceed ``field_bytes`` (with
        ``flow``: a path and a field per robot); on the goal fields any team (their cache makes room)."""
        if opts.flow:
            from planners.mapf.common import compact_grid

            nbr = compact_grid(np.asarray(grid, dtype=bool))[2]
            check_team(nbr.shape[0], int(n_robots), int(opts.field_bytes), field_dtype(nbr)[0].itemsize)

    def goal_rows(self, pc, gc, order, deadline: float | None = None, last_s: float = 0.0) -> np.ndarray:
        """The goal fields' rows of robots at compact ``pc`` heading to ``gc`` (:meth:`TurnFields.rows`, ``order``
        the robots by decreasing priority); under ``congestion`` the fields take the crowd's costs now and up to
        ``refresh`` of them are recomputed (under a clock, stopping in time for the plans: :data:`FIELD_MARGIN_S` +
        twice the last pass, ``last_s``, before the deadline)."""
        if self.congestion is None:
            return self.fields.rows(gc, order)
        self.fields.cost = self.congestion.costs(pc)
        rows = self.fields.rows(gc, order)
        stop = None if deadline is None else deadline - FIELD_MARGIN_S - 2 * last_s
        self.congestion.update(self.fields, rows, stop)
        return rows

    def heuristic(self, pc, gc, order, deadline: float | None = None, last_s: float = 0.0):
        """``(fields, rows)``: robot ``k``'s cost-to-go is ``fields[rows[k]]`` (row -1: Manhattan distance), its goal
        field's or, with ``flow``, its guide path's (under a clock the paths stop :data:`GUIDE_MARGIN_S` + twice
        the last pass, ``last_s``, before the deadline)."""
        rows = self.goal_rows(pc, gc, order, deadline, last_s)  # first: it may grow the cache (a new array)
        if self.guide is None:
            return self.fields.fields, rows
        stop = None if deadline is None else deadline - GUIDE_MARGIN_S - 2 * last_s
        rows = self.guide.update(pc, gc, self.fields.fields, rows, stop)  # first: it may make the fields
        return self.guide.fields, rows

    def distance(self, pc, gc, rows) -> np.ndarray:
        """Each robot's way from compact ``pc`` to ``gc`` by its goal field's row (Manhattan distance for row -1)."""
        cell_of, width = self.site.cell_of, self.site.width
        a, b = cell_of[pc], cell_of[gc]
        way = np.abs(a // width - b // width) + np.abs(a % width - b % width)
        has = np.flatnonzero(rows >= 0)
        way[has] = self.fields.fields[rows[has], pc[has] * self.fields.per_cell].astype(np.int64)
        return way
