"""The legs of one robot's route in one call of the Ising path layer (paper 5.1, batched).

Contract: ``IsingPath.find_paths(world, cells, rng) -> LegBatch`` plans the legs ``cells[j] ->
cells[j + 1]`` one after another exactly as ``find_path`` would (same compiled query loop, same
random stream, same paths), but builds one compute report and one statistics dict for all of
them (equal to the merge of the per-leg ones) instead of a result per leg.  It stops before the
first leg the compiled loop does not reach the goal of (a failure, a program it cannot map, an
invalid cell): the rng is left as it was before that leg and ``LegBatch.paths`` holds the legs
done, so the caller plans the rest with ``find_path``, which gives that leg its own result,
failure and fallback.  Only chips the compiled loop may drive are batched (``paths`` empty
otherwise).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planners.ising.path.engine import REACHED

__all__ = ["LegBatch", "BatchedLegs"]

_COUNTS = ("patch_solves", "anneal_calls", "segments", "backtracks", "direct_moves")


@dataclass
class LegBatch:
    """The legs planned in one call: their paths, one compute report and one statistics dict."""

    paths: list = field(default_factory=list)
    compute: object = None
    stats: dict = field(default_factory=dict)


class BatchedLegs:
    """:class:`~planners.ising.path.IsingPath`'s batch of legs (needs ``config``, ``chip``,
    ``_engine_args``, ``_goal_field``, ``_engine_query`` and ``_checked_path``)."""

    def find_paths(self, world, cells, rng: np.random.Generator) -> LegBatch:
        """Plan the legs of ``cells`` (``(L + 1, 2)``: a start, then the stops) until the first one
        the compiled loop cannot finish (module docstring)."""
        from ising_backend import CallLedger
        from planners.compute import ComputeReport

        cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
        grid = world.grid
        h, w = grid.shape
        paths: list = []
        if self._engine_args is None or len(cells) < 2:
            return LegBatch(compute=ComputeReport())
        inside = (cells[:, 0] >= 0) & (cells[:, 0] < h) & (cells[:, 1] >= 0) & (cells[:, 1] < w)
        styles = self.config.styles
        counts = np.zeros(len(_COUNTS), dtype=np.int64)
        mapping = np.zeros((len(styles), 4), dtype=np.int64)
        calls: list = []
        emu: list = []
        walked = 0
        for j in range(len(cells) - 1):
            if not (inside[j] and inside[j + 1]) or grid[cells[j, 0], cells[j, 1]] or grid[cells[j + 1, 0], cells[j + 1, 1]]:
                break  # find_path names the bad cell
            s = (int(cells[j, 0]), int(cells[j, 1]))
            g = (int(cells[j + 1, 0]), int(cells[j + 1, 1]))
            state = rng.bit_generator.state
            status, _end, walk, leg_counts, leg_map, sub_calls, sub_emu = self._engine_query(
                grid, s, g, rng, self._goal_field(world, g))
            path = self._checked_path(grid, s, g, walk) if status == REACHED else None
            if path is None:  # find_path redoes this leg and names what went wrong
                rng.bit_generator.state = state
                break
            paths.append(path)
            counts += leg_counts
            mapping += leg_map
            calls.append(sub_calls)
            emu.append(sub_emu)
            walked += len(walk) - 1
        if not paths:
            return LegBatch(compute=ComputeReport())
        charged = CallLedger()
        for delta in self.chip.charge(np.concatenate(calls), np.concatenate(emu)):
            charged._add_in_place(delta)
        stats = {
            "chip_calls": int(charged.physical_calls),
            "chip_batches": int(charged.batches),
            **{name: int(v) for name, v in zip(_COUNTS, counts)},
            "walk_length": walked,
            "mapping": {"path": {st: {"programs": int(r[0]), "valid": int(r[1]), "wins": int(r[2]),
                                      "map_errors": int(r[3])} for st, r in zip(styles, mapping)}},
            "path_length": sum(len(p) - 1 for p in paths),
        }
        return LegBatch(paths=paths, compute=ComputeReport.from_ledger(charged), stats=stats)
