"""The plan-level Gymnasium env ``mrmt_env/MRMT-Assign-v0``: idle robots pick targets."""

from __future__ import annotations

import numpy as np
import gymnasium as gym
from gymnasium import spaces

from mrmt_env.config import WORLD_OPTIONS, EnvConfig, WorldConfig
from mrmt_env.assign.state import AssignBatch, assign_feature_count, assign_obs_high
from mrmt_env.core import check_render_mode, render_ready, show
from mrmt_env.render import render_ansi, render_rgb
from mrmt_env.world import World

__all__ = ["MRMTAssignEnv", "shortest_path", "robot_path"]


def shortest_path(world: World, start, goal) -> np.ndarray:
    """A BFS shortest path ``(L+1, 2)`` from ``start`` to ``goal`` (ties: up, down, left, right)."""
    field = world.distance_field(goal)
    r, c = int(start[0]), int(start[1])
    if field[r, c] < 0:
        raise ValueError(f"cell {[r, c]} cannot reach {[int(goal[0]), int(goal[1])]}")
    path = [(r, c)]
    h, w = field.shape
    while field[r, c] > 0:
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            nr, nc = r + dr, c + dc
            if 0 <= nr < h and 0 <= nc < w and field[nr, nc] == field[r, c] - 1:
                r, c = nr, nc
                break
        path.append((r, c))
    return np.array(path, dtype=np.int64)


def _check_action(action, n_targets: int) -> np.ndarray:
    """One action as a ``(1,)`` int64 array; ``ValueError`` naming the value unless an integer in ``0..N``."""
    try:
        a = np.asarray(action)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"action must be one integer in 0..{n_targets}, got {show(action)} "
                         f"({' '.join(str(exc).split())})") from None
    if a.ndim != 0 and a.shape != (1,):
        raise ValueError(f"action must be one integer in 0..{n_targets}, got shape {a.shape}")
    v = a.reshape(-1)[0] if a.size else None
    v = v.item() if isinstance(v, np.generic) else v
    if isinstance(v, bool) or not isinstance(v, int):
        raise ValueError(f"action must be one integer in 0..{n_targets} (targets 0..{n_targets - 1}, {n_targets} = "
                         f"stop), got {show(v)} of dtype {a.dtype}")
    if not 0 <= v <= n_targets:
        raise ValueError(f"action {v} is outside 0..{n_targets} (targets 0..{n_targets - 1}, {n_targets} = stop)")
    return np.array([v], dtype=np.int64)


