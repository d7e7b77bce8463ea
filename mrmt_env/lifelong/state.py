"""Batched state of the lifelong envs: arrays, options and the compiled kernels.

:class:`LifelongBatch` holds ``B`` lifelong episodes of ``H x W`` worlds with
``R`` robots; the single env uses ``B = 1`` and the native vector env
``B = N``, so both run the same code (:mod:`mrmt_env.lifelong.kernels`).
:class:`LifelongOptions` is the validated task-stream and collision model.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mrmt_env.grid.kernels import grid_masks
from mrmt_env.lifelong.kernels import COUNTERS, LifelongArrays, lifelong_load, lifelong_step
from mrmt_env.maps import build_layout
from mrmt_env.world import World

__all__ = ["LifelongBatch", "LifelongOptions", "TASK_STREAMS", "COLLISION_MODELS", "MAX_TASK_RATE", "task_pool"]

TASK_STREAMS = ("refill", "poisson")
COLLISION_MODELS = ("block", "allow")
#: Largest Poisson arrival rate (tasks per step): the compiled inversion sampler's range.
MAX_TASK_RATE = 500.0
#: Arrival rate of ``tasks="poisson"`` when none is given (tasks per step).
DEFAULT_TASK_RATE = 0.5


@dataclass(frozen=True)
class LifelongOptions:
    """The task stream (``refill``: keep the initial ``K`` tasks open; ``poisson``: ``task_rate`` new
    tasks per step on average) and the collision model (``block`` or ``allow``)."""

    tasks: str = "refill"
    task_rate: float | None = None
    collisions: str = "block"

    def __post_init__(self) -> None:
        if self.tasks not in TASK_STREAMS:
            raise ValueError(f"tasks must be one of {TASK_STREAMS}, got {self.tasks!r}")
        if self.collisions not in COLLISION_MODELS:
            raise ValueError(f"collisions must be one of {COLLISION_MODELS}, got {self.collisions!r}")
        rate = self.task_rate
        if self.tasks == "refill":
            if rate is not None:
                raise ValueError(f"task_rate={rate!r} only applies to tasks='poisson' (refill keeps K tasks open)")
            return
        if rate is None:
            object.__setattr__(self, "task_rate", DEFAULT_TASK_RATE)
            return
        if isinstance(rate, bool) or not isinstance(rate, (int, float, np.integer, np.floating)) \
                or not np.isfinite(rate) or not 0 < rate <= MAX_TASK_RATE:
            raise ValueError(f"task_rate must be a number in (0, {MAX_TASK_RATE:g}] tasks per step, got {rate!r}")
        object.__setattr__(self, "task_rate", float(rate))


def task_pool(world: World, params: dict | None) -> np.ndarray:
    """Flat cells new tasks may appear on: a generated warehouse's pick cells (cells beside a shelf),
    else every free cell of robot 0's 4-connected component (sorted)."""
    from mrmt_env.distances import bfs_distance_field

    reach = bfs_distance_field(world.grid, world.robots[0]).reshape(-1) >= 0
    if params is not None and params.get("layout") == "warehouse":
        layout = build_layout("warehouse", np.random.default_rng(0), world.height, world.width,
                              params.get("layout_options"))  # fixed for given sizes: the generator is not used
        pick = np.zeros(world.grid.size, dtype=bool)
        pick[layout.target_cells] = True
        reach &= pick
    return np.flatnonzero(reach).astype(np.int64)


