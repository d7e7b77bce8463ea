"""The start kit's default scheduler (``default_planner/scheduler.cpp``), the LoRR envs' default.

Each free robot takes the free task of least makespan (ties to the lowest task id), within a bounded search work
(:data:`DEFAULT_WORK_BUDGET`) or, under a clock, half the step, as the start kit does.
Design notes: docs/design/lorr_simulator.md#the-start-kits-greedy-scheduler.
"""

from __future__ import annotations

import time

import numba
import numpy as np

from mrmt_env.distances import bfs_until, free_neighbour

__all__ = ["GreedyScheduler", "pair_distances", "greedy_kernel", "FAR"]

#: Cost of an unreachable errand (larger than any path).
FAR = np.int64(1 << 40)
#: Cells a step's searches may visit without a clock (half for task lengths, half for robots): a deterministic
#: stand-in for the start kit's time limit.  Only fleets of thousands on large maps reach it (then the rest is
#: assigned in the next steps); it is about 2-2.5 s a step there (benchmarks/RESULTS.md, issue 56).
DEFAULT_WORK_BUDGET = 1 << 24
#: The largest weight of the way to a task's first errand (option ``way``; the 2024 winner's measure takes 5).
MAX_WAY = 64
#: Under a clock the greedy stops at half the time left less this (the start kit's scheduler tolerance).
STOP_TOLERANCE_S = 0.01


