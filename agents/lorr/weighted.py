"""``lorr-weighted``: the 2024 winner's measure as a scheduler that scales to ten thousand robots.

Cost of robot ``r`` taking task ``t``: ``weight x way(r, first errand of t) + legs(t)`` (the legs: errand to
errand through the task, the start kit's task length); the 2024 winner's scheduler weighs the way by 5 on
every map, with its own planner; with this package's PIBT a weight of 1 finished more on WAREHOUSE and
SORTATION (the default; docs/lorr.md).  Robots whose task is not opened yet are free again every step (``reassign``, the rules allow
it), so a robot that a better-placed one overtakes gives its task up.  The choice is the global greedy
matching: the pair of least cost first, ties to the lower robot, a cell's tasks shortest first, then the
lower id -- exact by lazy re-evaluation, as a pair's cost only grows when its cell's best task is taken.  With
``optimal`` the matching of least total cost instead (scipy's ``linear_sum_assignment``; the sparse RANDOM maps).
With ``jam`` > 0 a task's cost adds ``jam`` moves per robot standing in, or bound for, the ``block`` x ``block``
square of its first errand, the robots the matching sends counted as it goes (docs/lorr.md, "Jams on the
warehouse maps").

Distances come from one BFS table per first-errand cell (:class:`~planners.mapf.common.GoalFields`, the
start kit's heuristic table keyed by goal), bounded by ``memory_mb``: on the warehouse maps 352-620 cells
hold every task's start; a task's legs read the tables of its errands but the last, by symmetry of the
grid's distances.  Under a clock the missing tables are built 32 at a time until half the time left; tasks
whose tables are not built yet wait for a later step.  Design notes and measurements: docs/lorr.md.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

from mrmt_env.lorr.greedy import STOP_TOLERANCE_S
from planners.heap import pop, push
from planners.compute import ComputeReport
from planners.options import Options, option

__all__ = ["WeightedScheduler", "weighted_matching", "optimal_matching", "add_turns", "Crowd", "Matched",
           "DEFAULT_WEIGHT", "DEFAULT_MEMORY_MB", "DEFAULT_BLOCK"]

#: Weight of the way to the first errand against the task's legs (the 2024 winner's is 5; 1 measured better here).
DEFAULT_WEIGHT = 1
#: Memory for the distance tables, MiB (int32 per cell per table).
DEFAULT_MEMORY_MB = 2048
#: Tables built per chunk under a clock.
CHUNK = 32
#: Side of the square blocks the jam term counts robots in.
DEFAULT_BLOCK = 16
OptionsRecord = Options  # within a scheduler class the name ``Options`` is its record


class Crowd(NamedTuple):
    """The jam term of :func:`weighted_matching`: a cell's cost grows by ``weight`` per robot bound for its block."""

    block: np.ndarray  # (cells,) each candidate cell's block
    load: np.ndarray  # (blocks,) robots in or bound for each block; the matching adds the robots it sends
    weight: int  # moves per robot (0: off)


@numba.njit(cache=True, nogil=True)
def _best(way, cell_start, head, length, weight, crowd):
    """A robot's cheapest cell by its ``way`` to each (-1 if none reachable has a task left) and the cost."""
    best, best_cost = -1, np.int64(1) << 40
    for c in range(way.shape[0]):
        if head[c] >= cell_start[c + 1] or way[c] < 0:
            continue
        cost = weight * np.int64(way[c]) + length[head[c]] + crowd.weight * crowd.load[crowd.block[c]]
        if cost < best_cost:
            best, best_cost = c, cost
    return best, best_cost


