"""The legs of one robot's route in one call of the Ising path layer (paper 5.1, batched).

Contract: ``plan_legs(runner, fields, world, cells, rng) -> LegBatch`` plans the legs ``cells[j] ->
cells[j + 1]`` exactly as ``find_path`` would (same compiled loop, random stream and paths) in one
compiled call (:func:`run_legs`) with one compute report and one statistics dict.  It stops at the first
leg that fails: ``LegBatch.paths`` holds the legs done, ``LegBatch.failed`` that leg's own result; the
caller plans the rest with ``find_path``.  Design notes: docs/design/ising_path.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numba
import numpy as np

from ising_backend import CallLedger, ChipUnavailableError, SolverOutputError, record_of_reads
from planners.compute import ComputeReport
from planners.ising.path.engine import COUNT_NAMES, REACHED, run_query
from planners.ising.path.kernels import cut_walk

__all__ = ["LegBatch", "plan_legs", "run_legs"]


@dataclass
class LegBatch:
    """The legs planned in one call: their paths, one compute report and one statistics dict."""

    paths: list = field(default_factory=list)
    compute: object = None
    stats: dict = field(default_factory=dict)
    failed: object = None  # the PathResult of leg len(paths) when the batch stopped at it


class LegsOut(NamedTuple):
    """:func:`run_legs`' result: leg ``j``'s path is ``points[ends[j]:ends[j + 1]]``; counts, mapping and
    walk steps are those of the legs done."""

    done: int  # the legs done
    points: np.ndarray  # (T, 2) their paths, one after the other
    ends: np.ndarray  # (done + 1,)
    counts: np.ndarray  # (5,) by the engine's COUNT_NAMES
    mapping: np.ndarray  # (k, 4) per style: reads, valid reads, wins, map_errors
    calls: np.ndarray  # per chip submission: its calls (the first n_sub the legs done', the rest the leg not done)
    emu: np.ndarray  # and emulation seconds
    walked: int  # walk steps
    last: object  # the QueryOut of the last leg run (the one not done when done < L)
    n_sub: int


@numba.njit(cache=True)
def usable_legs(cells, grid):
    """The legs of ``cells`` ``(L + 1, 2)`` before the first cell off ``grid`` or on an obstacle (the
    leg into it and, for a bad start, the first leg are left to ``find_path``, which names it)."""
    H, W = grid.shape
    for i in range(cells.shape[0]):
        r, c = cells[i, 0], cells[i, 1]
        if not (0 <= r < H and 0 <= c < W) or grid[r, c]:
            return max(i - 1, 0)
    return cells.shape[0] - 1


@numba.njit(cache=True)
def run_legs(rng, keys, tables, padded, fields, stops, loop, machine, grid, cut):
    """The legs ``stops[j] -> stops[j + 1]`` with :func:`~.engine.run_query` each (the same arguments),
    until the first leg that does not reach its goal with a valid path.  ``fields[j]`` is leg ``j``'s
    ranking field (``(L, 0, 0)`` for the Manhattan key).  Returns a :class:`LegsOut`."""
    L = stops.shape[0] - 1
    k = loop.style_ids.shape[0]  # the merge styles
    cap = 64
    points = np.empty((cap, 2), dtype=np.int64)
    ends = np.zeros(L + 1, dtype=np.int64)
    counts = np.zeros(5, dtype=np.int64)
    mapping = np.zeros((k, 4), dtype=np.int64)
    calls = np.empty(0, dtype=np.int64)
    emu = np.empty(0)
    walked = 0
    done = 0
    n_sub = 0
    last = run_query(rng, keys, tables, padded, fields[0], stops[0, 0], stops[0, 1], stops[1, 0], stops[1, 1], loop,
                     machine)
    for j in range(L):
        if j:
            last = run_query(rng, keys, tables, padded, fields[j], stops[j, 0], stops[j, 1], stops[j + 1, 0],
                             stops[j + 1, 1], loop, machine)
        calls = np.concatenate((calls, last.sub_calls))
        emu = np.concatenate((emu, last.sub_emu))
        if last.status != REACHED:
            break
        walk = last.walk
        ok, path = cut_walk(walk, grid, stops[j, 0], stops[j, 1], stops[j + 1, 0], stops[j + 1, 1], cut)
        if not ok:
            break
        top = ends[j]
        if top + path.shape[0] > cap:
            cap = 2 * (top + path.shape[0])
            grown = np.empty((cap, 2), dtype=np.int64)
            grown[:top] = points[:top]
            points = grown
        points[top: top + path.shape[0]] = path
        ends[j + 1] = top + path.shape[0]
        counts += last.counts
        mapping += last.mapping
        n_sub = calls.shape[0]
        walked += walk.shape[0] - 1
        done += 1
    return LegsOut(done, points[: ends[done]], ends[: done + 1], counts, mapping, calls, emu, walked, last, n_sub)


def plan_legs(runner, fields, world, cells, rng: np.random.Generator) -> LegBatch:
    """Plan the legs of ``cells`` (``(L + 1, 2)``: a start, then the stops) with the query component
    ``runner`` (:class:`~.runner.QueryRunner`) and ranking ``fields`` (:class:`~.query.GoalFields`)
    until the first one the compiled loop does not finish (module docstring)."""
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    if len(cells) < 2:
        return LegBatch(compute=ComputeReport())
    n_legs = usable_legs(cells, world.grid)  # legs up to the first bad cell (find_path names it)
    if n_legs == 0:
        return LegBatch(compute=ComputeReport())
    stops = cells[: n_legs + 1]
    grid = world.grid
    cfg = runner.config
    charged = CallLedger()
    try:
        with runner.chip.session(charged, decision="path_query") as link:
            out = run_legs(rng, *runner.pool.arrays(), runner.padded(grid), fields.goals(world, stops[1:]), stops,
                           runner.loop_args(grid), link.args, grid, cfg.cut_loops)
    except (ChipUnavailableError, SolverOutputError):  # a machine behind the callback failed: the legs go
        return LegBatch(compute=ComputeReport.from_ledger(charged))  # one by one
    done, points, ends, calls, n_sub = out.done, out.points, out.ends, out.calls, out.n_sub
    failed = None
    if done < n_legs:  # that leg's own result, charged to it (a callback machine charged the batch as it ran)
        leg = CallLedger()
        link.settle(calls[n_sub:], out.emu[n_sub:], into=leg)
        a, b = tuple(int(v) for v in stops[done]), tuple(int(v) for v in stops[done + 1])
        failed = runner.result(grid, a, b, out.last, leg, used=int(calls[n_sub:].sum()))
    batch = LegBatch(compute=ComputeReport.from_ledger(charged), failed=failed)
    if not done:
        return batch
    link.settle(calls[:n_sub], out.emu[:n_sub])
    batch.paths = [points[ends[j]: ends[j + 1]] for j in range(done)]
    batch.compute = ComputeReport.from_ledger(charged)
    batch.stats = {
        "chip_calls": int(charged.physical_calls),
        "chip_batches": int(charged.batches),
        **{name: int(v) for name, v in zip(COUNT_NAMES, out.counts.tolist())},
        "walk_length": int(out.walked),
        "mapping": {"path": record_of_reads(cfg.styles, out.mapping, cfg.num_reads)},
        "path_length": int(ends[done] - done),
    }
    return batch