class LifelongBatch:
    """``B`` lifelong episodes on ``H x W`` grids with ``R`` robots (see the module docstring)."""

    def __init__(self, n_envs: int, height: int, width: int, n_robots: int, options: LifelongOptions,
                 task_reward: float) -> None:
        b, r, hw = int(n_envs), int(n_robots), int(height) * int(width)
        self.n_envs, self.height, self.width, self.n_robots = b, int(height), int(width), r
        self.options = options
        self.task_reward = float(task_reward)
        self.succ = np.zeros((b, hw, 5), dtype=np.int64)
        self.pos = np.zeros((b, r), dtype=np.int64)
        self.at = np.full((b, hw), -1, dtype=np.int64)
        self.task_t = np.full((b, hw), -1, dtype=np.int64)
        self.free = np.zeros((b, hw), dtype=np.int64)
        self.free_idx = np.full((b, hw), -1, dtype=np.int64)
        self.n_free = np.zeros(b, dtype=np.int64)
        self.moves = np.zeros((b, r), dtype=np.int64)
        self.counters = np.zeros((b, len(COUNTERS)), dtype=np.int64)
        self.obs = np.zeros((b, 2 + r, hw), dtype=np.uint8)
        self.keys = np.zeros(b, dtype=np.uint64)
        self.draws = np.zeros(b, dtype=np.uint64)
        self.claim = np.full((b, hw), -1, dtype=np.int64)
        self.rewards = np.zeros(b, dtype=np.float64)
        #: The arrays every kernel call takes, one record (:class:`~mrmt_env.lifelong.kernels.LifelongArrays`).
        self.state = LifelongArrays(self.succ, self.pos, self.at, self.task_t, self.free, self.free_idx, self.n_free,
                                    self.moves, self.counters, self.obs)
        self.worlds: list[World | None] = [None] * b

    def load(self, i: int, world: World, pool: np.ndarray, key: int) -> None:
        """Start env ``i`` on ``world`` (its targets are the first open tasks, arrived at step 0)."""
        w = world.width
        robots = (world.robots[:, 0] * w + world.robots[:, 1]).astype(np.int64)
        tasks = (world.targets[:, 0] * w + world.targets[:, 1]).astype(np.int64)
        lifelong_load(i, np.ascontiguousarray(world.grid.reshape(-1)), w, robots, tasks, pool, self.state)
        self.keys[i] = np.uint64(key)
        self.draws[i] = np.uint64(0)
        self.worlds[i] = world

    def step(self, actions: np.ndarray, live: np.ndarray) -> np.ndarray:
        """Advance every live env by its joint action (``(B, R)`` int64, checked); returns the rewards (a view)."""
        o = self.options
        lifelong_step(actions, live, self.state, self.keys, self.draws, o.collisions == "block",
                      o.tasks == "poisson", 0.0 if o.task_rate is None else o.task_rate, self.task_reward,
                      self.claim, self.rewards)
        return self.rewards

    def masks(self) -> np.ndarray:
        """``(B, 5 * R)`` bools: stay and the moves not into an obstacle or off the grid."""
        out = np.zeros((self.n_envs, 5 * self.n_robots), dtype=np.bool_)
        grid_masks(self.succ, self.pos, out)  # the grid env's kernel: stay, and every unblocked move
        return out

    def info_arrays(self) -> dict:
        """Every info key as an array over the batch (the single env takes element 0)."""
        c = self.counters
        col = {name: c[:, j] for j, name in enumerate(COUNTERS)}
        steps, done = col["steps"], col["tasks_completed"]
        conflicts = col["vertex_conflicts"] + col["swap_conflicts"]
        return {
            "route_cost": col["route_cost"].copy(),
            "makespan": self.moves.max(axis=1),
            "steps": steps.copy(),
            "targets_visited": done.copy(),
            "n_targets": col["tasks_arrived"].copy(),
            "is_success": np.zeros(self.n_envs, dtype=bool),
            "invalid_moves": col["invalid_moves"].copy(),
            "conflicts": conflicts,
            "vertex_conflicts": col["vertex_conflicts"].copy(),
            "swap_conflicts": col["swap_conflicts"].copy(),
            "blocked_moves": col["blocked_moves"].copy(),
            "tasks_completed": done.copy(),
            "tasks_arrived": col["tasks_arrived"].copy(),
            "tasks_dropped": col["tasks_dropped"].copy(),
            "open_tasks": col["open_tasks"].copy(),
            "throughput": np.where(steps > 0, done / np.maximum(steps, 1), 0.0),
            "service_time_mean": np.where(done > 0, col["service_sum"] / np.maximum(done, 1), 0.0),
        }

    def info(self, i: int = 0) -> dict:
        """Env ``i``'s info as plain Python values (ints, bools, floats; no wall-clock values)."""
        c = self.counters[i].tolist()
        col = dict(zip(COUNTERS, c))
        steps, done = col["steps"], col["tasks_completed"]
        return {
            "route_cost": col["route_cost"],
            "makespan": int(self.moves[i].max()),
            "steps": steps,
            "targets_visited": done,
            "n_targets": col["tasks_arrived"],
            "is_success": False,
            "invalid_moves": col["invalid_moves"],
            "conflicts": col["vertex_conflicts"] + col["swap_conflicts"],
            "vertex_conflicts": col["vertex_conflicts"],
            "swap_conflicts": col["swap_conflicts"],
            "blocked_moves": col["blocked_moves"],
            "tasks_completed": done,
            "tasks_arrived": col["tasks_arrived"],
            "tasks_dropped": col["tasks_dropped"],
            "open_tasks": col["open_tasks"],
            "throughput": done / steps if steps else 0.0,
            "service_time_mean": col["service_sum"] / done if done else 0.0,
        }

    def open_task_cells(self, i: int = 0) -> np.ndarray:
        """``(K, 2)`` row-major ``[row, col]`` of env ``i``'s open tasks."""
        flat = np.flatnonzero(self.task_t[i] >= 0)
        return np.stack(np.divmod(flat, self.width), axis=1).astype(np.int64)

    def positions(self, i: int = 0) -> np.ndarray:
        """``(R, 2)`` current robot cells of env ``i``."""
        return np.stack(np.divmod(self.pos[i], self.width), axis=1).astype(np.int64)
