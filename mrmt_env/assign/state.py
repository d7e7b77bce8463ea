"""Batched state of the plan-level (Assign) env: arrays plus the compiled kernels.

:class:`AssignBatch` holds ``B`` episodes of worlds with the same ``R`` and
``N``; the single env uses ``B = 1`` and the native vector env ``B = N``, so
both run the same code (:mod:`mrmt_env.assign.kernels`).
"""

from __future__ import annotations

import numpy as np

from mrmt_env.assign.kernels import AssignArrays, N_ROBOT_FEATURES, assign_load, assign_masks, assign_observe, assign_step
from mrmt_env.world import World

__all__ = ["AssignBatch", "assign_feature_count", "assign_obs_high"]

def assign_feature_count(n_targets: int) -> int:
    """Columns of the observation: 8 features then one distance per target."""
    return N_ROBOT_FEATURES + int(n_targets)


def assign_obs_high(height: int, width: int, n_targets: int) -> float:
    """Upper bound of every observation value (committed time of one robot / (H + W))."""
    return float((n_targets + 2) * height * width) / float(height + width)


class AssignBatch:
    """``B`` plan-level episodes on ``H x W`` worlds with ``R`` robots and ``N`` targets."""

    def __init__(self, n_envs: int, height: int, width: int, n_robots: int, n_targets: int) -> None:
        b, r, n = int(n_envs), int(n_robots), int(n_targets)
        self.n_envs, self.height, self.width, self.n_robots, self.n_targets = b, int(height), int(width), r, n
        self.scale = float(height + width)
        self.far = float(height * width) / self.scale
        self.dist = np.full((b, r + n, r + n), -1, dtype=np.int32)
        self.coords = np.zeros((b, r + n, 2), dtype=np.float32)
        self.cell = np.zeros((b, r), dtype=np.int64)
        self.free_at = np.zeros((b, r), dtype=np.int64)
        self.active = np.ones((b, r), dtype=np.bool_)
        self.open_ = np.zeros((b, n), dtype=np.bool_)
        self.decider = np.full(b, -1, dtype=np.int64)
        self.counters = np.zeros((b, 4), dtype=np.int64)  # route_cost, steps, targets_visited, invalid
        self.worlds: list[World | None] = [None] * b
        self._arrays: list = [None] * b
        self._rewards = np.zeros(b, dtype=np.float64)
        self._terminated = np.zeros(b, dtype=np.bool_)

    def load(self, i: int, world: World) -> None:
        """Start env ``i``'s episode on ``world`` (targets under a robot are visited at once)."""
        w = world.width
        self.load_arrays(i, world.grid.reshape(-1), world.robots[:, 0] * w + world.robots[:, 1],
                         world.targets[:, 0] * w + world.targets[:, 1])
        self.worlds[i] = world

    def load_arrays(self, i: int, flat_grid: np.ndarray, robots: np.ndarray, targets: np.ndarray) -> None:
        """:meth:`load` from flat cell indices (``r * W + c``), as the vector env draws them."""
        nodes = np.concatenate([robots, targets]).astype(np.int64)
        state = AssignArrays(self.dist, self.coords, self.cell, self.free_at, self.active, self.open_, self.counters,
                             self.decider)
        assign_load(i, np.ascontiguousarray(flat_grid, dtype=np.bool_), self.width, self.height, nodes, self.n_robots,
                    state)
        self.worlds[i] = None
        self._arrays[i] = (flat_grid, nodes)

    def world(self, i: int) -> World:
        """Env ``i``'s world (built from the arrays on first use)."""
        if self.worlds[i] is None:
            flat_grid, nodes = self._arrays[i]
            w = self.width
            cells = np.stack([nodes // w, nodes % w], axis=1)
            self.worlds[i] = World(np.asarray(flat_grid, dtype=bool).reshape(self.height, w), cells[: self.n_robots],
                                   cells[self.n_robots:])
        return self.worlds[i]

    # ------------------------------------------------------------- dynamics
    def masks(self, out: np.ndarray | None = None) -> np.ndarray:
        out = np.empty((self.n_envs, self.n_targets + 1), dtype=np.bool_) if out is None else out
        assign_masks(self.cell, self.active, self.open_, self.dist, self.decider, out)
        return out

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Apply one action per env; returns ``(rewards, terminated)`` (views, overwritten next step).

        An action the mask forbids is a no-op costing -1 (counted in
        ``invalid_moves``), as a blocked move is in the grid env.

        Raises:
            ValueError: wrong shape or dtype, or a value outside ``0..N``
                (nothing is changed).
        """
        acts = np.asarray(actions)
        if acts.shape != (self.n_envs,) or acts.dtype.kind not in "iu":
            raise ValueError(
                f"actions must be {self.n_envs} integer(s) in 0..{self.n_targets} "
                f"(targets 0..{self.n_targets - 1}, {self.n_targets} = stop), got {acts.dtype} shape {acts.shape}"
            )
        bad = (acts < 0) | (acts > self.n_targets)
        if bad.any():
            b = int(np.flatnonzero(bad)[0])
            raise ValueError(
                f"action {int(acts[b])} of env {b} is outside 0..{self.n_targets} "
                f"(targets 0..{self.n_targets - 1}, {self.n_targets} = stop)"
            )
        assign_step(acts.astype(np.int64, copy=False), self.cell, self.free_at, self.active, self.open_, self.dist,
                    self.decider, self.counters, self._rewards, self._terminated)
        return self._rewards, self._terminated

    def observe(self, out: np.ndarray | None = None) -> np.ndarray:
        shape = (self.n_envs, self.n_targets + self.n_robots, assign_feature_count(self.n_targets))
        out = np.empty(shape, dtype=np.float32) if out is None else out
        assign_observe(self.cell, self.free_at, self.active, self.open_, self.dist, self.decider, self.coords,
                       self.scale, self.far, out)
        return out

    # -------------------------------------------------------------- metrics
    def info(self, i: int) -> dict:
        """Env ``i``'s flat metrics (the grid env's keys; no wall-clock values)."""
        route_cost, steps, visited, invalid = (int(v) for v in self.counters[i])
        return {
            "route_cost": route_cost,
            "makespan": int(self.free_at[i].max()),
            "steps": steps,
            "targets_visited": visited,
            "n_targets": self.n_targets,
            "is_success": visited == self.n_targets,
            "invalid_moves": invalid,
            "robot": int(self.decider[i]),
        }

    def positions(self, i: int) -> np.ndarray:
        """``(R, 2)`` cells where env ``i``'s robots are or will be when free."""
        nodes = self._arrays[i][1][self.cell[i]]
        return np.stack([nodes // self.width, nodes % self.width], axis=1)

    def visited(self, i: int) -> np.ndarray:
        return ~self.open_[i]
