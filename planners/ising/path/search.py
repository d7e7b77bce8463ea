"""Patch-sliding Ising pathfinding: the search of paper 5.1 (Algorithm 1).

Contract: ``IsingPath(chip, config).find_path(world, start, goal, rng) -> PathResult``;
never raises for a failed query (``result.failure`` says why); every chip call
is metered (:class:`ising_backend.MeteredSolver`) into ``result.compute``.
The chip generates every local segment; the host places patches, ranks local
targets (Manhattan to the goal), decodes, validates, scores and stitches.
Termination rules, budgets and measurements: docs/design/ising_path.md.
"""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from ising_backend import MeteredSolver, SolverOutputError
from planners.ising.config import resolve_config
from planners.ising.path.config import PathConfig
from planners.ising.path.decode import cut_loops, decode_paths
from planners.ising.path.qubo import build_patch_qubo, component_of, patch_frame

__all__ = ["IsingPath"]


class _LRU(OrderedDict):
    """A small least-recently-used cache (host-side memo of deterministic mapping work)."""

    def __init__(self, size: int):
        super().__init__()
        self.size = size

    def get_or(self, key, make):
        hit = self.get(key)
        if hit is None:
            hit = make()
            self[key] = hit
            if len(self) > self.size:
                self.popitem(last=False)
        else:
            self.move_to_end(key)
        return hit


def _cached_merge_mapping(style: str, scale: float, cache: _LRU):
    """A :class:`ising_backend.MergeMapping` whose results are memoised per logical model.

    Merging is a deterministic function of (model, style, scale, spec); patch
    problems recur (the same local obstacle pattern and local target), so the
    host maps each distinct one once.
    """
    from ising_backend import MergeMapping

    class _Cached(MergeMapping):
        def map(self, model, spec):
            key = (style, model.h.tobytes(), model.J.tobytes(), spec)
            return cache.get_or(key, lambda: MergeMapping.map(self, model, spec))

    return _Cached(style, scale=scale)


