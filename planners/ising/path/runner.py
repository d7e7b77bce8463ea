"""One Ising path query on the compiled loop (paper 5.1): the path planner's query component.

Contract: ``QueryRunner(config, frame, chip)`` owns what :func:`.engine.run_query` needs (the machine
link, the program pool, the mapping limits, the per-grid arguments) and turns one query's arrays into a
:class:`~planners.base.PathResult`: charged per submission, the failure named, the walk's loops cut and
the path checked (never an invalid path handed out).  Design notes: docs/design/ising_path.md.
"""

from __future__ import annotations

import numpy as np

from ising_backend import (
    MERGE_STYLE_IDS, CallLedger, ChipUnavailableError, SolverOutputError, ising_from_qubo,
    mapping_record, merge_error_message, merge_styles, record_of_reads,
)
from planners.fallback import unavailable_message
from planners.ising.path.engine import (
    BUDGET_SPENT, COUNT_NAMES, EXHAUSTED, QUERY_OPTIONS, ProgramPool, QueryLoop, run_query,
)
from planners.ising.path.kernels import cut_walk, neighbour_table
from planners.ising.path.qubo import build_patch_qubo

__all__ = ["QueryRunner"]


class QueryRunner:
    """The compiled query loop on one machine for one path configuration (module docstring)."""

    def __init__(self, config, frame, chip):
        self.config = config
        self.frame = frame
        self.chip = chip  # the compiled loop anneals on it through a session per query
        spec = chip.spec
        lim = spec.coefficient_limits
        self.limits = (lim[0], lim[1], int(spec.n_spins))
        self.style_ids = np.array([MERGE_STYLE_IDS[st] for st in config.styles], dtype=np.int64)
        self.nbr = neighbour_table(frame)
        w = config.full_weights
        coef = (w["C"], w["B"], w["Dg"], w["A_end"], 0.0) if config.form == "pair" else \
            (0.0, w["B"], 0.0, w["A_end"], w["A"])
        self.coef = np.array(coef, dtype=np.float64)
        self.pool = ProgramPool(frame.n, len(config.styles), spec.n_spins)
        self._grid_for = None  # (grid, padded grid, free cells, loop arguments) of the last grid

    # ------------------------------------------------------------------ per grid
    def _for_grid(self, grid) -> tuple:
        cached = self._grid_for
        if cached is not None and cached[0] is grid:
            return cached
        r = self.frame.radius
        h, w = grid.shape
        padded = np.ones((h + 2 * r, w + 2 * r), dtype=bool)
        padded[r: r + h, r: r + w] = grid
        free = int((~np.asarray(grid, dtype=bool)).sum())
        cfg = self.config
        fr = self.frame
        max_attempts, _per_target, max_calls = self._budgets(free)
        options = np.array([(fr.size, cfg.interior_targets, cfg.target_order == "merged", cfg.backtrack,
                             cfg.num_reads, cfg.targets_per_call, cfg.pack, max_attempts, max_calls,
                             cfg.form == "degree", float(cfg.chip_scale), *self.limits, free)], dtype=QUERY_OPTIONS)
        loop = QueryLoop(nbr=self.nbr, ring=fr.ring, offsets=fr.offsets, adj4=fr.adj4, diag=fr.diag, coef=self.coef,
                         style_ids=self.style_ids, options=options)
        self._grid_for = (grid, padded, free, loop)
        return self._grid_for

    def padded(self, grid) -> np.ndarray:
        """The grid padded with obstacles by the patch radius (memoised for the last grid)."""
        return self._for_grid(grid)[1]

    def loop_args(self, grid) -> QueryLoop:
        """:func:`.engine.run_query`'s ``loop`` record on ``grid``."""
        return self._for_grid(grid)[3]

    def budgets(self, grid) -> tuple[int, int, int]:
        """``(max_attempts, chip calls per attempt, max_chip_calls)`` of a query on ``grid``."""
        return self._budgets(self._for_grid(grid)[2])

    def _budgets(self, free: int) -> tuple[int, int, int]:
        cfg = self.config
        per_target = len(cfg.styles) * cfg.num_reads
        max_attempts = cfg.max_attempts if cfg.max_attempts is not None else max(64, free)
        max_calls = cfg.max_chip_calls if cfg.max_chip_calls is not None else max_attempts * per_target
        return max_attempts, per_target, max_calls

    # ------------------------------------------------------------------ one query
    def run(self, grid, s, g, rng, field):
        """The query ``s -> g`` on the compiled loop, charged to the machine per submission as its
        ``anneal_batch`` would charge."""
        charged = CallLedger()
        try:
            with self.chip.session(charged, decision="path_query") as link:
                out = run_query(rng, *self.pool.arrays(), self.padded(grid), field, s[0], s[1], g[0], g[1],
                                self.loop_args(grid), link.args)
                link.settle(out.sub_calls, out.sub_emu)
        except (ChipUnavailableError, SolverOutputError) as exc:  # a machine behind the callback failed
            unavailable = isinstance(exc, ChipUnavailableError)
            failure = unavailable_message(exc) if unavailable else f"the chip returned malformed samples: {exc}"
            counts = dict.fromkeys(COUNT_NAMES, 0)
            if unavailable:
                counts["chip_unavailable"] = 1
            mapping = mapping_record(self.config.styles)
            return self.finish(grid, s, g, [s], counts, mapping, charged, failure, None)
        return self.result(grid, s, g, out, charged)

    def result(self, grid, s, g, out, charged, used=None):
        """The :class:`PathResult` of one :func:`.engine.run_query` output (a :class:`~.engine.QueryOut`),
        charged already to ``charged`` (``used``: the query's physical chip calls, if not all of ``charged``)."""
        cfg = self.config
        pr, pc = out.row, out.col
        max_attempts, _per_target, max_calls = self.budgets(grid)
        counts = dict(zip(COUNT_NAMES, (int(v) for v in out.counts)))
        mapping = record_of_reads(cfg.styles, out.mapping, cfg.num_reads)
        failure = None
        if out.status == BUDGET_SPENT:
            failure = (f"gave up at [{pr}, {pc}] before reaching goal [{g[0]}, {g[1]}]: budget spent "
                       f"({counts['patch_solves']} patch solves of max_attempts={max_attempts}, "
                       f"{charged.physical_calls if used is None else used} chip calls of "
                       f"max_chip_calls={max_calls})")
        elif out.status == EXHAUSTED:
            failure = (f"no path found from [{s[0]}, {s[1]}] to [{g[0]}, {g[1]}]: every local target "
                       f"reachable from [{pr}, {pc}] was visited or failed"
                       + (" and backtracking is exhausted" if cfg.backtrack else " (backtrack=False)")
                       + " (the goal may be unreachable)")
        map_error = self._map_error(out.err, out.err_comp) if out.err[0] >= 0 else None
        return self.finish(grid, s, g, out.walk, counts, mapping, charged, failure, map_error)

    def _map_error(self, err, comp) -> str:
        """``"style: message"`` of the first program a merge style could not map (``err`` and
        ``comp`` from :func:`.engine.run_query`), the merge kernel's own words."""
        cfg = self.config
        fr = self.frame
        style = int(err[3])
        pr = build_patch_qubo(fr, np.asarray(comp, dtype=bool), fr.n // 2, int(err[2]), cfg.form, cfg.full_weights)
        model = ising_from_qubo(pr.q, pr.Q, pr.offset)
        H = np.rint(model.h * cfg.chip_scale).astype(np.int64)
        C = np.rint(model.J * cfg.chip_scale).astype(np.int64)
        Lh, Lj, n_spins = self.limits
        m = merge_styles(H, C, self.style_ids[style: style + 1], Lh, Lj, Lj, n_spins)
        message = merge_error_message(int(m.status[0]), m.err[0], H, C, m.a[0], Lh, Lj, n_spins, cfg.chip_scale)
        return f"{cfg.styles[style]}: {message}"

    def finish(self, grid, s, g, walk, counts, mapping, delta, failure, first_map_error):
        """The query's :class:`PathResult`: compute from the charge ``delta``, statistics, the
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
        walk = np.asarray(walk, dtype=np.int64).reshape(-1, 2)
        ok, path = cut_walk(walk, np.asarray(grid, dtype=bool), s[0], s[1], g[0], g[1], self.config.cut_loops)
        if not ok:  # never hand out an invalid path
            return PathResult(None, compute=compute, stats=stats,
                              failure="internal error: the stitched walk is not a valid 4-neighbour path")
        stats["path_length"] = len(path) - 1
        return PathResult(path, compute=compute, stats=stats)
