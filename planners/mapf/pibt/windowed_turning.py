"""Windowed prioritized planning with turning (LoRR MAPF_T): space-time A* over (cell, orientation, time), compiled.

Each call rolls :class:`~planners.mapf.pibt.turning.TurningPIBT` out ``window`` steps
(several times, with different tie-breaks; the cheapest joint plan is kept): a
conflict-free plan, every robot's fallback.  Robots in TurningPIBT's priority
order then re-plan their window with A* over F / R / C / W against every other
robot's current plan (vertex and swap reservations), taking a plan that costs
no more (steps off the goal + the (cell, orientation) distance left,
:class:`OrientFields`).  The joint plan stays conflict-free, so its first step
is a valid joint action; every call re-plans.  Jam guards, measurements:
``docs/design/lifelong_windowed_turning.md``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from planners.mapf.guides.guidance import MAX_GUIDANCE, orient_cost_rows
from planners.mapf.pibt.options import LaneOptions
from planners.mapf.common import TurnRobots
from planners.mapf.pibt.turning import (CLOCKWISE, COUNTER, DEAD_END_BONUS, FORWARD, WAIT, TurnFields, TurningPIBT,
                                   turning_kernel)
from planners.options import option
from planners.mapf.pibt.windowed import SearchHeap, _pop_unseen, _push, new_heap

__all__ = ["WindowedTurningPlanner", "WindowedOptions", "OrientFields", "windowed_turning_kernel", "repair_kernel", "plan_cost",
           "DEFAULT_WINDOW", "MAX_WINDOW", "DEFAULT_EXPANSIONS", "DEFAULT_PATIENCE", "DEFAULT_ROLLOUTS",
           "DEFAULT_WORK"]

DEFAULT_WINDOW = 16
MAX_WINDOW = 64
#: A* expansions per robot and pass; a search out of budget keeps the robot's plan.
DEFAULT_EXPANSIONS = 512
#: Calls without a change of cell after which a robot keeps its PIBT plan.
DEFAULT_PATIENCE = 8
#: PIBT rollouts per call (the cheapest is re-planned).
DEFAULT_ROLLOUTS = 8
#: Robot-steps of PIBT rollout per call: fewer rollouts, then a shorter window, for big fleets.
DEFAULT_WORK = 1 << 17
_UNREACHABLE = 1 << 24
#: A* key = cost * _TURNS + turns on the way (fewest turns among equal costs).
_TURNS = 256


@numba.njit(cache=True, nogil=True)
def _orient_bfs_rows(nbr, goals, rows, fields, far):
    """``fields[rows[i], v * 4 + o]`` = actions from compact ``v`` facing ``o`` to ``goals[i]`` (any
    orientation), by BFS backwards: (v, o) is reached by F from the cell behind, by R from (v, o - 1),
    by C from (v, o + 1)."""
    n = nbr.shape[0]
    queue = np.empty(4 * n, dtype=np.int32)
    for i in range(goals.shape[0]):
        f = fields[rows[i]]
        f[:] = far
        tail = 0
        for o in range(4):
            f[goals[i] * 4 + o] = 0
            queue[tail] = goals[i] * 4 + o
            tail += 1
        head = 0
        while head < tail:
            s = queue[head]
            head += 1
            v, o = s >> 2, s & 3
            nd = f[s] + 1
            u = nbr[v, (o + 2) & 3]
            for q in (u * 4 + o if u >= 0 else -1, v * 4 + ((o + 3) & 3), v * 4 + ((o + 1) & 3)):
                if q >= 0 and f[q] == far:
                    f[q] = nd
                    queue[tail] = q
                    tail += 1


class WindowScratch(NamedTuple):
    """:func:`windowed_turning_kernel`'s work arrays."""

    occ: np.ndarray     # ((W + 1) * n) the window's reservations
    seen: np.ndarray    # ((W + 1) * 4n) A*'s visit stamps
    parent: np.ndarray  # ((W + 1) * 4n) and parents
    heap: SearchHeap    # A*'s heap


