"""The ends of one Ising path query (paper 5.1): the goal's distance field going in, the result
coming out.

``_goal_field``: the BFS field that ranks local targets (``target_key="bfs"``), padded like the
grid; every target's field is padded once per world.  ``_finish``: the walk's loops cut, the path
checked (never an invalid path handed out), compute and statistics attached, or the failure named.
"""

from __future__ import annotations

import numpy as np

from planners.ising.path.kernels import cut_walk


__all__ = ["QueryEnds"]


class QueryEnds:
    """:class:`~planners.ising.path.IsingPath`'s query inputs and results (needs ``config``, ``frame``)."""

    def _goal_field(self, world, g) -> np.ndarray:
        """The ranking key's distance field, padded like the grid (``target_key="bfs"``): the
        world's BFS field of the goal (a target's is already computed), unreachable and outside
        cells last; an empty array for the paper's Manhattan key."""
        if self.config.target_key != "bfs":
            return np.zeros((0, 0), dtype=np.int64)
        stack, index = self._target_fields(world)
        k = index.get((int(g[0]), int(g[1])))
        return stack[k] if k is not None else self._pad_fields(world.distance_field(g)[None])[0]

    def _goal_fields(self, world, goals) -> np.ndarray:
        """:meth:`_goal_field` of every cell of ``goals`` (``(L, 2)``), stacked: ``(L, H', W')``, or
        ``(L, 0, 0)`` for the Manhattan key."""
        if self.config.target_key != "bfs":
            return np.zeros((len(goals), 0, 0), dtype=np.int64)
        stack, index = self._target_fields(world)
        rows = [index.get((int(r), int(c)), -1) for r, c in goals.tolist()]
        if min(rows) >= 0:
            return stack[rows]
        return np.stack([self._goal_field(world, g) for g in goals])

    def _target_fields(self, world) -> tuple[np.ndarray, dict]:
        """Every target's padded field ``(N, H', W')`` and ``{target cell: index}``, built once per world."""
        cached = self._fields_for
        if cached is None or cached[0] is not world:
            index = {(int(r), int(c)): k for k, (r, c) in enumerate(np.asarray(world.targets).tolist())}
            self._fields_for = cached = (world, self._pad_fields(world.target_fields), index)
        return cached[1], cached[2]

    def _pad_fields(self, fields: np.ndarray) -> np.ndarray:
        """``(k, H, W)`` BFS fields -> int64, padded by the patch radius; unreachable and outside cells
        get a distance beyond any path."""
        far = np.int64(2**40)
        r = self.frame.radius
        k, h, w = fields.shape
        out = np.full((k, h + 2 * r, w + 2 * r), far, dtype=np.int64)
        inner = out[:, r: r + h, r: r + w]
        inner[...] = fields
        inner[fields < 0] = far
        return out

    def _finish(self, grid, s, g, walk, counts, mapping, delta, failure, first_map_error):
        """The query's :class:`PathResult`: compute from the metered charge, statistics, the
        failure (naming mapping errors) or the loop-cut, checked path."""
        from planners.base import PathResult
        from planners.compute import ComputeReport

        compute = ComputeReport.from_ledger(delta)
        stats = {
            "chip_calls": int(delta.physical_calls),
            "chip_batches": int(delta.batches),
            **counts,
            "walk_length": len(walk) - 1,
            "mapping": {"path": mapping},
        }
        if failure is not None:
            n_err = sum(m["map_errors"] for m in mapping.values())
            if n_err and not any(m["programs"] for m in mapping.values()):
                failure = (f"no patch program could be mapped onto the chip ({n_err} mapping errors; "
                           f"first: {first_map_error}); search state: {failure}")
            elif n_err:
                failure += f"; {n_err} patch program(s) could not be mapped onto the chip, first: {first_map_error}"
            return PathResult(None, compute=compute, failure=failure, stats=stats)
        path = self._checked_path(grid, s, g, walk)
        if path is None:
            return PathResult(None, compute=compute, stats=stats,
                              failure="internal error: the stitched walk is not a valid 4-neighbour path")
        stats["path_length"] = len(path) - 1
        return PathResult(path, compute=compute, stats=stats)

    def _checked_path(self, grid, s, g, walk):
        """The walk (``(r, c)`` tuples or an ``(L, 2)`` array) with its loops cut, as an ``(L', 2)``
        array, or ``None`` if it is not a 4-neighbour path from ``s`` to ``g`` over free cells."""
        walk = np.asarray(walk, dtype=np.int64).reshape(-1, 2)
        ok, path = cut_walk(walk, np.asarray(grid, dtype=bool), s[0], s[1], g[0], g[1], self.config.cut_loops)
        return path if ok else None  # never hand out an invalid path