class MRMTAssignEnv(gym.Env):
    """
    ## Description

    The plan-level form of the MRMT task (the decision a learned allocator and
    the planners share).  At each step one *idle* robot -- the active robot
    with the least committed travel time, lowest index on ties -- chooses its
    next target; it then moves there along a BFS shortest path of the same
    world model as ``mrmt_env/MRMT-v0`` (``World.distance_matrix``).  Robots
    travel concurrently: the clock of a robot is the moves it has committed.

    ## Action Space

    ``Discrete(N + 1)``: ``j < N`` sends the deciding robot to target ``j``;
    ``N`` retires it (it takes no more targets).  Legal actions are given by
    ``action_masks()`` (sb3-contrib's ``MaskablePPO`` calls it) and by
    ``info["action_mask"]``: a target must be open (not yet taken) and
    reachable; stop is legal only while every open target stays reachable by
    another active robot, so a masked agent always visits every target.  An
    action the mask forbids changes nothing, costs -1 and counts in
    ``info["invalid_moves"]`` (as a blocked move does in the grid env); a
    value outside ``0..N`` raises ``ValueError``.

    ## Observation Space

    ``Box(0, high, (N + R, 8 + N), float32)``: one row per target, then one
    row per robot (in robot order).  Distances are BFS moves divided by
    ``H + W``; an unreachable one reads ``H * W / (H + W)``.

    | column | target row ``j``                              | robot row ``k``                     |
    |--------|-----------------------------------------------|-------------------------------------|
    | 0      | 1                                             | 0                                   |
    | 1      | open (not yet taken)                          | active                              |
    | 2, 3   | row / (H-1), col / (W-1)                      | same, of the cell it is bound for   |
    | 4      | distance from the deciding robot              | committed time beyond now           |
    | 5      | earliest arrival of another active robot      | committed moves (route so far)      |
    | 6      | distance to the nearest other open target     | 1 if it is the deciding robot       |
    | 7      | share of targets still open                   | share of targets still open         |
    | 8 + i  | distance to target ``i``                      | distance to target ``i``            |

    ## Rewards

    Minus the moves a step commits (0 for stop; -1 for a forbidden action),
    so a masked agent's return is minus the paper's route cost.

    ## Episode End

    Termination when no target is open (a masked agent needs at most
    ``N + R`` steps).  Truncation: the step limit (registered: 200;
    ``max_episode_steps`` for a directly constructed env).  After the env
    returned ``terminated`` or (its own) ``truncated``, ``step`` raises
    ``RuntimeError`` until ``reset``; under ``gymnasium.make`` the limit is
    gymnasium's ``TimeLimit`` wrapper, which the env does not see: call
    ``reset`` after ``truncated`` as after ``terminated``.

    ## Info

    ``route_cost``, ``makespan``, ``steps`` (decisions), ``targets_visited``,
    ``n_targets``, ``is_success``, ``invalid_moves`` (always 0), ``robot``
    (the robot deciding next, -1 at the end) and ``action_mask``.
    No wall-clock values.

    ## Arguments

    Those of ``MRMTEnv``: ``config`` (a :class:`~mrmt_env.config.WorldConfig`) or ``height``, ``width``, ``obstacle_density``,
    ``n_robots``, ``n_targets``, ``placement``, ``layout``, ``layout_options``, ``world``,
    ``max_episode_steps``, ``render_mode`` (``"ansi"``, ``"rgb_array"``,
    ``"human"``).  Worlds and seeding are the grid env's: the same
    ``reset(seed=s)`` gives the same world in both.

    ## Version History

    * v0: initial version.
    """

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "render_fps": 2}

    #: The options of :class:`~mrmt_env.config.EnvConfig` this env takes.
    config_options = (*WORLD_OPTIONS, "max_episode_steps")

    def __init__(self, config: EnvConfig | WorldConfig | None = None, *, render_mode: str | None = None,
                 **options) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.config = cfg = EnvConfig.of(config, takes=self.config_options, env=type(self).__name__, **options)
        self.max_episode_steps = cfg.max_episode_steps
        self.source = cfg.source()
        h, w, r = self.source.height, self.source.width, self.source.n_robots
        n = int(self.source.fixed.n_targets if self.source.fixed is not None else self.source.params["n_targets"])
        self.n_robots, self.n_targets = r, n
        self.action_space = spaces.Discrete(n + 1)
        self.observation_space = spaces.Box(0.0, assign_obs_high(h, w, n), (n + r, assign_feature_count(n)), np.float32)
        self.state = AssignBatch(1, h, w, r, n)
        self.world: World | None = None
        self._ended: str | None = None
        self.orders: list[list[int]] = [[] for _ in range(r)]

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        world = self.source.reset_world(options, self.np_random, self.n_targets)
        self.world = world
        self.state.load(0, world)
        self._ended = None
        self.orders = [[] for _ in range(self.n_robots)]
        if self.render_mode == "human":
            self.render()
        return self.state.observe()[0], self._info()

    def step(self, action):
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        if self._ended is not None:
            raise RuntimeError(f"the episode has ended ({self._ended}); call reset() before step()")
        a = _check_action(action, self.n_targets)
        k = int(self.state.decider[0])
        before = int(self.state.counters[0, 2])
        rewards, terminated = self.state.step(a)
        if int(self.state.counters[0, 2]) > before:  # the decider took target a
            self.orders[k].append(int(a[0]))
        term = bool(terminated[0])
        steps = int(self.state.counters[0, 1])
        truncated = not term and self.max_episode_steps is not None and steps >= self.max_episode_steps
        if term or truncated:
            self._ended = (f"terminated at step {steps}: no target left open" if term else
                           f"truncated at step {steps}: max_episode_steps={self.max_episode_steps}")
        if self.render_mode == "human":
            self.render()
        return self.state.observe()[0], float(rewards[0]), term, truncated, self._info()

    def action_masks(self) -> np.ndarray:
        """Legal actions now: ``(N + 1,)`` bool (targets, then stop); sb3-contrib's hook."""
        if self.world is None:
            raise RuntimeError("call reset() before action_masks()")
        return self.state.masks()[0]

    def render(self):
        if not render_ready(self.world is not None, self.render_mode):
            return None
        pos = self.state.positions(0)
        visited = self.state.visited(0)
        if self.render_mode == "rgb_array":
            return render_rgb(self.world.grid, self.world.targets, visited, pos)
        info = self._info()
        header = (f"step {info['steps']}  targets {info['targets_visited']}/{info['n_targets']}  "
                  f"route_cost {info['route_cost']}  makespan {info['makespan']}  next robot {info['robot']}")
        text = render_ansi(self.world.grid, self.world.targets, visited, pos, header)
        if self.render_mode == "human":
            print(text, end="")
            return None
        return text

    # -------------------------------------------------------------- helpers
    def _info(self) -> dict:
        info = self.state.info(0)
        info["action_mask"] = self.state.masks()[0]
        return info

    def route_paths(self) -> list[np.ndarray]:
        """Per robot, the cell-by-cell BFS path through the targets it has taken so far."""
        if self.world is None:
            raise RuntimeError("call reset() first")
        return [robot_path(self.world, k, order) for k, order in enumerate(self.orders)]


def robot_path(world: World, robot: int, order) -> np.ndarray:
    """Robot ``robot``'s BFS path from its start through targets ``order`` (``(L+1, 2)``)."""
    cells = [world.robots[robot]] + [world.targets[j] for j in order]
    path = [np.asarray(world.robots[robot]).reshape(1, 2)]
    for a, b in zip(cells, cells[1:]):
        path.append(shortest_path(world, a, b)[1:])
    return np.concatenate(path, axis=0)
