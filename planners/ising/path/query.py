"""The goal's distance field of an Ising path query (paper 5.1, ``target_key="bfs"``).

``GoalFields(config, frame)``: the BFS field that ranks local targets, padded like the grid;
every target's field is padded once per world (the world already holds them).
"""

from __future__ import annotations

import numpy as np

__all__ = ["GoalFields"]


class GoalFields:
    """Padded ranking fields of one path configuration (module docstring)."""

    def __init__(self, config, frame):
        self.bfs = config.target_key == "bfs"
        self.radius = frame.radius
        self._for = None  # (world, padded target fields, {target cell: index}) of the last world

    def goal(self, world, g) -> np.ndarray:
        """The ranking key's distance field of goal ``g``, padded like the grid: the world's BFS
        field of the goal (a target's is already computed), unreachable and outside cells last; an
        empty array for the paper's Manhattan key."""
        if not self.bfs:
            return np.zeros((0, 0), dtype=np.int64)
        stack, index = self._targets(world)
        k = index.get((int(g[0]), int(g[1])))
        return stack[k] if k is not None else self._pad(world.distance_field(g)[None])[0]

    def goals(self, world, goals) -> np.ndarray:
        """:meth:`goal` of every cell of ``goals`` (``(L, 2)``), stacked: ``(L, H', W')``, or
        ``(L, 0, 0)`` for the Manhattan key."""
        if not self.bfs:
            return np.zeros((len(goals), 0, 0), dtype=np.int64)
        stack, index = self._targets(world)
        rows = [index.get((int(r), int(c)), -1) for r, c in goals.tolist()]
        if min(rows) >= 0:
            return stack[rows]
        return np.stack([self.goal(world, g) for g in goals])

    def _targets(self, world) -> tuple[np.ndarray, dict]:
        """Every target's padded field ``(N, H', W')`` and ``{target cell: index}``, built once per world."""
        cached = self._for
        if cached is None or cached[0] is not world:
            index = {(int(r), int(c)): k for k, (r, c) in enumerate(np.asarray(world.targets).tolist())}
            self._for = cached = (world, self._pad(world.target_fields), index)
        return cached[1], cached[2]

    def _pad(self, fields: np.ndarray) -> np.ndarray:
        """``(k, H, W)`` BFS fields -> int64, padded by the patch radius; unreachable and outside cells
        get a distance beyond any path."""
        far = np.int64(2**40)
        r = self.radius
        k, h, w = fields.shape
        out = np.full((k, h + 2 * r, w + 2 * r), far, dtype=np.int64)
        inner = out[:, r: r + h, r: r + w]
        inner[...] = fields
        inner[fields < 0] = far
        return out
