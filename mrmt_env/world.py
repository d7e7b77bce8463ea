"""The world model: an obstacle grid, robot start cells and target cells.

A :class:`World` is immutable and validated on construction.  Cells are
``[row, col]`` integer pairs; ``grid[r, c]`` is ``True`` for an obstacle.
Motion is 4-neighbour with unit cost (paper section 6.1), so every distance
used by the planners is a breadth-first-search distance on the free cells.

Node order used by every planner: robots first (``0 .. R-1``), then targets
(``R .. R+N-1``).  :attr:`World.distance_matrix` follows that order.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from mrmt_env.distances import UNREACHABLE, bfs_distance_field, bfs_distance_fields, component_labels

__all__ = ["World", "WorldError"]


class WorldError(ValueError):
    """A world that breaks one of the model's rules (the message names the value)."""


def _as_cells(name: str, cells, allow_empty: bool, shape: tuple[int, int]) -> np.ndarray:
    """``(K, 2)`` int64 cells, each an integer pair inside the ``shape`` grid (checked before any
    integer conversion, so a huge value is named as given, never wrapped or rounded)."""
    singular = name[:-1]
    try:
        arr = np.asarray(cells if len(cells) else np.zeros((0, 2), dtype=np.int64))
    except (TypeError, ValueError) as exc:
        raise WorldError(f"{name} must be a list of [row, col] pairs ({exc})") from None
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise WorldError(f"{name} must be a list of [row, col] pairs, got shape {arr.shape}")
    if not allow_empty and len(arr) == 0:
        raise WorldError(f"a world needs at least one of {name}, got 0")
    if arr.dtype.kind not in "iubfO":
        raise WorldError(f"{name} must hold integer [row, col] pairs, got dtype {arr.dtype}")
    h, w = shape
    for i, (r, c) in enumerate(arr.tolist()):
        for v in (r, c):
            if isinstance(v, (float, np.floating)):
                ok = bool(np.isfinite(v)) and float(v).is_integer()
            else:
                ok = isinstance(v, (int, np.integer))
            if not ok:
                raise WorldError(f"{name} cell {[r, c]} is not an integer [row, col] pair")
        if not (0 <= r < h and 0 <= c < w):
            raise WorldError(
                f"{singular} {i} cell [{_show(r)}, {_show(c)}] is out of bounds for a {h}x{w} grid "
                f"(rows 0..{h - 1}, cols 0..{w - 1})"
            )
    return arr.astype(np.int64).reshape(-1, 2)


def _show(v) -> str:
    """An integer-valued coordinate as an integer (``3.0`` -> ``3``, ``1e30`` -> all its digits)."""
    return str(int(v))


