"""Patch-sliding Ising pathfinding: the search of paper 5.1 (Algorithm 1).

Contract: ``IsingPath(chip, config).find_path(world, start, goal, rng) -> PathResult``;
never raises for a failed query (``result.failure`` says why); every chip call
is metered into ``result.compute``.  A chip that cannot answer hands the query to A*
(flagged; :mod:`planners.ising.fallback`).  The chip generates every local segment; the
host places patches, ranks local targets (by BFS distance to the goal; the paper's
Manhattan distance in ``ising-paper``), decodes, validates, scores and stitches, all in
one compiled loop (:mod:`.engine`) on any machine.
Termination rules, budgets and measurements: docs/design/ising_path.md.
"""

from __future__ import annotations

import numpy as np

from planners.ising.config import ConfigAttributes, resolve_config
from planners.ising.fallback import path_fallback
from planners.ising.path.batch import BatchedLegs
from planners.ising.path.config import PathConfig
from planners.ising.path.engine import CompiledSearch, ProgramPool
from planners.ising.path.kernels import neighbour_table
from planners.ising.path.qubo import patch_frame
from planners.ising.path.query import QueryEnds

__all__ = ["IsingPath", "PaperIsingPath"]


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
        self._padded_for = None
        self._fields_for = None  # (world, padded target fields, {target cell: index}) of the last world
        self._nbr = neighbour_table(self.frame)
        from ising_backend import MERGE_STYLE_IDS, MachineLink

        spec = self.chip.spec
        lim = spec.coefficient_limits
        self._limits = (lim[0], lim[1], int(spec.n_spins))
        self._style_ids = np.array([MERGE_STYLE_IDS[st] for st in cfg.styles], dtype=np.int64)
        self._free_for = None
        self._loop_for = None  # (grid, the compiled loop's arguments on it) of the last grid
        self._link = MachineLink(self.chip)  # the compiled loop anneals on any machine through it
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
        return path_fallback(self.config.fallback, world, s, g, rng, self._run_engine(grid, s, g, rng, field))


class PaperIsingPath(IsingPath):
    """:class:`IsingPath` with the paper's configuration (:meth:`PathConfig.paper`)."""

    name = "ising-paper"
    defaults = PathConfig.paper()
