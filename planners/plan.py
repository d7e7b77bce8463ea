"""Plans: per robot, its ordered targets and its cell-by-cell path.

A :class:`Plan` is what every pipeline returns, classical or Ising.  Its route
metrics follow the paper: route cost = total moves of all robots, makespan =
the longest robot route, imbalance = longest minus shortest route.

:func:`validate_plan` is the one place that decides whether a plan is legal
for a world; it raises :class:`PlanError` naming the robot and step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba
import numpy as np

from mrmt_env.world import World
from planners.compute import ComputeReport

__all__ = ["RobotRoute", "Plan", "PlanError", "validate_plan", "path_problem"]


class PlanError(ValueError):
    """A plan that is not legal for its world (the message names robot and step)."""


@dataclass(frozen=True)
class RobotRoute:
    """One robot's part of a plan.

    Attributes:
        targets: target indices (into ``world.targets``) in visiting order.
        path: ``(L+1, 2)`` int cells, the start cell first, then one
            4-neighbour move (or a wait) per row.  ``L`` is the route length.
    """

    targets: tuple[int, ...]
    path: np.ndarray

    def __post_init__(self) -> None:
        path = np.asarray(self.path, dtype=np.int64).reshape(-1, 2)
        path.setflags(write=False)
        object.__setattr__(self, "path", path)
        object.__setattr__(self, "targets", tuple(int(t) for t in self.targets))

    @property
    def length(self) -> int:
        """Number of moves (path cells minus one; a wait in place counts as a move)."""
        return max(len(self.path) - 1, 0)

    def to_dict(self) -> dict:
        return {"targets": list(self.targets), "path": self.path.tolist()}


@dataclass(frozen=True)
class Plan:
    """A joint plan for all robots, with what it cost to compute.

    ``success`` is False when a layer failed (for example the Ising path
    layer gave up); then ``failure`` says why and ``routes`` holds what was
    planned before the failure (still legal, but not visiting every target).
    """

    routes: tuple[RobotRoute, ...]
    compute: ComputeReport = field(default_factory=ComputeReport)
    success: bool = True
    failure: str | None = None
    stats: dict = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "routes", tuple(self.routes))

    @property
    def lengths(self) -> list[int]:
        return [r.length for r in self.routes]

    @property
    def route_cost(self) -> int:
        return int(sum(self.lengths))

    @property
    def makespan(self) -> int:
        return int(max(self.lengths, default=0))

    @property
    def imbalance(self) -> int:
        lengths = self.lengths
        return int(max(lengths) - min(lengths)) if lengths else 0

    def to_dict(self) -> dict:
        """The JSON object of ``mrmt plan`` output."""
        d = {
            "robots": [r.to_dict() for r in self.routes],
            "route_cost": self.route_cost,
            "makespan": self.makespan,
            "imbalance": self.imbalance,
            "success": bool(self.success),
            "compute": self.compute.to_dict(),
        }
        if self.failure:
            d["failure"] = self.failure
        if isinstance(self.stats.get("solver"), dict):  # a peer solver's stop criterion and effort
            d["solver"] = dict(self.stats["solver"])
        return d


@numba.njit(cache=True, nogil=True)
def _path_ok(grid, p, ar, ac, br, bc):
    h, w = grid.shape
    n = p.shape[0]
    if p[0, 0] != ar or p[0, 1] != ac or p[n - 1, 0] != br or p[n - 1, 1] != bc:
        return False
    for i in range(n):
        r = p[i, 0]
        c = p[i, 1]
        if r < 0 or r >= h or c < 0 or c >= w or grid[r, c]:
            return False
        if i > 0 and abs(r - p[i - 1, 0]) + abs(c - p[i - 1, 1]) > 1:
            return False
    return True


@numba.njit(cache=True, nogil=True)
def _first_visit(p, pos, r, c):
    """The first step ``>= pos`` of path ``p`` at cell ``(r, c)``, or -1."""
    for i in range(pos, p.shape[0]):
        if p[i, 0] == r and p[i, 1] == c:
            return i
    return -1


def path_problem(world: World, path, a, b) -> str | None:
    """Why ``path`` is not a legal leg from cell ``a`` to cell ``b`` on ``world`` (``None`` if it is).

    The leg check of :func:`validate_plan` (compiled fast path, then a message that names the cell).
    """
    p = np.asarray(path)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0:
        return f"path layer returned an array of shape {p.shape}, not (L+1, 2) cells"
    if p.dtype == np.int64 and _path_ok(world.grid, p, int(a[0]), int(a[1]), int(b[0]), int(b[1])):
        return None
    if not np.array_equal(p[0], a) or not np.array_equal(p[-1], b):
        return f"path layer returned a path from {p[0].tolist()} to {p[-1].tolist()}, not {list(a)} to {list(b)}"
    h, w = world.shape
    inside = (p[:, 0] >= 0) & (p[:, 0] < h) & (p[:, 1] >= 0) & (p[:, 1] < w)
    if not inside.all():
        return f"path layer returned cell {p[~inside][0].tolist()} off the {h}x{w} grid"
    blocked = world.grid[p[:, 0], p[:, 1]]
    if blocked.any():
        return f"path layer returned a path through obstacle {p[blocked][0].tolist()}"
    steps = np.abs(np.diff(p, axis=0)).sum(axis=1)
    if (steps > 1).any():
        i = int(np.flatnonzero(steps > 1)[0])
        return f"path layer returned a jump from {p[i].tolist()} to {p[i + 1].tolist()}"
    if p.dtype.kind not in "iu":
        return f"path layer returned {p.dtype} cells, not integers"
    return None


def validate_plan(world: World, plan: Plan, require_complete: bool = True) -> None:
    """Raise :class:`PlanError` unless ``plan`` is legal for ``world``.

    Checks, per robot: the path starts at the robot's start cell; every step
    is a 4-neighbour move or a wait; no cell is an obstacle or off the grid;
    the robot's listed targets are valid indices and are reached in the
    listed order along its path.  Across robots: no target is listed twice,
    and (``require_complete``) every target is listed by some robot.
    """
    if len(plan.routes) != world.n_robots:
        raise PlanError(f"plan has {len(plan.routes)} routes for {world.n_robots} robots")
    listed: dict[int, int] = {}
    targets = np.asarray(world.targets).tolist()
    for k, route in enumerate(plan.routes):
        path = route.path
        if len(path) == 0:
            raise PlanError(f"robot {k}: empty path (it must start at its start cell)")
        if not np.array_equal(path[0], world.robots[k]):
            raise PlanError(
                f"robot {k}: path starts at {path[0].tolist()}, not at its start cell {world.robots[k].tolist()}"
            )
        end_r, end_c = path[-1]
        fast_ok = path.dtype == np.int64 and _path_ok(world.grid, path, int(path[0, 0]), int(path[0, 1]),
                                                      int(end_r), int(end_c))
        for step, cell in enumerate(() if fast_ok else path):
            r, c = int(cell[0]), int(cell[1])
            if not (0 <= r < world.height and 0 <= c < world.width):
                raise PlanError(f"robot {k} step {step}: cell [{r}, {c}] is off the {world.height}x{world.width} grid")
            if world.grid[r, c]:
                raise PlanError(f"robot {k} step {step}: cell [{r}, {c}] is an obstacle")
            if step and int(np.abs(cell - path[step - 1]).sum()) > 1:
                raise PlanError(
                    f"robot {k} step {step}: jump from {path[step - 1].tolist()} to [{r}, {c}] "
                    "(only 4-neighbour moves are allowed)"
                )
        pos = 0
        for t in route.targets:
            if not (0 <= t < world.n_targets):
                raise PlanError(f"robot {k}: target index {t} out of range 0..{world.n_targets - 1}")
            if t in listed:
                raise PlanError(f"robot {k}: target {t} is already assigned to robot {listed[t]}")
            listed[t] = k
            r, c = targets[t]
            if fast_ok:  # an int64 path: the compiled scan
                hit = int(_first_visit(path, pos, r, c))
            else:
                hits = np.flatnonzero((path[pos:, 0] == r) & (path[pos:, 1] == c))
                hit = pos + int(hits[0]) if len(hits) else -1
            if hit < 0:
                raise PlanError(
                    f"robot {k}: path never reaches target {t} at {[r, c]} "
                    f"after step {pos} (targets must be reached in the listed order)"
                )
            pos = hit
    if require_complete:
        missed = [t for t in range(world.n_targets) if t not in listed]
        if missed:
            raise PlanError(f"targets {missed} are not assigned to any robot")
