"""The Gymnasium environment: centralised control of all robots."""

from __future__ import annotations

import numpy as np
import gymnasium as gym
from gymnasium import spaces

from mrmt_env.config import OBSERVATIONS, WORLD_OPTIONS, EnvConfig, WorldConfig
from mrmt_env.core import N_ACTIONS, MRMTCore, check_render_mode, render_ready, show
from mrmt_env.observation import image_observation_space, observation_space, to_image
from mrmt_env.world import World

__all__ = ["MRMTEnv", "check_joint_action", "OBSERVATIONS"]

def check_joint_action(action, n_robots: int) -> list[int]:
    """Validate a joint action and return it as a list of Python ints.

    Accepts an integer array-like of shape ``(R,)`` with values in ``0..4``.

    Raises:
        ValueError: wrong shape, non-integer dtype or a value outside ``0..4``
            (the message names the value and the robot).  Nothing is clipped.
    """
    try:
        a = np.asarray(action)
    except (TypeError, ValueError) as exc:  # e.g. ragged nested lists
        raise ValueError(f"action must be {n_robots} integer(s) 0..{N_ACTIONS - 1}, one per robot, got {show(action)} "
                         f"({' '.join(str(exc).split())})") from None
    if a.shape != (n_robots,):
        raise ValueError(f"action must have shape ({n_robots},) (one move per robot), got shape {a.shape}")
    acts = a.tolist()
    if a.dtype.kind not in "iu":
        bad = [v for v in acts if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer))]
        if a.dtype.kind != "O" or bad:
            raise ValueError(f"action must hold integers 0..{N_ACTIONS - 1}, got dtype {a.dtype}"
                             + (f" ({show(bad[0])})" if bad else ""))
    for k, v in enumerate(acts):
        if not 0 <= v < N_ACTIONS:
            raise ValueError(
                f"action for robot {k} is {v}; valid moves are 0..{N_ACTIONS - 1} "
                "(0 stay, 1 up, 2 down, 3 left, 4 right)"
            )
    return acts