@numba.njit(cache=True, nogil=True)
def pair_distances(flat_grid, width, a, b, out) -> int:
    """``out[k]`` = BFS moves from ``a[k]`` to ``b[k]`` (flat cells), -1 if unreachable; returns the
    cells visited (the work done)."""
    n = flat_grid.shape[0]
    dist = np.full(n, -1, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    work = 0
    for k in range(a.shape[0]):
        s, g = a[k], b[k]
        out[k] = -1
        if s == g:
            out[k] = 0
            continue
        dist[s] = 0
        queue[0] = s
        tail = bfs_until(flat_grid, width, dist, queue, 1, g)
        out[k] = dist[g]
        work += tail
        for i in range(tail):
            dist[queue[i]] = -1
    return work


@numba.njit(cache=True, nogil=True)
def greedy_kernel(flat_grid, width, robots, cell_start, cell_tasks, length, task_id, free, min_len, budget,
                  way, out) -> int:
    """The greedy choice of every robot in ``robots`` (flat cells, in order): ``out[i]`` = the index
    of the free task of least ``way x BFS(robot, first errand) + length``, ties to the lowest ``task_id``
    (-1 if none is reachable); the task is then taken (``free[k] = False``).  Tasks sit at cells
    through ``cell_tasks[cell_start[c]:cell_start[c + 1]]``.  Each robot's BFS stops once ``way`` x its depth
    plus ``min_len`` exceeds the best cost found, so near tasks cost a small search.  Robots are
    taken in order until ``budget`` cells were visited (at least one); returns how many were."""
    n = flat_grid.shape[0]
    dist = np.full(n, -1, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    left = 0
    for k in range(free.shape[0]):
        if free[k]:
            left += 1
    work = 0
    for i in range(robots.shape[0]):
        out[i] = -1
        if i > 0 and work >= budget:
            return i
        if left == 0:
            continue
        s = robots[i]
        dist[s] = 0
        queue[0] = s
        head, tail = 0, 1
        best = np.int64(-1)
        best_cost = np.int64(1) << 62
        while head < tail:
            p = queue[head]
            head += 1
            d = dist[p]
            if way * d + min_len > best_cost:
                break
            for j in range(cell_start[p], cell_start[p + 1]):
                k = cell_tasks[j]
                if free[k]:
                    c = way * d + length[k]
                    if c < best_cost or (c == best_cost and task_id[k] < task_id[best]):
                        best_cost = c
                        best = k
            for m in range(4):
                q = free_neighbour(flat_grid, width, p, m)
                if q >= 0 and dist[q] < 0:
                    dist[q] = d + 1
                    queue[tail] = q
                    tail += 1
        work += tail
        for j in range(tail):
            dist[queue[j]] = -1
        if best >= 0:
            out[i] = best
            free[best] = False
            left -= 1
    return robots.shape[0]


class GreedyScheduler:
    """The start kit's default scheduler (see the module docstring); ``schedule(sim)`` -> proposal."""

    name = "lorr-greedy"
    accelerated = False

    def __init__(self, work_budget: int = DEFAULT_WORK_BUDGET, way: int = 1) -> None:
        if isinstance(work_budget, bool) or not isinstance(work_budget, int) or work_budget < 1:
            raise ValueError(f"work_budget must be an integer >= 1 (cells visited per step), got {work_budget!r}")
        if isinstance(way, bool) or not isinstance(way, int) or not 1 <= way <= MAX_WAY:
            raise ValueError(f"way = {way!r} must be an integer in [1, {MAX_WAY}] (the weight of the way to a task's "
                             f"first errand against its errand legs; 1 = the start kit's)")
        self.work_budget = work_budget
        self.way = way
        self._sim = None

    def reset(self, sim) -> None:
        self._sim = sim
        self.free_agents: set[int] = set()
        self.free_tasks: set[int] = set()
        self._length: dict[int, int] = {}   # task line -> errand-to-errand length
        self._seen_t = -1
        self.flat = np.ascontiguousarray(sim.inst.grid.reshape(-1))

    def task_length(self, tasks, ids: np.ndarray, budget: int, stop: float | None = None) -> np.ndarray:
        """Errand-to-errand length of each task (cached per file line; FAR if an errand is cut off;
        -1 while not computed: lines are measured in id order, 64 at a time, until ``budget`` cells were
        visited; under a ``stop`` time, 8 at a time until, after the first 8, ``time.perf_counter()`` passed it)."""
        inst = tasks.inst
        lines = [tasks.line[int(k)] for k in ids.tolist()]
        missing = [ln for ln in dict.fromkeys(lines) if ln not in self._length]
        work = 0
        chunk = 64 if stop is None else 8
        for lo in range(0, len(missing), chunk):
            if work >= budget or (lo > 0 and stop is not None and time.perf_counter() > stop):
                break
            a, b, owner = [], [], []
            for ln in missing[lo:lo + chunk]:
                e = inst.task_errands(ln)
                a.extend(e[:-1].tolist())
                b.extend(e[1:].tolist())
                owner.extend([ln] * (len(e) - 1))
                self._length[ln] = 0
            if a:
                d = np.empty(len(a), dtype=np.int64)
                work += pair_distances(self.flat, inst.width, np.array(a, dtype=np.int64),
                                       np.array(b, dtype=np.int64), d)
                for ln, v in zip(owner, d.tolist()):
                    self._length[ln] = int(FAR) if v < 0 or self._length[ln] >= FAR else self._length[ln] + v
        return np.array([self._length.get(ln, -1) for ln in lines], dtype=np.int64)

    def schedule(self, sim, deadline: float | None = None) -> np.ndarray:
        """The start kit's greedy proposal.  Without a ``deadline`` its work is bounded by :attr:`work_budget`
        (deterministic); with one (``time.perf_counter()`` seconds), as the start kit's, by the clock: it stops
        assigning at half the time left less 10 ms (the rest is the planner's): task lengths 8 lines at a time,
        then robots 16 at a time, at least 8 lines and 16 robots a step.  (Giving the robots half of that time
        assigned 2.5x the robots a step on CITY-02 but to tasks farther off: 3-5x fewer tasks in 200 steps.)"""
        now = time.perf_counter()
        stop = None if deadline is None else now + (deadline - now) / 2 - STOP_TOLERANCE_S
        if self._sim is not sim:
            self.reset(sim)
        tasks = sim.tasks
        if sim.t != self._seen_t:
            self.free_agents.update(tasks.new_free)
            self.free_tasks.update(tasks.new_tasks)
            self._seen_t = sim.t
        proposal = tasks.assigned.copy()
        self.free_agents = {a for a in self.free_agents if tasks.assigned[a] == -1}
        self.free_tasks = {k for k in self.free_tasks if k in tasks.open and tasks.holder[k] == -1}
        robots = sorted(self.free_agents)
        if not robots or not self.free_tasks:
            return proposal
        ids = np.array(sorted(self.free_tasks), dtype=np.int64)
        first = np.array([tasks.remaining(int(k))[0] for k in ids.tolist()], dtype=np.int64)
        budget = self.work_budget // 2 if stop is None else 1 << 62
        length = self.task_length(tasks, ids, budget, stop)
        ok = (length >= 0) & (length < FAR)
        order = np.argsort(first, kind="stable")
        counts = np.bincount(first, minlength=self.flat.size)
        cell_start = np.zeros(self.flat.size + 1, dtype=np.int64)
        np.cumsum(counts, out=cell_start[1:])
        free = ok.copy()
        min_len = int(length[ok].min()) if ok.any() else 0
        out = np.empty(len(robots), dtype=np.int64)
        cells, order = sim.pos[robots], order.astype(np.int64)
        done = 0
        step = len(robots) if stop is None else 16
        while done < len(robots) and (stop is None or done == 0 or time.perf_counter() <= stop):
            n = greedy_kernel(self.flat, sim.width, cells[done:done + step], cell_start, order, length, ids, free,
                              min_len, budget, self.way, out[done:done + step])
            done += n
            if stop is None:
                break
        for a, j in zip(robots[:done], out[:done].tolist()):
            if j >= 0:
                proposal[a] = ids[j]
                self.free_agents.discard(a)
                self.free_tasks.discard(int(ids[j]))
        return proposal