@numba.njit(cache=True, nogil=True)
def weighted_matching(way, cell_start, length, weight, out, crowd) -> int:
    """The global greedy matching (module docstring).  ``way[i, c]``: moves from robot ``i`` to cell ``c`` (-1 cut
    off); cell ``c``'s tasks are the slots ``cell_start[c]:cell_start[c + 1]``, shortest first, ``length[slot]``
    their legs; ``crowd`` a :class:`Crowd` (its loads grow as robots are sent).  ``out[i]`` = the slot robot ``i``
    takes, -1 for none; returns the pairs made.  Costs only grow, so lazy re-evaluation stays exact."""
    n = way.shape[0]
    head = cell_start[:-1].copy()
    seen = np.empty(n, dtype=np.int64)   # the head of its cell when the robot's cost was taken
    seen_load = np.empty(n, dtype=np.int64)  # and its block's load
    cell = np.empty(n, dtype=np.int64)
    heap = np.empty((n, 1), dtype=np.int64)  # cost * n + robot
    size = 0
    for i in range(n):
        out[i] = -1
        c, cost = _best(way[i], cell_start, head, length, weight, crowd)
        cell[i] = c
        if c >= 0:
            seen[i], seen_load[i] = head[c], crowd.load[crowd.block[c]]
            size = push(heap, size, (cost * n + i,), 1)
    made = 0
    while size > 0:
        size = pop(heap, size, 1, 1)
        i = heap[size, 0] % n
        c = cell[i]
        if head[c] != seen[i] or (crowd.weight and crowd.load[crowd.block[c]] != seen_load[i]):
            # its cell's best task went to another robot, or more robots were sent to its block: cost again
            c, cost = _best(way[i], cell_start, head, length, weight, crowd)
            cell[i] = c
            if c >= 0:
                seen[i], seen_load[i] = head[c], crowd.load[crowd.block[c]]
                size = push(heap, size, (cost * n + i,), 1)
            continue
        out[i] = head[c]
        head[c] += 1
        crowd.load[crowd.block[c]] += 1
        made += 1
    return made


def optimal_matching(way, cell_start, length, weight, out) -> int:
    """As :func:`weighted_matching` (same arguments but the jam term), the matching of least total cost: as many
    pairs as the reachable pairs allow, then the least sum of ``weight x way + legs`` (scipy's
    ``linear_sum_assignment`` on robots by slots)."""
    from scipy.optimize import linear_sum_assignment

    out[:] = -1
    n, slots = way.shape[0], len(length)
    if n == 0 or slots == 0:
        return 0
    w = way[:, np.repeat(np.arange(len(cell_start) - 1), np.diff(cell_start))].astype(np.int64)
    cost = weight * w + np.asarray(length, dtype=np.int64)[None, :]
    big = int(cost.max(initial=0)) * min(n, slots) + 1  # a cut-off pair costs more than any matching of reachable ones
    cost = np.where(w >= 0, cost, big)
    rows, cols = linear_sum_assignment(cost)
    ok = cost[rows, cols] < big
    out[rows[ok]] = cols[ok]
    return int(ok.sum())


@numba.njit(cache=True, nogil=True)
def add_turns(table, rows, pos, orient, blocked, width, way) -> None:
    """In place: ``way[i, c]`` (moves from robot ``i`` to cell ``c``, read from ``table[rows[c]]``) plus the turns
    robot ``i`` needs before its first move along a shortest way there (0, 1 or 2: to the nearest direction that
    a shortest way leaves by); ``orient`` 0 east, 1 south, 2 west, 3 north; ``blocked`` the flat grid."""
    n, ncell = way.shape
    nb = np.empty(4, dtype=np.int64)
    for i in range(n):
        p, o = pos[i], orient[i]
        for d in range(4):
            q = p + (1, width, -1, -width)[d]
            edge = (d == 0 and p % width == width - 1) or (d == 2 and p % width == 0)
            nb[d] = q if 0 <= q < blocked.shape[0] and not edge and not blocked[q] else -1
        for c in range(ncell):
            f = way[i, c]
            if f <= 0:
                continue
            best = 2
            for d in range(4):
                if nb[d] >= 0 and table[rows[c], nb[d]] == f - 1:
                    k = (d - o) % 4
                    best = min(best, 2 if k == 2 else (0 if k == 0 else 1))
            way[i, c] = f + best


class Matched(NamedTuple):
    """One step's matching (:meth:`WeightedScheduler.match`): free ``robots``; the ready free tasks as slots
    ``ids`` (ordered by first-errand cell, legs, id), cell ``c``'s slots ``cell_start[c]:cell_start[c + 1]``,
    ``length`` their legs; ``way[i, c]`` robot ``i``'s moves to cell ``c``; ``crowd`` its jam term after the
    matching; ``out[i]`` the slot robot ``i`` took (-1 none)."""

    robots: np.ndarray
    ids: np.ndarray
    way: np.ndarray
    cell_start: np.ndarray
    length: np.ndarray
    weight: int
    crowd: Crowd
    out: np.ndarray