class MRMTEnv(gym.Env):
    """
    ## Description

    Multi-robot multi-target planning on a grid (paper "Ising Acceleration for
    Multi-Robot Multi-Target Planning", sections 3 and 6.1): ``R`` robots on an
    ``H x W`` grid with obstacles must visit ``N`` target cells between them.
    A target is visited when any robot stands on it.  The paper's objective is
    the total route length (``info["route_cost"]``); its longest route is
    ``info["makespan"]``.  One agent controls every robot (centralised
    control), so stable-baselines3 can train on it unchanged.

    Robots have no collision model (the paper has none): they may share a cell.
    Pairs of robots sharing a cell (vertex conflicts) and pairs exchanging
    cells (swap conflicts) are counted in ``info`` so users can see them.

    ## Action Space

    ``MultiDiscrete([5] * R)``: one move per robot, applied simultaneously.

    - 0: stay
    - 1: up (row - 1)
    - 2: down (row + 1)
    - 3: left (col - 1)
    - 4: right (col + 1)

    (``mrmt_env.distances.MOVES`` lists moves 1..4 in this order.)  A move
    into an obstacle or off the grid leaves the robot in place and is counted
    in ``info["invalid_moves"]``.  An action of the wrong shape, a non-integer
    dtype or a value outside 0..4 raises ``ValueError``; nothing is clipped.

    ## Observation Space

    ``Box(0, 1, (2 + R, H, W), uint8)``, channel first:

    | Channel | Meaning                                    |
    |---------|--------------------------------------------|
    | 0       | obstacle cells                             |
    | 1       | targets not yet visited                    |
    | 2 + k   | robot k's current cell (exactly one 1)     |

    With ``observation="image"`` the same channels come as an image SB3's
    ``CnnPolicy`` accepts: ``Box(0, 255, (2 + R, s*H, s*W), uint8)``, values
    0/255, each cell an ``s x s`` block with ``s = ceil(36 / min(H, W))``
    (40 x 40 on 10 x 10; ``mrmt_env.observation.to_image``).

    The observation holds the whole world:
    ``mrmt_env.observation.world_from_observation(obs)`` rebuilds a ``World``
    (robots at their current cells, unvisited targets in row-major order).

    ## Rewards

    Per step: ``target_reward`` for each target visited for the first time in
    that step, minus 1 for each robot whose action is a move (1..4), whether the
    move is made or blocked.  Staying costs 0, so an idle robot is not punished.
    The default ``target_reward = 2 * H * W`` exceeds the cost of reaching any
    further target (a robot can walk its whole free component in fewer moves),
    so the episode return

        ``target_reward * (targets visited after reset) - route_cost - invalid_moves``

    is maximised exactly by visiting every target with the fewest total moves
    and no blocked moves.  Targets under a robot at reset give no reward.

    Optional dense reward (``dense_reward = c > 0``): each step also gets
    ``c * (phi(s') - phi(s))`` with ``phi`` = minus the summed BFS moves from
    each robot to its nearest unvisited target: progress towards targets pays
    at once.  It is potential-based shaping (Ng et al. 1999), so with
    ``gamma = 1`` the best policies are unchanged (the shaping sums to
    ``-phi(s_0)`` over a completed episode).

    ## Action Masks

    ``action_masks()`` returns ``(5 * R,)`` bools, robot by robot (stay, up,
    down, left, right): a move into an obstacle or off the grid is masked.
    This is the flat ``MultiDiscrete`` mask sb3-contrib's ``MaskablePPO``
    expects; masked moves stay legal for the env (blocked, as above).

    ## Starting State

    Without a fixed ``world``, each ``reset(seed=...)`` draws a new world with
    ``mrmt_env.generate_world`` from the env's random generator (the paper's
    set-up: exactly ``round(density * H * W)`` obstacles, robots and targets on
    distinct cells of one 4-connected free component; or the map family
    ``layout``, ``docs/maps.md``).  With a fixed world,
    every episode starts from it.  ``reset(options={"world": w})`` starts one
    episode from the ``World`` ``w`` (same ``H, W, R`` as the env).  Targets
    under a robot at reset are visited at once.

    ## Episode End

    1. Termination: every target has been visited (``info["is_success"]``).
       A world whose targets are all visited at reset terminates on the
       first step.
    2. Truncation: the step limit.  Registered ids get it from
       ``gymnasium.make`` (``TimeLimit``, ``max_episode_steps`` below); a
       directly constructed env truncates itself if ``max_episode_steps`` is
       given.  Truncation never sets ``terminated``.

    After the env returned ``terminated`` or (its own) ``truncated``, ``step``
    raises ``RuntimeError`` until ``reset``: the episode's metrics are final.
    Under ``gymnasium.make`` the step limit is gymnasium's ``TimeLimit``
    wrapper, which the env itself does not see: call ``reset`` after
    ``truncated`` as after ``terminated`` (a further step would go on moving).

    ## Info

    Every ``reset`` and ``step`` returns the flat keys ``route_cost`` (moves
    actually made by all robots so far; blocked moves are not moves),
    ``makespan`` (most moves made by one robot), ``steps``,
    ``targets_visited``, ``n_targets``, ``is_success``, ``invalid_moves``,
    ``conflicts`` (= ``vertex_conflicts + swap_conflicts``, summed over steps:
    each step adds the number of robot pairs sharing a cell after it and the
    number of pairs that exchanged cells in it), ``vertex_conflicts`` and
    ``swap_conflicts``.  No wall-clock values.

    ## Arguments

    ```python
    >>> import gymnasium as gym
    >>> import mrmt_env
    >>> env = gym.make("mrmt_env/MRMT-v0", render_mode="ansi")
    >>> obs, info = env.reset(seed=0)
    >>> obs.shape
    (5, 10, 10)

    ```

    The options come as one frozen :class:`~mrmt_env.config.EnvConfig` (``config``, the first
    positional argument; a :class:`~mrmt_env.config.WorldConfig` holds the world's alone) or as
    keywords of the same names, which override it (what ``gym.make(id, n_robots=5)`` passes); every
    env of the package takes them so, and refuses, naming them, options it does not take.

    | Parameter          | Type                 | Default     | Description                                        |
    |--------------------|----------------------|-------------|----------------------------------------------------|
    | `config`           | EnvConfig or None    | None        | the options below (but `render_mode`), as one record |
    | `height`           | int                  | 10          | grid rows (generated worlds)                       |
    | `width`            | int                  | 10          | grid columns (generated worlds)                    |
    | `obstacle_density` | float or None        | 0.2         | obstacle share of the `uniform` layout             |
    | `n_robots`         | int                  | 3           | robots R                                           |
    | `n_targets`        | int                  | 10          | targets N                                          |
    | `placement`        | str                  | `"uniform"` | `"uniform"` or `"centre"` robot spawn              |
    | `layout`           | str                  | `"uniform"` | map family: `uniform`, `warehouse`, `rooms`, `maze` |
    | `layout_options`   | dict or None         | None        | the family's options (`mrmt_env.maps`)             |
    | `world`            | World, path or None  | None        | fixed world (or world file) for every episode      |
    | `max_episode_steps`| int or None          | None        | self-truncation for direct construction            |
    | `target_reward`    | float or None        | `2 * H * W` | reward per newly visited target                    |
    | `observation`      | str                  | `"binary"`  | `"binary"` or `"image"` (CNN-ready, see above)     |
    | `dense_reward`     | float                | 0.0         | weight of the BFS-progress shaping (0 = off)        |
    | `render_mode`      | str or None          | None        | `"ansi"`, `"rgb_array"` or `"human"` (prints text) |

    Registered ids: ``mrmt_env/MRMT-v0`` (10x10, density 0.2, 3 robots, 10
    targets, uniform placement, 200 steps), ``mrmt_env/MRMT-Centre-v0`` (the
    same with the paper's centre spawn), ``mrmt_env/MRMT-5x5-v0`` (5x5, 1
    obstacle, 2 robots, 3 targets, 50 steps; for quick RL training); big
    worlds of 10 robots and 100 targets on 64x64: ``mrmt_env/MRMT-64x64-v0``
    (uniform), ``mrmt_env/MRMT-Warehouse-v0``, ``mrmt_env/MRMT-Rooms-v0``
    (1000 steps each), ``mrmt_env/MRMT-Maze-v0`` (4000 steps); and
    ``mrmt_env/MRMT-Warehouse-128x128-v0`` (50 robots, 500 targets, 1500
    steps).  Grids up to ``mrmt_env.core.MAX_GRID_ENV_CELLS`` (1024x1024);
    map families and limits: ``docs/maps.md``.

    ## Version History

    * v0: initial version.
    """

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "render_fps": 4}

    #: The options of :class:`~mrmt_env.config.EnvConfig` this env takes.
    config_options = (*WORLD_OPTIONS, "max_episode_steps", "target_reward", "observation", "dense_reward")

    def __init__(self, config: EnvConfig | WorldConfig | None = None, *, render_mode: str | None = None,
                 **options) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.config = cfg = EnvConfig.of(config, takes=self.config_options, env=type(self).__name__, **options)
        self.observation_mode = cfg.observation
        self.dense_reward = float(cfg.dense_reward)
        self.render_mode = render_mode
        self.max_episode_steps = cfg.max_episode_steps
        self.source = cfg.source(grid_env=True)
        self.n_robots = self.source.n_robots
        self.action_space = spaces.MultiDiscrete([N_ACTIONS] * self.n_robots)
        space = image_observation_space if cfg.observation == "image" else observation_space
        self.observation_space = space(self.n_robots, self.source.height, self.source.width)
        self.core = MRMTCore(cfg.target_reward)
        self._field = None
        self._ashape = (self.n_robots,)
        self.world: World | None = None
        self._ended: str | None = None

    # ------------------------------------------------------------------ API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        world = self.source.reset_world(options, self.np_random)
        self.world = world
        self.core.reset(world)
        self._ended = None
        if self.dense_reward:
            self._field = self.core.nearest_target_field()
        if self.render_mode == "human":
            self.render()
        return self._obs(), self.core.info()

    def step(self, action):
        core = self.core
        if core.world is None:
            raise RuntimeError("call reset() before step()")
        if self._ended is not None:
            raise RuntimeError(f"the episode has ended ({self._ended}); call reset() before step()")
        # fast path for the common case (an integer ndarray of the right shape)
        if type(action) is np.ndarray and action.shape == self._ashape and action.dtype.kind in "iu":
            acts = action.tolist()
            if min(acts) < 0 or max(acts) >= N_ACTIONS:
                acts = check_joint_action(action, self.n_robots)  # raises, naming the robot
        else:
            acts = check_joint_action(action, self.n_robots)
        if self.dense_reward:
            phi = core.potential(self._field)
            reward = core.step(acts)
            if core.last_new_targets:
                self._field = core.nearest_target_field()
            reward += self.dense_reward * (core.potential(self._field) - phi)
        else:
            reward = core.step(acts)
        terminated = core.n_visited == core.n_targets
        truncated = (
            not terminated and self.max_episode_steps is not None and core.steps >= self.max_episode_steps
        )
        if terminated or truncated:
            self._ended = (f"terminated at step {core.steps}: every target visited" if terminated else
                           f"truncated at step {core.steps}: max_episode_steps={self.max_episode_steps}")
        if self.render_mode == "human":
            self.render()
        return self._obs(), float(reward), terminated, truncated, core.info()

    def render(self):
        if not render_ready(self.core.world is not None, self.render_mode):
            return None
        return self.core.render(self.render_mode, makespan=True)

    def action_masks(self) -> np.ndarray:
        """``(5 * R,)`` bool: per robot, which of stay/up/down/left/right is not blocked (sb3-contrib's hook)."""
        if self.core.world is None:
            raise RuntimeError("call reset() before action_masks()")
        return self.core.move_masks().reshape(-1)

    # -------------------------------------------------------------- helpers
    def _obs(self) -> np.ndarray:
        obs = self.core.observation()
        return to_image(obs) if self.observation_mode == "image" else obs

    def current_world(self) -> World:
        """The world now: robots at their current cells, unvisited targets in
        their original order (``world_from_observation`` gives row-major order)."""
        if self.core.world is None:
            raise RuntimeError("call reset() first")
        return self.core.current_world()