class IsingPath:
    """Patch-sliding Ising pathfinder (paper Algorithm 1).

    Args:
        chip: the :class:`ising_backend.EmulatedChip` that runs every patch
            program (default: a fresh ``EmulatedChip(ChipSpec())``; a pipeline
            passes its one chip to every layer).
        config: a :class:`PathConfig`; keyword ``options`` override its fields.
    """

    name = "ising"
    config_class = PathConfig

    def __init__(self, chip=None, config: PathConfig | None = None, **options):
        from ising_backend import ChipSpec, EmulatedChip

        self.config = cfg = resolve_config(PathConfig, config, options)
        self.chip = EmulatedChip(ChipSpec()) if chip is None else chip
        self.frame = patch_frame(cfg.patch_size)
        n_spins = self.chip.spec.n_spins
        if self.frame.n - 2 > n_spins:
            raise ValueError(
                f"patch_size = {cfg.patch_size} gives up to {self.frame.n - 2} patch variables; "
                f"the chip has {n_spins} spins (spec.n_spins)"
            )
        self._problem_cache = _LRU(4096)
        self._merge_cache = _LRU(4 * 4096)
        self._mappings = None

    def __getattr__(self, name):  # config options read as attributes (planner.form, planner.styles, ...)
        cfg = self.__dict__.get("config")
        if cfg is not None and name in PathConfig.__dataclass_fields__:
            return getattr(cfg, name)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __repr__(self) -> str:
        return f"IsingPath({self.config!r})"

    # ------------------------------------------------------------------ mapping
    def _solve(self, solver, problems: list, rng: np.random.Generator) -> list:
        """One portfolio submission: every problem x every merge style, ``num_reads`` reads each."""
        from ising_backend import run_portfolio_batch

        models = [m for _, m in problems]
        problems = [pr for pr, _ in problems]
        fr = self.frame

        def decoder(pr):
            def decode(spins):
                return decode_paths(fr, pr, (np.asarray(spins) > 0)[None])[0]
            return decode

        if self._mappings is None:
            self._mappings = [_cached_merge_mapping(st, self.config.chip_scale, self._merge_cache) for st in self.config.styles]
        mappings = self._mappings
        return run_portfolio_batch(models, mappings, solver, decode=[decoder(p) for p in problems],
                                   num_reads=self.config.num_reads, seed=int(rng.integers(0, 2**63 - 1)),
                                   pack=self.config.pack)

    def _problem(self, comp: np.ndarray, target: int):
        """The patch problem (and its logical Ising model) for a free-cell mask and local target, memoised."""
        from ising_backend import QuboModel

        def make():
            pr = build_patch_qubo(self.frame, comp, self.frame.n // 2, target, self.config.form, self.config.full_weights)
            model = QuboModel(pr.q, pr.Q, pr.offset).to_ising() if pr.n else None
            return pr, model

        return self._problem_cache.get_or((np.packbits(comp).tobytes(), target), make)

    # ------------------------------------------------------------------ ranking
    def _ranked_targets(self, pos, goal, comp, excluded) -> list:
        fr = self.frame
        idx = np.flatnonzero(comp)
        idx = idx[idx != fr.n // 2]
        cells = fr.offsets[idx] + np.asarray(pos)
        keep = np.array([(int(r), int(c)) not in excluded for r, c in cells], dtype=bool)
        idx, cells = idx[keep], cells[keep]
        if len(idx) == 0:
            return []
        is_goal = (cells == np.asarray(goal)).all(axis=1)
        ring = fr.ring[idx]
        cls = np.where(is_goal, 0, np.where(ring, 1, 2))
        if not self.config.interior_targets:
            sel = cls < 2
            idx, cells, cls = idx[sel], cells[sel], cls[sel]
        to_goal = np.abs(cells - np.asarray(goal)).sum(axis=1)
        from_pos = np.abs(fr.offsets[idx]).sum(axis=1)
        if self.config.target_order == "merged":  # interior cells compete on distance, boundary wins ties
            order = np.lexsort((idx, from_pos, cls, to_goal, cls != 0))
        else:
            order = np.lexsort((idx, from_pos, to_goal, cls))
        return [(int(idx[k]), (int(cells[k, 0]), int(cells[k, 1]))) for k in order]

    # ------------------------------------------------------------------ main loop
    def find_path(self, world, start, goal, rng: np.random.Generator | None = None):
        """A 4-neighbour path from ``start`` to ``goal`` built from chip-generated patch segments."""
        from planners.base import PathResult
        from planners.compute import ComputeReport

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
        fr = self.frame
        rad = fr.radius
        centre = fr.n // 2
        padded = np.pad(np.asarray(grid, dtype=bool), rad, constant_values=True)
        solver = MeteredSolver(self.chip)
        mapping = {st: {"programs": 0, "valid": 0, "wins": 0, "map_errors": 0} for st in self.config.styles}
        counts = {"patch_solves": 0, "anneal_calls": 0, "segments": 0, "backtracks": 0, "direct_moves": 0}

        per_target = len(self.config.styles) * self.config.num_reads  # chip calls of one local-target attempt
        max_attempts = self.config.max_attempts if self.config.max_attempts is not None else max(64, int((~grid).sum()))
        max_calls = self.config.max_chip_calls if self.config.max_chip_calls is not None else max_attempts * per_target
        pos = s
        walk = [s]
        visited = {s}
        stack: list = []  # committed segments (lists of cells), most recent last
        failed: set = set()  # (position, local target) pairs that gave no valid candidate
        failure = None
        first_map_error = None

        while pos != g:
            used = solver.charged.physical_calls
            if counts["patch_solves"] >= max_attempts or used + per_target > max_calls:
                failure = (f"gave up at [{pos[0]}, {pos[1]}] before reaching goal [{g[0]}, {g[1]}]: budget spent "
                           f"({counts['patch_solves']} patch solves of max_attempts={max_attempts}, "
                           f"{used} chip calls of max_chip_calls={max_calls})")
                break
            allowed = ~padded[pos[0]:pos[0] + fr.size, pos[1]:pos[1] + fr.size].reshape(-1)
            comp = component_of(fr, allowed, centre)
            excluded = visited | {t for (p, t) in failed if p == pos}
            ranked = self._ranked_targets(pos, g, comp, excluded)
            if not ranked:
                if self.config.backtrack and stack:
                    seg = stack.pop()
                    walk.extend(reversed(seg[:-1]))
                    pos = seg[0]
                    counts["backtracks"] += 1
                    continue
                failure = (f"no path found from [{s[0]}, {s[1]}] to [{g[0]}, {g[1]}]: every local target "
                           f"reachable from [{pos[0]}, {pos[1]}] was visited or failed"
                           + (" and backtracking is exhausted" if self.config.backtrack else " (backtrack=False)")
                           + " (the goal may be unreachable)")
                break
            # calls left in the budget limit how many targets share this submission
            room = max(1, (max_calls - used) // per_target)
            room = min(room, max_attempts - counts["patch_solves"])
            batch = ranked[: min(self.config.targets_per_call, room)]
            problems = [self._problem(comp, li) for li, _ in batch]
            # a problem without variables (the target is the robot's only patch neighbour) needs no chip
            results: list = [[] for _ in batch]
            on_chip = []
            for k, (pr, _) in enumerate(problems):
                if pr.n == 0:
                    path = decode_paths(fr, pr, np.zeros((1, 0)))[0]
                    if path is not None:
                        results[k].append((pr.offset, None, path))
                else:
                    on_chip.append(k)
            if on_chip:
                try:
                    outs = self._solve(solver, [problems[k] for k in on_chip], rng)
                except SolverOutputError as exc:
                    failure = f"the chip returned malformed samples: {exc}"
                    break
                counts["anneal_calls"] += 1
                counts["patch_solves"] += len(on_chip)
                for k, res in zip(on_chip, outs):
                    for st, o in res.outcomes.items():
                        mapping[st]["programs"] += o.reads
                        mapping[st]["valid"] += o.valid
                        mapping[st]["map_errors"] += int(o.error is not None)
                        if o.error is not None and first_map_error is None:
                            first_map_error = f"{st}: {o.error}"
                    if res.success:
                        tol = 1e-9 * max(1.0, abs(res.best_score))
                        winners = [st for st in self.config.styles if res.outcomes[st].best_score <= res.best_score + tol]
                        results[k].append((res.best_score, winners, res.best))
            chosen = None
            for k, (li, target) in enumerate(batch):
                if results[k]:
                    chosen = results[k][0]
                    break
                failed.add((pos, target))
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
            visited.update(seg)
            stack.append(seg)
            counts["segments"] += 1
            pos = seg[-1]

        delta = solver.charged
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
        cells = cut_loops(walk) if self.config.cut_loops else walk
        path = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
        # final check (never hand out an invalid path)
        steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
        if (steps != 1).any() or grid[path[:, 0], path[:, 1]].any() or tuple(path[0]) != s or tuple(path[-1]) != g:
            return PathResult(None, compute=compute, stats=stats,
                              failure="internal error: the stitched walk is not a valid 4-neighbour path")
        stats["path_length"] = len(path) - 1
        return PathResult(path, compute=compute, stats=stats)
