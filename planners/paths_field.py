"""Path layer ``field``: a leg is a descent of the goal's BFS distance field, which the host holds.

Host work with no search and no chip call (the ``ising`` preset's legs): from each cell, the first neighbour one
step closer in :data:`mrmt_env.distances.MOVES` order. A goal that is not a target gets its field by one BFS
(``stats["field_bfs"]``). Design notes: docs/design/field_paths.md#the-field-layers-contract.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from mrmt_env.world import World
from planners.base import PathResult
from planners.compute import ComputeReport

__all__ = ["FieldPath", "FieldLegs", "descend"]


@numba.njit(cache=True, nogil=True)
def descend(dist, sr, sc):
    """The descent of BFS field ``dist`` (``(H, W)`` int32, -1 unreachable, 0 at the goal) from
    ``(sr, sc)``: ``(L+1, 2)`` int64 cells, start first; zero rows when the start is unreachable."""
    h, w = dist.shape
    d = dist[sr, sc]
    if d < 0:
        return np.zeros((0, 2), dtype=np.int64)
    path = np.empty((d + 1, 2), dtype=np.int64)
    r, c = sr, sc
    path[0, 0] = r
    path[0, 1] = c
    for step in range(1, d + 1):
        want = d - step
        if r > 0 and dist[r - 1, c] == want:
            r -= 1
        elif r < h - 1 and dist[r + 1, c] == want:
            r += 1
        elif c > 0 and dist[r, c - 1] == want:
            c -= 1
        else:  # a BFS field always has a neighbour one closer; it is the right one
            c += 1
        path[step, 0] = r
        path[step, 1] = c
    return path


@dataclass
class FieldLegs:
    """A robot's legs planned in one call (the pipeline's batched-legs contract)."""

    paths: list = field(default_factory=list)
    compute: ComputeReport = field(default_factory=ComputeReport)
    stats: dict = field(default_factory=dict)


class FieldPath:
    """Path layer ``field``: legs as descents of the goal's BFS field (module docstring)."""

    name = "field"

    def __init__(self) -> None:
        self._world = None
        self._index = None

    def _target_index(self, world: World) -> np.ndarray:
        """``(H, W)`` int64: the target index of each target cell, -1 elsewhere (cached per world)."""
        if self._world is not world:
            index = np.full(world.shape, -1, dtype=np.int64)
            index[world.targets[:, 0], world.targets[:, 1]] = np.arange(world.n_targets)
            self._world, self._index = world, index
        return self._index

    def _leg(self, world: World, start, goal, stats: dict):
        """``(path or None, failure or None)`` of one leg."""
        (sr, sc), (gr, gc) = (int(start[0]), int(start[1])), (int(goal[0]), int(goal[1]))
        for name, (r, c) in (("start", (sr, sc)), ("goal", (gr, gc))):
            if not world.is_free((r, c)):
                return None, f"{name} cell {[r, c]} is off the {world.height}x{world.width} grid or on an obstacle"
        t = self._target_index(world)[gr, gc]
        if t >= 0:
            dist = world.target_fields[t]
        else:
            dist = world.distance_field((gr, gc))
            stats["field_bfs"] = stats.get("field_bfs", 0) + 1
        path = descend(dist, sr, sc)
        if len(path) == 0:
            return None, f"goal {[gr, gc]} is unreachable from {[sr, sc]}"
        return path, None

    def find_path(self, world: World, start, goal, rng: np.random.Generator | None = None) -> PathResult:
        stats: dict = {}
        path, failure = self._leg(world, start, goal, stats)
        return PathResult(path, failure=failure, stats={**stats, "field_legs": int(path is not None)})

    def find_paths(self, world: World, cells, rng: np.random.Generator | None = None) -> FieldLegs:
        """The legs ``cells[j] -> cells[j + 1]`` up to the first that fails (the pipeline replans
        that one with :meth:`find_path`, which gives it its failure)."""
        out = FieldLegs()
        for j in range(len(cells) - 1):
            path, failure = self._leg(world, cells[j], cells[j + 1], out.stats)
            if failure:
                break
            out.paths.append(path)
        out.stats["field_legs"] = len(out.paths)
        return out

    def __repr__(self) -> str:
        return "FieldPath()"
