"""The start kit's default scheduler (``default_planner/scheduler.cpp``), the LoRR envs' default.

Each free robot (ascending index; the start kit walks a hash set) takes the free task of least
makespan -- the shortest way to its first errand, then through every errand in order (BFS, no
turning) -- ties to the lowest task id; a robot with no free task left waits for the next step.
Free robots and free tasks are remembered across steps as the start kit does.  Distances: one
BFS per free robot (its cell to every cell, in chunks so memory stays bounded) and each task's
errand-to-errand length once per task line (compiled early-exit BFS).
"""

from __future__ import annotations

import numba
import numpy as np

from mrmt_env.distances import bfs_flat

__all__ = ["GreedyScheduler", "pair_distances", "distance_rows", "FAR"]

#: Cost of an unreachable errand (larger than any path).
FAR = np.int64(1 << 40)
_CHUNK = 128


@numba.njit(cache=True, nogil=True)
def pair_distances(flat_grid, width, a, b, out) -> None:
    """``out[k]`` = BFS moves from ``a[k]`` to ``b[k]`` (flat cells), -1 if unreachable."""
    n = flat_grid.shape[0]
    h = n // width
    dist = np.full(n, -1, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    for k in range(a.shape[0]):
        s, g = a[k], b[k]
        out[k] = -1
        if s == g:
            out[k] = 0
            continue
        dist[s] = 0
        queue[0] = s
        head, tail = 0, 1
        found = -1
        while head < tail and found < 0:
            p = queue[head]
            head += 1
            r, c = p // width, p % width
            for m in range(4):
                nr = r + (-1, 1, 0, 0)[m]
                nc = c + (0, 0, -1, 1)[m]
                if 0 <= nr < h and 0 <= nc < width:
                    q = nr * width + nc
                    if not flat_grid[q] and dist[q] < 0:
                        dist[q] = dist[p] + 1
                        queue[tail] = q
                        tail += 1
                        if q == g:
                            found = dist[q]
        out[k] = found
        for i in range(tail):
            dist[queue[i]] = -1


@numba.njit(cache=True, nogil=True)
def _rows(flat_grid, width, sources, out) -> None:
    queue = np.empty(flat_grid.shape[0], dtype=np.int64)
    for k in range(sources.shape[0]):
        f = out[k]
        f[:] = -1
        f[sources[k]] = 0
        queue[0] = sources[k]
        bfs_flat(flat_grid, width, f, queue, 1)


def distance_rows(flat_grid: np.ndarray, width: int, sources: np.ndarray) -> np.ndarray:
    """``(K, H*W)`` int32 BFS distances from each flat source cell (-1 unreachable)."""
    sources = np.ascontiguousarray(sources, dtype=np.int64)
    out = np.empty((len(sources), flat_grid.shape[0]), dtype=np.int32)
    if len(sources):
        _rows(flat_grid, width, sources, out)
    return out


class GreedyScheduler:
    """The start kit's default scheduler (see the module docstring); ``schedule(sim)`` -> proposal."""

    name = "lorr-greedy"
    accelerated = False

    def __init__(self) -> None:
        self._sim = None

    def reset(self, sim) -> None:
        self._sim = sim
        self.free_agents: set[int] = set()
        self.free_tasks: set[int] = set()
        self._length: dict[int, int] = {}   # task line -> errand-to-errand length
        self._seen_t = -1
        self.flat = np.ascontiguousarray(sim.inst.grid.reshape(-1))

    def task_length(self, tasks, ids: np.ndarray) -> np.ndarray:
        """Errand-to-errand length of each task (cached per file line); FAR if an errand is cut off."""
        inst = tasks.inst
        lines = [tasks.line[int(k)] for k in ids.tolist()]
        missing = sorted({ln for ln in lines if ln not in self._length})
        if missing:
            a, b, owner = [], [], []
            for ln in missing:
                e = inst.task_errands(ln)
                a.extend(e[:-1].tolist())
                b.extend(e[1:].tolist())
                owner.extend([ln] * (len(e) - 1))
                self._length[ln] = 0
            if a:
                d = np.empty(len(a), dtype=np.int64)
                pair_distances(self.flat, inst.width, np.array(a, dtype=np.int64), np.array(b, dtype=np.int64), d)
                for ln, v in zip(owner, d.tolist()):
                    self._length[ln] = int(FAR) if v < 0 or self._length[ln] >= FAR else self._length[ln] + v
        return np.array([self._length[ln] for ln in lines], dtype=np.int64)

    def schedule(self, sim) -> np.ndarray:
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
        length = self.task_length(tasks, ids)
        free = np.ones(len(ids), dtype=bool)
        width = sim.width
        for lo in range(0, len(robots), _CHUNK):
            if not free.any():
                break
            chunk = robots[lo:lo + _CHUNK]
            rows = distance_rows(self.flat, width, sim.pos[chunk])[:, first].astype(np.int64)
            cost = np.where(rows < 0, FAR, rows + length)
            for i, a in enumerate(chunk):
                if not free.any():
                    break
                j = int(np.argmin(np.where(free, cost[i], FAR * 4)))
                proposal[a] = ids[j]
                free[j] = False
                self.free_agents.discard(a)
                self.free_tasks.discard(int(ids[j]))
        return proposal
