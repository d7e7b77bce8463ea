"""The three planning-layer interfaces and their result types.

Every planning method (classical or Ising) implements exactly one of these protocols (sharing, tour or path), so a
pipeline can combine any three (paper section 2.3). Each result carries a :class:`~planners.compute.ComputeReport`
of the layer's accelerator counts; the pipeline measures ``cpu_s`` around each call.
Design notes (node conventions): docs/design/pipeline.md#the-layer-interfaces.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from mrmt_env.world import World
from planners.compute import ComputeReport

__all__ = ["PathResult", "TourResult", "SharingResult", "PathPlanner", "TourSolver", "SharingPlanner"]


@dataclass(frozen=True)
class PathResult:
    """A path from start to goal, or a failure.

    ``path`` is ``(L+1, 2)`` int cells from start to goal inclusive, or
    ``None`` on failure (then ``failure`` says why).  Never an invalid path.
    """

    path: np.ndarray | None
    compute: ComputeReport = field(default_factory=ComputeReport)
    failure: str | None = None
    stats: dict = field(default_factory=dict, compare=False)

    @property
    def success(self) -> bool:
        return self.path is not None

    @property
    def length(self) -> int | None:
        return None if self.path is None else len(self.path) - 1


@dataclass(frozen=True, kw_only=True)
class Outcome:
    """What a tour or sharing result carries beside its answer (keywords only): the compute charge,
    statistics, and ``failure``, the one failure channel (a message; ``None`` on success)."""

    compute: ComputeReport = field(default_factory=ComputeReport)
    stats: dict = field(default_factory=dict, compare=False)
    failure: str | None = None

    @property
    def success(self) -> bool:
        return self.failure is None


@dataclass(frozen=True)
class TourResult(Outcome):
    """An open route over local nodes ``1..n`` starting from node 0.

    ``order`` is a permutation of ``1..n`` (local node indices); ``cost`` is
    the route cost under the ``dist`` the solver was given.  A solver that
    gives up returns ``failure`` (a message), an empty ``order`` and
    ``cost = inf``; the pipeline turns it into a failed plan.
    """

    order: tuple[int, ...]
    cost: float


@dataclass(frozen=True)
class SharingResult(Outcome):
    """Targets assigned to robots: ``assignment[k]`` lists target indices (0..N-1)
    for robot ``k`` (order not meaningful; the tour layer orders them).

    A planner that gives up sets ``failure`` (the one failure channel); the
    pipeline turns it into a failed plan.
    """

    assignment: tuple[tuple[int, ...], ...]


@runtime_checkable
class PathPlanner(Protocol):
    name: str

    def find_path(self, world: World, start, goal, rng: np.random.Generator | None = None) -> PathResult:
        """A 4-neighbour path on ``world.grid`` from ``start`` to ``goal``."""
        ...


@runtime_checkable
class TourSolver(Protocol):
    name: str

    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        """Order nodes ``1..n`` of ``dist`` (``(n+1, n+1)``) into an open route from node 0."""
        ...


@runtime_checkable
class SharingPlanner(Protocol):
    name: str

    def assign(
        self,
        dist: np.ndarray,
        n_robots: int,
        tour: TourSolver,
        rng: np.random.Generator | None = None,
    ) -> SharingResult:
        """Split targets among robots.  ``dist`` is ``world.distance_matrix``;
        ``tour`` is the downstream tour solver (for methods that price a
        bundle by its tour cost, e.g. Ising robotless-bundle assignment)."""
        ...
