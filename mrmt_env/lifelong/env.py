"""The lifelong Gymnasium env: tasks keep arriving, robots must not collide."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from mrmt_env.config import WORLD_OPTIONS, EnvConfig, WorldConfig
from mrmt_env.core import N_ACTIONS, MRMTCore, check_render_mode, render_ready
from mrmt_env.grid.env import check_joint_action
from mrmt_env.lifelong.state import LifelongBatch, LifelongOptions, task_pool
from mrmt_env.observation import observation_space
from mrmt_env.render import render_ansi, render_rgb
from mrmt_env.world import World

__all__ = ["MRMTLifelongEnv", "LifelongSetup"]


class LifelongSetup:
    """What a lifelong env (single, vector or PettingZoo) is built from: the world source, the options
    and the task reward; ``start(batch, i, rng, options)`` draws a world, its pool and stream key."""

    def __init__(self, config: EnvConfig) -> None:
        self.options = LifelongOptions(tasks=config.tasks, task_rate=config.task_rate, collisions=config.collisions)
        self.source = config.source(grid_env=True)
        target_reward = config.target_reward
        MRMTCore(target_reward)  # validates target_reward with the one-shot env's message
        h, w = self.source.height, self.source.width
        self.task_reward = MRMTCore.default_target_reward(h, w) if target_reward is None else float(target_reward)
        self._pools: dict[bytes, np.ndarray] = {}

    def batch(self, n_envs: int) -> LifelongBatch:
        s = self.source
        return LifelongBatch(n_envs, s.height, s.width, s.n_robots, self.options, self.task_reward)

    def start(self, batch: LifelongBatch, i: int, rng: np.random.Generator, options=None) -> World:
        world = self.source.reset_world(options, rng)
        key = world.grid.tobytes() + world.robots[0].tobytes()
        pool = self._pools.get(key)
        if pool is None:
            pool = task_pool(world, None if self.source.fixed is not None else self.source.params)
            if len(self._pools) > 64:
                self._pools.clear()
            self._pools[key] = pool
        batch.load(i, world, pool, int(rng.integers(0, 2**63)))
        return world


class MRMTLifelongEnv(gym.Env):
    """
    ## Description

    Lifelong multi-robot task serving on a grid: ``R`` robots, a stream of
    tasks (a task is a cell; it is served when a robot stands on it) and,
    by default, no collisions.  The League of Robot Runners' and POGEMA's
    lifelong setting on the package's worlds; the paper's one-shot problem
    is ``mrmt_env/MRMT-v0``.  Dynamics: :mod:`mrmt_env.lifelong.kernels`.

    ## Task stream

    The world's ``n_targets`` targets are the first ``K`` open tasks.
    ``tasks="refill"`` (default) replaces each served task by a new one, so
    ``K`` stay open; ``tasks="poisson"`` adds a Poisson number of tasks per
    step (``task_rate``, default 0.5).  New tasks go uniformly on pool cells
    without an open task: a warehouse's pick cells, else the robots' free
    component, never under a robot.  An arrival that finds no such cell is dropped
    (``info["tasks_dropped"]``).

    ## Collisions

    ``collisions="block"`` (default): a move into a cell another robot keeps
    or claims first (lower index), or an exchange of two robots' cells, is
    refused and the robot stays; refusals cascade to robots that needed its
    cell (``mrmt_env.lifelong.kernels.resolve_block``); each refusal counts in
    ``blocked_moves``, and ``conflicts`` stays 0.  ``"allow"``: robots may
    share cells; vertex and swap conflicts are counted as in ``MRMT-v0``.

    ## Spaces and reward

    As ``MRMT-v0``: ``MultiDiscrete([5] * R)`` (stay, up, down, left, right)
    and ``Box(0, 1, (2 + R, H, W), uint8)`` (obstacles, open tasks, one
    channel per robot), so its wrappers and policies apply.  Reward per step:
    ``target_reward`` (default ``2 * H * W``) per task served minus 1 per robot
    that attempts a move.  ``action_masks()``: moves not into an obstacle.

    ## Episode end

    Never terminated (the stream does not end); truncated at
    ``max_episode_steps`` (registered ids: by ``TimeLimit``).

    ## Info

    ``tasks_completed``, ``throughput`` (tasks per step), ``service_time_mean``
    (arrival to service, steps), ``open_tasks``, ``tasks_arrived``,
    ``tasks_dropped``, ``blocked_moves``, ``conflicts`` (with
    ``vertex_conflicts`` / ``swap_conflicts``), ``invalid_moves``, and the
    one-shot keys ``route_cost``, ``makespan``, ``steps``, ``targets_visited``
    (= tasks completed), ``n_targets`` (= tasks arrived), ``is_success``
    (always False).  No wall-clock values.

    ## Arguments

    Those of ``MRMTEnv`` (``config``, a :class:`~mrmt_env.config.WorldConfig`, or ``height``, ``width``, ``obstacle_density``,
    ``n_robots``, ``n_targets`` = ``K``, ``placement``, ``layout``,
    ``layout_options``, ``world``, ``target_reward``, ``max_episode_steps``,
    ``render_mode``) plus ``tasks``, ``task_rate`` and ``collisions``.
    """

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "render_fps": 4}

    #: The options of :class:`~mrmt_env.config.EnvConfig` this env takes.
    config_options = (*WORLD_OPTIONS, "max_episode_steps", "target_reward", "tasks", "task_rate", "collisions")

    def __init__(self, config: EnvConfig | WorldConfig | None = None, *, render_mode: str | None = None,
                 **options) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.config = cfg = EnvConfig.of(config, takes=self.config_options, env=type(self).__name__, **options)
        self.max_episode_steps = cfg.max_episode_steps
        self.setup = LifelongSetup(cfg)
        self.source = self.setup.source
        self.options = self.setup.options
        self.n_robots = self.source.n_robots
        self.action_space = spaces.MultiDiscrete([N_ACTIONS] * self.n_robots)
        self.observation_space = observation_space(self.n_robots, self.source.height, self.source.width)
        self.state = self.setup.batch(1)
        self.world: World | None = None
        self._ashape = (self.n_robots,)
        self._live = np.ones(1, dtype=np.bool_)
        self._ended: str | None = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self.world = self.setup.start(self.state, 0, self.np_random, options)
        self._ended = None
        if self.render_mode == "human":
            self.render()
        return self._obs(), self.state.info(0)

    def step(self, action):
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        if self._ended is not None:
            raise RuntimeError(f"the episode has ended ({self._ended}); call reset() before step()")
        if type(action) is np.ndarray and action.shape == self._ashape and action.dtype.kind in "iu" \
                and action.min() >= 0 and action.max() < N_ACTIONS:
            acts = action.astype(np.int64, copy=False).reshape(1, -1)
        else:
            acts = np.array(check_joint_action(action, self.n_robots), dtype=np.int64).reshape(1, -1)
        reward = float(self.state.step(acts, self._live)[0])
        info = self.state.info(0)
        truncated = self.max_episode_steps is not None and info["steps"] >= self.max_episode_steps
        if truncated:
            self._ended = f"truncated at step {info['steps']}: max_episode_steps={self.max_episode_steps}"
        if self.render_mode == "human":
            self.render()
        return self._obs(), reward, False, truncated, info

    def render(self):
        if not render_ready(self.world is not None, self.render_mode):
            return None
        return render_state(self.state, 0, self.render_mode)

    def action_masks(self) -> np.ndarray:
        """``(5 * R,)`` bool: per robot, which of stay/up/down/left/right is not into an obstacle."""
        if self.world is None:
            raise RuntimeError("call reset() before action_masks()")
        return self.state.masks()[0]

    def open_tasks(self) -> np.ndarray:
        """``(K, 2)`` cells of the open tasks, row-major."""
        return self.state.open_task_cells(0)

    def positions(self) -> np.ndarray:
        """``(R, 2)`` current robot cells."""
        return self.state.positions(0)

    def _obs(self) -> np.ndarray:
        return self.state.obs[0].reshape(self.observation_space.shape).copy()


def render_state(state: LifelongBatch, i: int, mode: str):
    """Env ``i`` of a batch as text (a header, then the grid: ``o`` open tasks) or an RGB image."""
    world = state.worlds[i]
    tasks = state.open_task_cells(i)
    pos = state.positions(i)
    if mode == "rgb_array":
        return render_rgb(world.grid, tasks, [False] * len(tasks), pos)
    info = state.info(i)
    header = (f"step {info['steps']}  served {info['tasks_completed']}  open {info['open_tasks']}  "
              f"blocked {info['blocked_moves']}")
    text = render_ansi(world.grid, tasks, [False] * len(tasks), pos, header)
    if mode == "human":
        print(text, end="")
        return None
    return text