class OrientFields(TurnFields):
    """:class:`~planners.mapf.pibt.turning.TurnFields` over (free cell, orientation): ``fields[row, v * 4 + o]``
    = fewest actions from compact ``v`` facing ``o`` to the goal, facing any way, or their least cost
    under guidance (same cache bound, BFS budget in states)."""

    per_cell = 4
    plain_kernel = staticmethod(_orient_bfs_rows)
    cost_kernel = staticmethod(orient_cost_rows)


@numba.njit(cache=True, nogil=True)
def _h(grid, heuristic, row, v, o, goal):
    """Cost to go from compact ``v`` facing ``o``: its field (``row`` of ``heuristic = (fields, rows, far)``),
    Manhattan distance without one."""
    fields, _, far = heuristic
    if row >= 0:
        d = fields[row, v * 4 + o]
        return _UNREACHABLE if d == far else np.int64(d)
    a, b, width = grid.cell_of[v], grid.cell_of[goal], grid.width
    return abs(a // width - b // width) + abs(a % width - b % width)


@numba.njit(cache=True, nogil=True)
def _cost(grid, heuristic, paths, k, w, goal):
    """Robot ``k``'s plan cost: its steps not spent on the goal (a forward move from ``v`` facing ``o``
    costs ``grid.cost[v, o]``, anything else 1) + the cost to go from its last state."""
    move = grid.cost
    c = 0
    for t in range(w):
        s, s2 = paths[k, t], paths[k, t + 1]
        if s >> 2 != s2 >> 2:
            c += move[s >> 2, s & 3]
        elif s >> 2 != goal:
            c += 1
    last = paths[k, w]
    _, rows, _ = heuristic
    return c + _h(grid, heuristic, rows[k], last >> 2, last & 3, goal)


@numba.njit(cache=True, nogil=True)
def plan_cost(grid, heuristic, paths, goals) -> int:
    """Sum over robots of the plan cost (steps off the goal + cost to go from the last state); ``grid`` a
    :class:`~planners.mapf.common.MoveGrid`, ``heuristic = (fields, rows, far)``."""
    w = paths.shape[1] - 1
    total = 0
    for k in range(paths.shape[0]):
        total += _cost(grid, heuristic, paths, k, w, goals[k])
    return total


@numba.njit(cache=True, nogil=True)
def _reserve(occ, paths, k, n, w, who):
    for t in range(w + 1):
        occ[t * n + (paths[k, t] >> 2)] = who


@numba.njit(cache=True, nogil=True)
def windowed_turning_kernel(grid, goals, heuristic, order, limits, keep, paths, scratch, stamp):
    """Re-plan every robot's window in ``order`` against all the others' plans (compact cells):
    ``paths[k, t]`` = robot ``k``'s ``v * 4 + o`` at step ``t``, a conflict-free joint plan on entry and
    on return; a robot with ``keep[k]`` keeps its plan, another takes the plan A* finds within
    ``expansions`` when it costs no more (and does not stand still off the goal where the old plan
    moved).  ``grid`` a :class:`~planners.mapf.common.MoveGrid`; ``heuristic = (fields, rows, far)``, the
    (cell, orientation) fields; ``limits = (window, expansions)``; ``scratch`` a :class:`WindowScratch`:
    ``occ ((W+1)*n)`` -1 on entry and return; ``seen`` / ``parent`` A* scratch over
    ``(W+1)*4n`` states, ``stamp`` their last stamp.  Returns ``(stamp, plans improved, searches out
    of budget)``."""
    nbr, move = grid.nbr, grid.cost
    _, rows, _ = heuristic
    window, expansions = limits
    occ, seen, parent, heap = scratch.occ, scratch.seen, scratch.parent, scratch.heap
    n = nbr.shape[0]
    ns = 4 * n
    w = window
    r = paths.shape[0]
    for k in range(r):
        _reserve(occ, paths, k, n, w, k)
    improved = failed = 0
    for idx in range(r):
        k = order[idx]
        goal, row = goals[k], rows[k]
        bound = _cost(grid, heuristic, paths, k, w, goal)
        if bound == 0 or keep[k]:
            continue
        _reserve(occ, paths, k, n, w, -1)
        stamp += 1
        s0 = paths[k, 0]
        size = _push(heap, 0, _h(grid, heuristic, row, s0 >> 2, s0 & 3, goal) * _TURNS, 0, s0, -1)
        best = -1
        popped = 0
        while size > 0 and popped < expansions:
            size = _pop_unseen(heap, size, seen, stamp, parent)
            if size < 0:
                break
            f, g, s = heap.f[size], heap.g[size], heap.state[size]
            popped += 1
            t = s // ns
            if t == w:
                best = s
                break
            v, o = (s % ns) >> 2, s & 3
            for a in range(4):
                v2, o2 = v, o
                if a == FORWARD:
                    v2 = nbr[v, o]
                    if v2 < 0:
                        continue
                elif a == CLOCKWISE:
                    o2 = (o + 1) & 3
                elif a == COUNTER:
                    o2 = (o + 3) & 3
                s2 = ((t + 1) * n + v2) * 4 + o2
                if seen[s2] == stamp or occ[(t + 1) * n + v2] != -1:
                    continue
                if v2 != v:
                    j = occ[(t + 1) * n + v]  # the robot coming into my cell ...
                    if j != -1 and occ[t * n + v2] == j:  # ... from the cell I go to: a swap
                        continue
                g2 = g + (move[v, o] if v2 != v else (0 if v == goal else 1))
                f2 = g2 + _h(grid, heuristic, row, v2, o2, goal)
                if f2 <= bound:  # key: cost, then turns (no turn where a wait does as well)
                    turns = f % _TURNS + (1 if a == CLOCKWISE or a == COUNTER else 0)
                    size = _push(heap, size, f2 * _TURNS + min(turns, _TURNS - 1), g2, s2, s)
        if best == -1:
            failed += 1
        elif best % ns != paths[k, 0] or paths[k, 0] >> 2 == goal or paths[k, w] == paths[k, 0]:
            s = best  # (standing still off the goal replaces no plan: it would freeze a jam for good)
            while s != -1:
                paths[k, s // ns] = s % ns
                s = parent[s]
            if _cost(grid, heuristic, paths, k, w, goal) < bound:
                improved += 1
        _reserve(occ, paths, k, n, w, k)
    for k in range(r):
        _reserve(occ, paths, k, n, w, -1)
    return stamp, improved, failed


@numba.njit(cache=True, nogil=True)
def repair_kernel(nbr, pos, orient, act, order, nxt, owner, occ_now) -> int:
    """Make every F that breaks a rule wait, until none does: a cell ahead off the map or blocked, a
    cell another robot stays in or a higher-priority F takes, a swap.  ``nxt[k]`` = robot ``k``'s next
    compact cell on return; ``owner`` / ``occ_now`` scratch over cells, -1 on entry and on return.
    Returns the F actions turned into waits."""
    r = pos.shape[0]
    for k in range(r):
        occ_now[pos[k]] = k
    changed = 0
    again = True
    while again:
        again = False
        for k in range(r):
            nxt[k] = pos[k]
            if act[k] == FORWARD:
                nxt[k] = nbr[pos[k], orient[k]]
                if nxt[k] < 0:
                    act[k] = WAIT
                    nxt[k] = pos[k]
                    changed += 1
        for k in range(r):
            if act[k] != FORWARD:
                owner[pos[k]] = k
        for idx in range(r):
            k = order[idx]
            if act[k] != FORWARD:
                continue
            j = occ_now[nxt[k]]
            if owner[nxt[k]] != -1 or (j != -1 and act[j] == FORWARD and nxt[j] == pos[k]):
                act[k] = WAIT
                changed += 1
                again = True
            else:
                owner[nxt[k]] = k
        for k in range(r):
            owner[nxt[k]] = -1
            owner[pos[k]] = -1
    for k in range(r):
        occ_now[pos[k]] = -1
        if act[k] != FORWARD:
            nxt[k] = pos[k]
    return changed


@dataclass(frozen=True)
class WindowedOptions(LaneOptions):
    """:class:`WindowedTurningPlanner`'s options: the goal fields' (:class:`~planners.mapf.pibt.turning.LaneOptions`;
    ``field_bytes``, ``bfs_budget`` bound each cache: BFS distance for the rollout, (cell, orientation) distance for
    A*; lanes off by default: on RANDOM-01..05 they helped at 400-700 robots and cost tasks at 100-200 and 800)
    and the windows'."""

    guidance: int = option(0, int, 0, MAX_GUIDANCE, meaning="extra cost of a move against its lane (rollouts, "
                           "fields and A*'s step costs; 0 = off)")
    window: int = option(DEFAULT_WINDOW, int, 2, MAX_WINDOW, meaning="planning horizon in steps (with 1, A* undoes "
                         "the turns by which PIBT makes way: robots facing each other wait for good)")
    expansions: int = option(DEFAULT_EXPANSIONS, int, 1, 1 << 30, meaning="A* expansions per robot and pass (a "
                             "search out of budget keeps the plan)")
    passes: int = option(1, int, 0, 1 << 10, meaning="re-planning passes over all robots per call (0: no A*, the "
                         "cheapest rollout runs; with rollouts=1 too the actions are TurningPIBT's)")
    rollouts: int = option(DEFAULT_ROLLOUTS, int, 1, 1 << 10, meaning="PIBT rollouts per call, the first with the "
                           "planner's own tie-breaks, the others drawn from (seed, step, k); the cheapest is re-planned")
    patience: int = option(DEFAULT_PATIENCE, int, 0, 1 << 20, meaning="a robot that has not changed cell for more "
                           "than this many calls keeps its PIBT plan")
    work: int = option(DEFAULT_WORK, int, 1, 1 << 40, meaning="robot-steps of rollout per call: with more robots, "
                       "fewer rollouts (at least 1), then a shorter window (at least 2)")


class WindowedTurningPlanner(TurningPIBT):
    """Windowed prioritized planning with turning on one grid (see the module docstring); shares
    :class:`~planners.mapf.pibt.turning.TurningPIBT`'s input checks, priorities and :meth:`step`.

    Args:
        grid: ``(H, W)`` bool obstacles.
        seed: priority tie-breaks (of the PIBT rollout too).
        options: the fields of :class:`WindowedOptions`.
    """

    name = "windowed"
    Options = WindowedOptions

    def __init__(self, grid: np.ndarray, seed: int = 0, **options) -> None:
        super().__init__(grid, seed=seed, **options)
        opts = self.options
        self.window, self.expansions, self.passes = opts.window, opts.expansions, opts.passes
        self.rollouts, self.patience, self.work = opts.rollouts, opts.patience, opts.work
        self.ofields = OrientFields(self.nbr, opts.field_bytes, opts.bfs_budget, cost=self.move_cost)
        n = len(self.cell_of)
        states = (self.window + 1) * 4 * n
        self._scratch = WindowScratch(np.full((self.window + 1) * n, -1, dtype=np.int64),
                                      np.zeros(states, dtype=np.int64), np.zeros(states, dtype=np.int64),
                                      new_heap(4 * self.expansions + 1))
        self._stamp = 0
        self.still, self._prev = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
        self.paths = np.zeros((0, self.window + 1), dtype=np.int64)
        #: per call: plans A* improved, searches out of budget (all passes); F the repair pass made wait
        self.improved = self.failed = self.repairs = 0

    def effort(self, n_robots: int) -> tuple[int, int]:
        """``(window, rollouts)`` of a call with ``n_robots`` robots under :attr:`work`."""
        window = min(self.window, max(self.work // max(n_robots, 1), 2))
        return window, min(self.rollouts, max(self.work // (max(n_robots, 1) * window), 1))

    def _rollout(self, pc, orient, gc, order, window, k: int = 0) -> np.ndarray:
        """TurningPIBT's next ``window`` joint actions from here (goals fixed, priorities advanced on a
        copy) as ``(R, window + 1)`` compact ``v * 4 + o``: a conflict-free joint plan.  Rollout ``k > 0``
        draws its tie-breaks (of cells and of priorities) from ``(seed, step, k)``."""
        r = len(pc)
        rows = self.fields.rows(gc, order)
        seed, tie = self.seed, self.tie
        if k:
            rng = np.random.default_rng((self.seed, self.t, k))
            seed, tie = int(rng.integers(1 << 62)), rng.random(r)
            order = np.lexsort((-tie, -self.elapsed)).astype(np.int64)
        paths = np.empty((r, window + 1), dtype=np.int64)
        pos, ori, elapsed = pc.copy(), orient.copy(), self.elapsed.copy()
        nxt, act = np.empty(r, dtype=np.int64), np.empty(r, dtype=np.int64)
        none = np.full(r, -1, dtype=np.int64)  # no commitments in a rollout
        paths[:, 0] = pos * 4 + ori
        for i in range(window):
            turning_kernel(self.move_grid, TurnRobots(pos, ori, gc, none), (self.fields.fields, rows),
                           order, (seed, self.t + i), (nxt, act), (self._occ_now, self._occ_next))
            pos = np.where(act == FORWARD, nxt, pos)
            ori = (ori + np.where(act == CLOCKWISE, 1, np.where(act == COUNTER, 3, 0))) % 4
            elapsed = np.where(pos == gc, 0, elapsed + 1 + DEAD_END_BONUS * self.dead_end[pos])
            order = np.lexsort((-tie, -elapsed)).astype(np.int64)
            paths[:, i + 1] = pos * 4 + ori
        return paths

    def actions(self, pos, orient, goals, deadline: float | None = None) -> np.ndarray:
        """``(R,)`` int64 actions (0 F, 1 R, 2 C, 3 W), always a valid joint action; :attr:`paths` holds
        the planned windows as ``(R, w + 1)`` ``flat cell * 4 + orientation`` (``w`` from :meth:`effort`).
        Advances the priorities, assuming the actions are executed."""
        pos, orient, goals = self._check(pos, orient, goals)
        r = len(pos)
        order = self.order(r)
        pc, gc = self.cid[pos], self.cid[goals]
        window, rollouts = self.effort(r)
        paths = self._rollout(pc, orient, gc, order, window)
        rows = self.ofields.rows(gc, order)
        far = self.ofields.dtype.type(self.ofields.far)
        if rollouts > 1:
            best = plan_cost(self.move_grid, (self.ofields.fields, rows, far), paths, gc)
            for k in range(1, rollouts):
                other = self._rollout(pc, orient, gc, order, window, k)
                cost = plan_cost(self.move_grid, (self.ofields.fields, rows, far), other, gc)
                if cost < best:
                    paths, best = other, cost
        self.improved = self.failed = 0
        if len(self.still) != r:
            self.still, self._prev = np.zeros(r, dtype=np.int64), pos
        self.still = np.where(pos == self._prev, self.still + 1, 0)  # calls since the robot changed cell
        self._prev = pos
        keep = self.still > self.patience
        for _ in range(self.passes):
            self._stamp, improved, failed = windowed_turning_kernel(
                self.move_grid, gc, (self.ofields.fields, rows, far), order,
                (window, self.expansions), keep, paths, self._scratch, self._stamp)
            self.improved += improved
            self.failed += failed
        p0, p1 = paths[:, 0], paths[:, 1]
        turn = np.where((p1 & 3) == ((p0 + 1) & 3), CLOCKWISE, np.where((p1 & 3) == ((p0 + 3) & 3), COUNTER, WAIT))
        act = np.where((p1 >> 2) != (p0 >> 2), FORWARD, turn).astype(np.int64)
        nxt = np.empty(r, dtype=np.int64)
        self.repairs = repair_kernel(self.nbr, pc, orient, act, order, nxt, self._occ_now, self._occ_next)
        self.paths = self.cell_of[paths >> 2] * 4 + (paths & 3)
        self.targets = self.cell_of[nxt]
        self.elapsed = np.where(nxt == gc, 0, self.elapsed + 1 + DEAD_END_BONUS * self.dead_end[nxt])
        self.t += 1
        return act