@dataclass(frozen=True)
class WeightedOptions(Options):
    """:class:`WeightedScheduler`'s options (``--scheduler-option``)."""

    weight: int = option(DEFAULT_WEIGHT, int, 0, 1000, meaning="the way to the first errand weighed against the "
                         "errand legs")
    reassign: bool = option(True, bool, meaning="robots whose task is not opened yet are free again every step")
    memory_mb: int = option(DEFAULT_MEMORY_MB, int, 1, 1 << 20, meaning="MiB for distance tables")
    jam: int = option(0, int, 0, 1000, meaning="moves per robot in or bound for a task's block (0 = off)")
    block: int = option(DEFAULT_BLOCK, int, 1, 4096, meaning="side of the jam term's blocks, cells")
    turns: bool = option(False, bool, meaning="the way counts the turns before the robot's first move along it")
    optimal: bool = option(False, bool, meaning="the matching of least total cost (scipy's linear_sum_assignment) "
                           "instead of the greedy one; takes no jam term")


class WeightedScheduler:
    """The winner's measure (module docstring); ``schedule(sim, deadline=None)`` -> proposal; ``options``: the
    fields of :class:`WeightedOptions`."""

    name = "lorr-weighted"
    accelerated = False
    Options: type[OptionsRecord] = WeightedOptions  # a subclass's may be a composed record (planners.options.record)

    def __init__(self, **options) -> None:
        self.options = opts = self.Options.from_dict(options, self.name)
        self.weight, self.reassign, self.memory_mb = opts.weight, opts.reassign, opts.memory_mb
        self.jam, self.block = opts.jam, opts.block
        if opts.optimal and opts.jam:
            raise ValueError(f"{self.name}: optimal=true takes no jam term (jam={opts.jam}; the jam term grows as the "
                             "greedy matching sends robots): give jam=0 or optimal=false")
        self.last_compute = ComputeReport()
        self._sim = None

    def reset(self, sim) -> None:
        from planners.mapf.common import GoalFields

        self._sim = sim
        cells = sim.inst.grid.size
        self.fields = GoalFields(sim.inst.grid, capacity=max(1, (self.memory_mb << 20) // (4 * cells)))
        self._legs: dict[int, int] = {}   # task file line -> legs (errand to errand)
        self._cells: dict[int, tuple] = {}  # task file line -> its errands
        self._needed: set = set()  # cells of the open free tasks' errands but the last

    def _errands(self, tasks, task: int) -> tuple:
        """The errands of ``task`` (cached per task file line)."""
        return self._line(tasks.inst, tasks.line[task])

    def _line(self, inst, line: int) -> tuple:
        cells = self._cells.get(line)
        if cells is None:
            cells = self._cells[line] = tuple(inst.task_errands(line).tolist())
        return cells

    def _ready(self, cells, stop: float | None) -> np.ndarray:
        """Build the missing tables of ``cells`` (under ``stop``: ``CHUNK`` at a time, at least one chunk, until
        ``time.perf_counter()`` passes it); returns which cells have one."""
        missing = [c for c in dict.fromkeys(cells) if not self.fields.has(c)]
        if missing and len(self.fields) + len(missing) > self.fields.capacity:
            self.fields.keep(self._needed)  # full: drop the tables no open task starts or passes at
        if stop is None:
            self.fields.rows(np.array(missing, dtype=np.int64))
        else:
            for lo in range(0, len(missing), CHUNK):
                if lo and time.perf_counter() > stop:
                    break
                self.fields.rows(np.array(missing[lo:lo + CHUNK], dtype=np.int64))
        return np.array([self.fields.has(c) for c in cells], dtype=bool)

    def legs(self, tasks, ids: list[int], stop: float | None = None) -> np.ndarray:
        """Errand-to-errand length of each task of ``ids`` (cached per file line; -1 while its tables wait for a
        later step under ``stop``; ``1 << 40`` when an errand is cut off)."""
        inst = tasks.inst
        lines = [tasks.line[k] for k in ids]
        todo = [ln for ln in dict.fromkeys(lines) if ln not in self._legs]
        if todo:
            errands = [self._line(inst, ln) for ln in todo]
            need = sorted({c for e in errands for c in e[:-1]})
            have = dict(zip(need, self._ready(need, stop).tolist()))
            todo = [(ln, e) for ln, e in zip(todo, errands) if all(have[c] for c in e[:-1])]
        if todo:
            a = np.array([c for _, e in todo for c in e[:-1]], dtype=np.int64)
            b = np.array([c for _, e in todo for c in e[1:]], dtype=np.int64)
            owner = np.repeat(np.arange(len(todo)), [len(e) - 1 for _, e in todo])
            d = self.fields.fields[self.fields.rows(a), b].astype(np.int64)
            total = np.zeros(len(todo), dtype=np.int64)
            np.add.at(total, owner, np.where(d < 0, 1 << 40, d))
            for (ln, _), v in zip(todo, np.minimum(total, 1 << 40).tolist()):
                self._legs[ln] = v
        return np.array([self._legs.get(ln, -1) for ln in lines], dtype=np.int64)

    def schedule(self, sim, deadline: float | None = None) -> np.ndarray:
        """This step's proposal (module docstring); under ``deadline`` the tables are built until half the time left."""
        proposal, m = self.match(sim, deadline)
        if m is not None:
            got = m.out >= 0
            proposal[m.robots[got]] = m.ids[m.out[got]]
        return proposal

    def match(self, sim, deadline: float | None = None):
        """``(proposal, matched)``: the robots holding opened tasks (the rest -1) and this step's
        :class:`Matched` (``None`` when no free robot or no ready free task is left)."""
        now = time.perf_counter()
        stop = None if deadline is None else now + (deadline - now) / 2 - STOP_TOLERANCE_S
        if self._sim is not sim:
            self.reset(sim)
        tasks = sim.tasks
        proposal = tasks.assigned.copy()
        if self.reassign:
            for a in np.flatnonzero(proposal >= 0).tolist():
                if not tasks.is_opened(int(proposal[a])):
                    proposal[a] = -1
        self.keep(sim, proposal)
        robots = np.flatnonzero(proposal < 0)
        held = set(proposal[proposal >= 0].tolist())
        free_ids = [k for k in tasks.open if k not in held]
        if len(robots) == 0 or not free_ids:
            return proposal, None
        self._needed = {c for k in free_ids for c in self._errands(tasks, k)[:-1]}
        first = np.array([self._errands(tasks, k)[0] for k in free_ids], dtype=np.int64)
        legs = self.legs(tasks, free_ids, stop)
        ok = (legs >= 0) & (legs < 1 << 40)
        ok &= self._ready(first.tolist(), stop)
        ids, first, legs = np.array(free_ids, dtype=np.int64)[ok], first[ok], legs[ok]
        if len(ids) == 0:
            return proposal, None
        order = np.lexsort((ids, legs, first))
        cells, start = np.unique(first[order], return_index=True)
        cell_start = np.append(start, len(order)).astype(np.int64)
        rows = self.fields.rows(cells)
        way = np.ascontiguousarray(self.fields.fields[np.ix_(rows, sim.pos[robots])].T)  # robot by cell, row-wise
        if self.options.turns:
            add_turns(self.fields.fields, rows, sim.pos[robots], sim.orient[robots], self.fields.grid,
                      sim.inst.grid.shape[1], way)
        out = np.empty(len(robots), dtype=np.int64)
        crowd = self.crowd(sim, proposal, cells)
        if self.options.optimal:
            optimal_matching(way, cell_start, legs[order], self.weight, out)
        else:
            weighted_matching(way, cell_start, legs[order], self.weight, out, crowd)
        return proposal, Matched(robots, ids[order], way, cell_start, legs[order], self.weight, crowd, out)

    def keep(self, sim, proposal) -> None:
        """In place: tasks kept out of this step's matching (none here)."""

    def crowd(self, sim, proposal, cells) -> Crowd:
        """The jam term for candidate ``cells``: per block, the robots standing in it and those of ``proposal``
        whose next errand lies in it (the matching adds the robots it sends)."""
        width = sim.inst.grid.shape[1]
        across = -(-width // self.block)

        def block(flat):
            return (flat // width // self.block) * across + flat % width // self.block

        blocks = -(-sim.inst.grid.shape[0] // self.block) * across
        load = np.zeros(blocks, dtype=np.int64)
        if self.jam:
            from mrmt_env.lorr.tasks import goals_under

            goals = goals_under(sim.tasks, proposal)
            load += np.bincount(block(sim.pos), minlength=blocks)
            load += np.bincount(block(goals[goals >= 0]), minlength=blocks)
        return Crowd(block(np.asarray(cells, dtype=np.int64)), load, self.jam)
