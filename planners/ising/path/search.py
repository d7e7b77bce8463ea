"""Patch-sliding Ising pathfinding: the search of paper 5.1 (Algorithm 1).

Contract: ``IsingPath(chip, config).find_path(world, start, goal, rng) -> PathResult``;
never raises for a failed query (``result.failure`` says why); every chip call
is metered (:class:`ising_backend.MeteredSolver`) into ``result.compute``.  A chip
that cannot answer hands the query to A* (flagged; :mod:`planners.ising.fallback`).
The chip generates every local segment; the host places patches, ranks local
targets (by BFS distance to the goal; the paper's Manhattan distance in
``ising-paper``), decodes, validates, scores and stitches.
Termination rules, budgets and measurements: docs/design/ising_path.md.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import NamedTuple

import numpy as np

from ising_backend import ChipUnavailableError, MeteredSolver, SolverOutputError
from planners.ising.config import ConfigAttributes, resolve_config
from planners.ising.fallback import path_fallback, unavailable_message
from planners.ising.path.config import PathConfig
from planners.ising.path.decode import decode_paths
from planners.ising.path.engine import CompiledSearch, ProgramPool
from planners.ising.path.kernels import extract_path, neighbour_table, rank_local_targets, score_patch_samples
from planners.ising.path.qubo import build_patch_qubo, patch_frame
from planners.ising.path.batch import BatchedLegs
from planners.ising.path.query import QueryEnds

__all__ = ["IsingPath", "PaperIsingPath"]


class _LRU(OrderedDict):
    """A small least-recently-used cache (host-side memo of deterministic mapping work)."""

    def __init__(self, size: int = 4096):  # a default, so copy/pickle can rebuild it (size comes back as state)
        super().__init__()
        self.size = size


class _PatchProgram(NamedTuple):
    """A patch problem with its logical Ising model and its merged programs, stacked per style."""

    problem: object  # PatchQubo
    model: object  # IsingModel of the patch QUBO (None without variables)
    styles: tuple  # indices (into config.styles) of the mapped styles
    errors: dict  # style -> MergeError message
    h: np.ndarray  # (mapped styles, N) physical fields, zero-padded
    J: np.ndarray  # (mapped styles, N, N)
    ptr: np.ndarray  # (mapped styles, n + 1) copy layout
    idx: np.ndarray  # (mapped styles, N)


class IsingPath(CompiledSearch, QueryEnds, BatchedLegs, ConfigAttributes):
    """Patch-sliding Ising pathfinder (paper Algorithm 1).

    Args:
        chip: the :class:`ising_backend.EmulatedChip` that runs every patch
            program (default: a fresh ``EmulatedChip(ChipSpec())``; a pipeline
            passes its one chip to every layer).
        config: a :class:`PathConfig`; keyword ``options`` override its fields.
    """

    name = "ising"
    config_class = PathConfig
    defaults: PathConfig | None = None  # None: PathConfig()

    def __init__(self, chip=None, config: PathConfig | None = None, **options):
        from ising_backend import ChipSpec, EmulatedChip, as_machine

        self.chip = EmulatedChip(ChipSpec()) if chip is None else as_machine(chip)
        cfg = resolve_config(PathConfig, config, options, self.defaults)
        # a patch not given explicitly shrinks to a smaller chip (an explicit config is taken as it is)
        self.config = cfg = cfg if config is not None else cfg.fit_spins(self.chip.spec.n_spins, keep=set(options))
        self.frame = patch_frame(cfg.patch_size)
        n_spins = self.chip.spec.n_spins
        if self.frame.n - 2 > n_spins:
            raise ValueError(
                f"patch_size = {cfg.patch_size} gives up to {self.frame.n - 2} patch variables; "
                f"the chip has {n_spins} spins (spec.n_spins)"
            )
        self._problem_cache = _LRU(4096)
        self._padded_for = None
        self._fields_for = None  # (world, padded target fields, {target cell: index}) of the last world
        self._nbr = neighbour_table(self.frame)
        from ising_backend import MERGE_STYLE_IDS

        spec = self.chip.spec
        lim = spec.coefficient_limits
        self._limits = (lim[0], lim[1], int(spec.n_spins))
        self._style_ids = np.array([MERGE_STYLE_IDS[st] for st in cfg.styles], dtype=np.int64)
        self._free_for = None
        self._loop_for = None  # (grid, the compiled loop's arguments on it) of the last grid
        self._engine_args = None
        from ising_backend import MachineLink

        self._link = MachineLink(self.chip)  # the compiled loop anneals on any machine through it
        if not cfg.pack and cfg.targets_per_call == 1 and cfg.patch_size <= 7:
            w = cfg.full_weights
            coef = (w["C"], w["B"], w["Dg"], w["A_end"], 0.0) if cfg.form == "pair" else \
                (0.0, w["B"], 0.0, w["A_end"], w["A"])
            self._engine_args = (cfg.form == "degree", np.array(coef, dtype=np.float64), float(cfg.chip_scale),
                                 self._style_ids, self._limits[0], self._limits[1], self._limits[2],
                                 *self._link.kernel_args)
            self._pool = ProgramPool(self.frame.n, len(cfg.styles), spec.n_spins)

    def __repr__(self) -> str:
        return f"IsingPath({self.config!r})"

    # ------------------------------------------------------------------ mapping
    def _padded(self, grid: np.ndarray) -> np.ndarray:
        """The grid padded with obstacles by the patch radius (memoised for the last grid)."""
        cached = self._padded_for
        if cached is not None and cached[0] is grid:
            return cached[1]
        r = self.frame.radius
        h, w = grid.shape
        padded = np.ones((h + 2 * r, w + 2 * r), dtype=bool)
        padded[r: r + h, r: r + w] = grid
        self._padded_for = (grid, padded)
        return padded

    def _program(self, comp: np.ndarray, key: bytes, target: int) -> _PatchProgram:
        """The patch problem for a free-cell mask and local target, mapped by every merge style (memoised).

        Patch problems recur along the legs of one world (the same local obstacle pattern
        and local target), so each distinct one is built and merged once per planner.
        """
        hit = self._problem_cache.get((key, target))
        if hit is not None:
            self._problem_cache.move_to_end((key, target))
            return hit
        from ising_backend import ising_from_qubo, merge_error_message, merge_styles

        cfg = self.config
        pr = build_patch_qubo(self.frame, comp, self.frame.n // 2, target, cfg.form, cfg.full_weights)
        if not pr.n:
            none = np.zeros((0, 0), dtype=np.int64)
            prog = _PatchProgram(pr, None, (), {}, np.zeros((0, 0)), np.zeros((0, 0, 0)), none, none)
        else:
            # every merge style in one compiled call (ising_backend.merge_spins's kernel, same programs)
            model = ising_from_qubo(pr.q, pr.Q, pr.offset)
            scale = cfg.chip_scale
            H = np.rint(model.h * scale).astype(np.int64)
            C = np.rint(model.J * scale).astype(np.int64)
            Lh, Lj, n_spins = self._limits
            status, err, a, _, h, J, _, ptr, idx = merge_styles(H, C, self._style_ids, Lh, Lj, Lj, n_spins)
            ok = np.flatnonzero(status == 0)
            errors = {cfg.styles[k]: merge_error_message(int(status[k]), err[k], H, C, a[k], Lh, Lj, n_spins, scale)
                      for k in np.flatnonzero(status != 0)}
            if len(ok) < len(status):
                h, J, ptr, idx = h[ok], J[ok], ptr[ok], idx[ok]
            prog = _PatchProgram(pr, model, tuple(int(k) for k in ok), errors, h, J, ptr, idx)
        self._problem_cache[(key, target)] = prog
        if len(self._problem_cache) > self._problem_cache.size:
            self._problem_cache.popitem(last=False)
        return prog

    def _outcome(self, prog: _PatchProgram, n_valid, best, energy, logical):
        """Per style ``(reads, valid, error, best score)`` and the best candidate of one problem.

        The first read with the lowest original energy wins (styles in portfolio order);
        styles whose best is within ``1e-9 x max(1, |best|)`` share the win.
        """
        reads = self.config.num_reads
        outcomes = {}
        best_score, best_at = np.inf, None
        row = 0
        for st in self.config.styles:
            if st in prog.errors:
                outcomes[st] = (0, 0, prog.errors[st], np.inf)
                continue
            score = float(energy[row])
            if score < best_score:
                best_score, best_at = score, (row, int(best[row]))
            outcomes[st] = (reads, int(n_valid[row]), None, score)
            row += 1
        if best_at is None:
            return None, outcomes
        tol = 1e-9 * max(1.0, abs(best_score))
        winners = [st for st in self.config.styles if outcomes[st][3] <= best_score + tol]
        pr = prog.problem
        path = extract_path(logical[best_at] > 0, pr.cells, pr.start, pr.goal, self._nbr)
        return (best_score, winners, path.tolist()), outcomes

    def _submit(self, solver, progs: list, rng: np.random.Generator) -> list:
        """One chip submission: every problem x every mapped merge style, ``num_reads`` reads each;
        one compiled decode-check-score call per problem."""
        seed = int(rng.integers(0, 2**63 - 1))
        rows = [p.h.shape[0] for p in progs]
        if not sum(rows):
            return [self._outcome(p, (), (), (), None) for p in progs]
        if len(progs) == 1:
            h, J = progs[0].h, progs[0].J
        else:
            N = max(p.h.shape[1] for p in progs)
            h = np.zeros((sum(rows), N))
            J = np.zeros((sum(rows), N, N))
            at = 0
            for p in progs:
                b, n_p = p.h.shape
                h[at:at + b, :n_p] = p.h
                J[at:at + b, :n_p, :n_p] = p.J
                at += b
        spins, _ = solver.anneal_batch(h, J, num_reads=self.config.num_reads, seed=seed)
        out, at = [], 0
        for p, b in zip(progs, rows):
            pr, m = p.problem, p.model
            out.append(self._outcome(p, *score_patch_samples(spins[at:at + b], p.ptr, p.idx, pr.n, pr.cells, pr.start,
                                                             pr.goal, self._nbr, m.h, m.J, m.offset)))
            at += b
        return out

    def _solve_portfolio(self, solver, progs: list, rng: np.random.Generator) -> list:
        """``pack=True``: the same submission through :func:`ising_backend.run_portfolio_batch`
        (block-packed programs)."""
        from ising_backend import MergeMapping, run_portfolio_batch

        fr = self.frame

        def decoder(pr):
            return lambda spins: decode_paths(fr, pr, (np.asarray(spins) > 0)[None])[0]

        mappings = [MergeMapping(st, scale=self.config.chip_scale) for st in self.config.styles]
        results = run_portfolio_batch([p.model for p in progs], mappings, solver,
                                      decode=[decoder(p.problem) for p in progs], num_reads=self.config.num_reads,
                                      seed=int(rng.integers(0, 2**63 - 1)), pack=True)
        out = []
        for res in results:
            outcomes = {st: (o.reads, o.valid, o.error, o.best_score) for st, o in res.outcomes.items()}
            best = None
            if res.success:
                tol = 1e-9 * max(1.0, abs(res.best_score))
                best = (res.best_score, [st for st in self.config.styles
                                         if res.outcomes[st].best_score <= res.best_score + tol], res.best)
            out.append((best, outcomes))
        return out

    # ------------------------------------------------------------------ main loop
    def find_path(self, world, start, goal, rng: np.random.Generator | None = None):
        """A 4-neighbour path from ``start`` to ``goal`` built from chip-generated patch segments."""
        from planners.base import PathResult

        grid = world.grid
        h, w = grid.shape
        s = (int(start[0]), int(start[1]))
        g = (int(goal[0]), int(goal[1]))
        for name, (r, c) in (("start", s), ("goal", g)):
            if not (0 <= r < h and 0 <= c < w):
                return PathResult(None, failure=f"{name} cell [{r}, {c}] is off the {h}x{w} grid")
            if grid[r, c]:
                return PathResult(None, failure=f"{name} cell [{r}, {c}] is an obstacle")
        rng = np.random.default_rng() if rng is None else rng
        field = self._goal_field(world, g)
        result = None
        if self._engine_args is not None:
            state = rng.bit_generator.state
            result = self._run_engine(grid, s, g, rng, field)
            if result is None:
                rng.bit_generator.state = state  # a program the chip cannot take: the reference loop names it
        if result is None:
            result = self._search(grid, s, g, rng, field)
        return path_fallback(self.config.fallback, world, s, g, rng, result)

    def _search(self, grid, s, g, rng, field=None):
        """The search loop in Python: the reference of :mod:`.engine` (and the loop for other chips,
        ``pack``, ``targets_per_call > 1`` and patches above 7x7)."""
        fr = self.frame
        cfg = self.config
        rad = fr.radius
        offsets = fr.offsets
        padded = self._padded(grid)
        if field is None:
            field = np.zeros((0, 0), dtype=np.int64)
        solver = MeteredSolver(self.chip)
        mapping = {st: {"programs": 0, "valid": 0, "wins": 0, "map_errors": 0} for st in self.config.styles}
        counts = {"patch_solves": 0, "anneal_calls": 0, "segments": 0, "backtracks": 0, "direct_moves": 0}

        max_attempts, per_target, max_calls = self._budgets(grid)
        pos = s
        walk = [s]
        visited_mask = np.zeros_like(padded)  # cells on the committed walk (padded coordinates)
        visited_mask[s[0] + rad, s[1] + rad] = True
        stack: list = []  # committed segments (lists of cells), most recent last
        failed_at: dict = {}  # position -> local targets that gave no valid candidate from there
        failure = None
        first_map_error = None

        while pos != g:
            used = solver.charged.physical_calls
            if counts["patch_solves"] >= max_attempts or used + per_target > max_calls:
                failure = (f"gave up at [{pos[0]}, {pos[1]}] before reaching goal [{g[0]}, {g[1]}]: budget spent "
                           f"({counts['patch_solves']} patch solves of max_attempts={max_attempts}, "
                           f"{used} chip calls of max_chip_calls={max_calls})")
                break
            if failed_at.get(pos):
                excluded = visited_mask.copy()
                for (r, c) in failed_at[pos]:
                    excluded[r + rad, c + rad] = True
            else:
                excluded = visited_mask
            comp, ranked_idx = rank_local_targets(padded, pos[0], pos[1], g[0], g[1], fr.size, self._nbr, fr.ring,
                                                  excluded, cfg.interior_targets, cfg.target_order == "merged", field)
            if len(ranked_idx) == 0:
                if cfg.backtrack and stack:
                    seg = stack.pop()
                    walk.extend(reversed(seg[:-1]))
                    pos = seg[0]
                    counts["backtracks"] += 1
                    continue
                failure = (f"no path found from [{s[0]}, {s[1]}] to [{g[0]}, {g[1]}]: every local target "
                           f"reachable from [{pos[0]}, {pos[1]}] was visited or failed"
                           + (" and backtracking is exhausted" if cfg.backtrack else " (backtrack=False)")
                           + " (the goal may be unreachable)")
                break
            # calls left in the budget limit how many targets share this submission
            room = max(1, (max_calls - used) // per_target)
            room = min(room, max_attempts - counts["patch_solves"])
            batch = [(int(li), (pos[0] + int(offsets[li, 0]), pos[1] + int(offsets[li, 1])))
                     for li in ranked_idx[: min(cfg.targets_per_call, room)]]
            key = comp.tobytes()
            problems = [self._program(comp, key, li) for li, _ in batch]
            # a problem without variables (the target is the robot's only patch neighbour) needs no chip
            results: list = [[] for _ in batch]
            on_chip = []
            for k, prog in enumerate(problems):
                pr = prog.problem
                if pr.n == 0:
                    path = decode_paths(fr, pr, np.zeros((1, 0)))[0]
                    if path is not None:
                        results[k].append((pr.offset, None, path))
                else:
                    on_chip.append(k)
            if on_chip:
                try:
                    if cfg.pack:
                        outs = self._solve_portfolio(solver, [problems[k] for k in on_chip], rng)
                    else:
                        outs = self._submit(solver, [problems[k] for k in on_chip], rng)
                except SolverOutputError as exc:
                    failure = f"the chip returned malformed samples: {exc}"
                    break
                except ChipUnavailableError as exc:  # charged by the meter; find_path may fall back
                    failure = unavailable_message(exc)
                    counts["chip_unavailable"] = 1
                    break
                counts["anneal_calls"] += 1
                counts["patch_solves"] += len(on_chip)
                for k, (best, outcomes) in zip(on_chip, outs):
                    for st, (reads, valid, err, _score) in outcomes.items():
                        m = mapping[st]
                        m["programs"] += reads
                        m["valid"] += valid
                        m["map_errors"] += int(err is not None)
                        if err is not None and first_map_error is None:
                            first_map_error = f"{st}: {err}"
                    if best is not None:
                        results[k].append(best)
            chosen = None
            for k, (li, target) in enumerate(batch):
                if results[k]:
                    chosen = results[k][0]
                    break
                failed_at.setdefault(pos, []).append(target)
            if chosen is None:
                continue
            _, winners, path = chosen
            if winners:  # equal-scoring styles: one win, to a style drawn by rng (no order bias)
                win = winners[int(rng.integers(len(winners)))] if len(winners) > 1 else winners[0]
                mapping[win]["wins"] += 1
            else:
                counts["direct_moves"] += 1
            seg = [(pos[0] + int(fr.offsets[i, 0]), pos[1] + int(fr.offsets[i, 1])) for i in path]
            if g in seg:  # the segment passes the goal: the robot stops there
                seg = seg[: seg.index(g) + 1]
            walk.extend(seg[1:])
            for (r, c) in seg:
                visited_mask[r + rad, c + rad] = True
            stack.append(seg)
            counts["segments"] += 1
            pos = seg[-1]

        return self._finish(grid, s, g, walk, counts, mapping, solver.charged, failure, first_map_error)


class PaperIsingPath(IsingPath):
    """:class:`IsingPath` with the paper's configuration (:meth:`PathConfig.paper`)."""

    name = "ising-paper"
    defaults = PathConfig.paper()
