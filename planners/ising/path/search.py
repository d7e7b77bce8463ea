"""Patch-sliding Ising pathfinding: the search of paper 5.1 (Algorithm 1).

Contract: ``IsingPath(chip, config).find_path(world, start, goal, rng) -> PathResult`` never raises for a
failed query (``result.failure`` says why; a chip that cannot answer sets ``stats["chip_unavailable"]``
and the pipeline hands the query to A*); every chip call is metered into ``result.compute``.  The chip
generates every local segment; the host ranks, decodes, validates, scores and stitches in one compiled
loop (:mod:`.engine`).  Termination rules, budgets and measurements: docs/design/ising_path.md.
"""

from __future__ import annotations

import numpy as np

from planners.ising.path.batch import LegBatch, plan_legs
from planners.ising.path.config import PathConfig
from planners.ising.path.qubo import patch_frame
from planners.ising.path.query import GoalFields
from planners.ising.path.runner import QueryRunner

__all__ = ["IsingPath", "PaperIsingPath"]


class IsingPath:
    """Patch-sliding Ising pathfinder (paper Algorithm 1).

    Built from two components: ``runner`` (:class:`~.runner.QueryRunner`: the compiled query
    loop on the machine) and ``fields`` (:class:`~.query.GoalFields`: the ranking fields).

    Args:
        chip: the Ising machine that runs every patch program (any
            :class:`ising_backend.IsingMachine` or ``dimod.Sampler``; default a fresh
            ``EmulatedChip(ChipSpec())``; a pipeline passes its one chip to every layer).
        config: a :class:`PathConfig`; keyword ``options`` override its fields.
    """

    name = "ising"
    config_class = PathConfig
    defaults: PathConfig | None = None  # None: PathConfig()

    def __init__(self, chip=None, config: PathConfig | None = None, **options):
        from ising_backend import as_machine

        self.chip = as_machine(chip)  # the paper's emulated chip for None
        cfg = PathConfig.resolve(config, options, self.defaults)
        # a patch not given explicitly shrinks to a smaller chip (an explicit config is taken as it is)
        self.config = cfg = cfg if config is not None else cfg.fit_spins(self.chip.spec.n_spins, keep=set(options))
        self.frame = patch_frame(cfg.patch_size)
        n_spins = self.chip.spec.n_spins
        if self.frame.n - 2 > n_spins:
            raise ValueError(
                f"patch_size = {cfg.patch_size} gives up to {self.frame.n - 2} patch variables; "
                f"the chip has {n_spins} spins (spec.n_spins)"
            )
        self.runner = QueryRunner(cfg, self.frame, self.chip)
        self.fields = GoalFields(cfg, self.frame)

    def __repr__(self) -> str:
        return f"IsingPath({self.config!r})"

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
        return self.runner.run(grid, s, g, rng, self.fields.goal(world, g))

    def find_paths(self, world, cells, rng: np.random.Generator) -> LegBatch:
        """The legs ``cells[j] -> cells[j + 1]`` in one compiled call (:func:`.batch.plan_legs`)."""
        return plan_legs(self.runner, self.fields, world, cells, rng)


class PaperIsingPath(IsingPath):
    """:class:`IsingPath` with the paper's configuration (:meth:`PathConfig.paper`)."""

    name = "ising-paper"
    defaults = PathConfig.paper()