@dataclass(frozen=True, eq=False)
class World:
    """A validated multi-robot multi-target grid world.

    Args:
        grid: ``(H, W)`` array-like of bool, ``True`` = obstacle.
        robots: ``(R, 2)`` robot start cells ``[row, col]``; at least one.
        targets: ``(N, 2)`` target cells; pairwise distinct; may be empty.

    Raises:
        WorldError: a cell out of bounds, a robot or target on an obstacle,
            a duplicate target, a target no robot can reach (4-neighbour
            moves), or zero robots.  The message names the offending cell.

    Robots may share a start cell and may start on a target (the paper has
    no inter-robot collision model); such a target counts as visited at
    reset in the environment.
    """

    grid: np.ndarray
    robots: np.ndarray
    targets: np.ndarray

    def __post_init__(self) -> None:
        grid = np.asarray(self.grid)
        if grid.ndim != 2 or grid.shape[0] < 1 or grid.shape[1] < 1:
            raise WorldError(f"grid must be a non-empty 2-D array, got shape {grid.shape}")
        if grid.dtype != np.bool_:
            bad = ~np.isin(grid, (0, 1))
            if bad.any():
                r, c = (int(i) for i in np.argwhere(bad)[0])
                raise WorldError(
                    f"grid must be boolean (True = obstacle) or 0/1, got {grid[r, c].item()!r} at cell [{r}, {c}]"
                )
            grid = grid.astype(bool)
        grid = np.ascontiguousarray(grid)
        grid.setflags(write=False)
        h, w = grid.shape
        robots = _as_cells("robots", self.robots, allow_empty=False, shape=(h, w))
        targets = _as_cells("targets", self.targets, allow_empty=True, shape=(h, w))
        for name, cells in (("robot", robots), ("target", targets)):
            for i, (r, c) in enumerate(cells.tolist()):
                if grid[r, c]:
                    raise WorldError(f"{name} {i} cell [{r}, {c}] is on an obstacle")
        seen: dict[tuple[int, int], int] = {}
        for i, (r, c) in enumerate(targets):
            key = (int(r), int(c))
            if key in seen:
                raise WorldError(f"target {i} cell [{r}, {c}] duplicates target {seen[key]}")
            seen[key] = i
        robots.setflags(write=False)
        targets.setflags(write=False)
        object.__setattr__(self, "grid", grid)
        object.__setattr__(self, "robots", robots)
        object.__setattr__(self, "targets", targets)
        labels, _ = component_labels(grid)  # one linear pass (not a BFS per robot): reachable = same component
        robot_parts = labels[robots[:, 0], robots[:, 1]]
        reach = np.isin(labels[targets[:, 0], targets[:, 1]], robot_parts) if len(targets) else np.zeros(0, bool)
        for i, (r, c) in enumerate(targets):
            if not reach[i]:
                raise WorldError(
                    f"target {i} cell [{r}, {c}] is unreachable from every robot (4-neighbour moves)"
                )

    # ------------------------------------------------------------------ sizes
    @property
    def height(self) -> int:
        return int(self.grid.shape[0])

    @property
    def width(self) -> int:
        return int(self.grid.shape[1])

    @property
    def shape(self) -> tuple[int, int]:
        return (self.height, self.width)

    @property
    def n_robots(self) -> int:
        return int(len(self.robots))

    @property
    def n_targets(self) -> int:
        return int(len(self.targets))

    @property
    def nodes(self) -> np.ndarray:
        """``(R+N, 2)`` cells of robots then targets (the planners' node order)."""
        return np.concatenate([self.robots, self.targets], axis=0)

    # -------------------------------------------------------------- distances
    @cached_property
    def robot_fields(self) -> np.ndarray:
        """``(R, H, W)`` int32 BFS distance from each robot start; -1 = unreachable."""
        return bfs_distance_fields(self.grid, self.robots)

    @cached_property
    def target_fields(self) -> np.ndarray:
        """``(N, H, W)`` int32 BFS distance from each target; -1 = unreachable."""
        return bfs_distance_fields(self.grid, self.targets)

    @cached_property
    def distance_matrix(self) -> np.ndarray:
        """``(R+N, R+N)`` float64 BFS distances among robots then targets.

        ``np.inf`` marks a pair in different free components.  Computed once
        per world from the distance fields (one BFS per node).
        """
        nodes = self.nodes
        fields = np.concatenate([self.robot_fields, self.target_fields], axis=0)
        d = fields[:, nodes[:, 0], nodes[:, 1]].astype(np.float64)
        d[d == UNREACHABLE] = np.inf
        d.setflags(write=False)
        return d

    def distance_field(self, cell) -> np.ndarray:
        """BFS distance field ``(H, W)`` from an arbitrary free cell."""
        return bfs_distance_field(self.grid, cell)

    # ---------------------------------------------------------------- helpers
    def is_free(self, cell) -> bool:
        r, c = int(cell[0]), int(cell[1])
        return 0 <= r < self.height and 0 <= c < self.width and not self.grid[r, c]

    def replace(self, *, robots=None, targets=None) -> "World":
        """A new world on the same grid with other robots and/or targets."""
        return World(
            self.grid,
            self.robots if robots is None else robots,
            self.targets if targets is None else targets,
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, World):
            return NotImplemented
        return (
            self.grid.shape == other.grid.shape
            and np.array_equal(self.grid, other.grid)
            and np.array_equal(self.robots, other.robots)
            and np.array_equal(self.targets, other.targets)
        )

    def __hash__(self) -> int:
        return hash((self.grid.tobytes(), self.grid.shape, self.robots.tobytes(), self.targets.tobytes()))

    def __repr__(self) -> str:
        return f"World({self.height}x{self.width}, robots={self.n_robots}, targets={self.n_targets})"
