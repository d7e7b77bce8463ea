"""The PettingZoo environments: one agent per robot, team reward.

``parallel_env(**kwargs)`` returns a :class:`MRMTParallelEnv`; ``env(**kwargs)``
the AEC form (``parallel_to_aec``).  Both run the same
:class:`~mrmt_env.core.MRMTCore` as the Gymnasium env, so the dynamics,
reward and ``info`` keys are those documented in
:class:`mrmt_env.grid.env.MRMTEnv`.

* Agents ``robot_0 .. robot_{R-1}``; action space ``Discrete(5)`` each
  (0 stay, 1 up, 2 down, 3 left, 4 right); all robots move at once.
* Observation of agent ``robot_k``: ``Box(0, 1, (3 + R, H, W), uint8)``, the
  global channels (obstacles, unvisited targets, one channel per robot;
  see :mod:`mrmt_env.observation`) plus a last channel marking its own cell.
* ``state()``: the global observation ``(2 + R, H, W)`` (``state_space``).
* Reward: the team reward (the Gymnasium env's step reward) to every agent.
* Every agent terminates when all targets are visited; every agent truncates
  after ``max_cycles`` steps (default 200; ``max_episode_steps`` is an alias).
  Then ``agents`` becomes empty.
* ``info`` of every agent: the flat metrics dict of the Gymnasium env.
"""

from __future__ import annotations

import operator

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from mrmt_env.config import WorldConfig
from mrmt_env.core import N_ACTIONS, MRMTCore, check_render_mode, show
from mrmt_env.observation import ROBOT_CHANNEL0, agent_observation_space, observation_space
from mrmt_env.world import World

__all__ = ["MRMTParallelEnv", "parallel_env", "env", "DEFAULT_MAX_CYCLES"]

DEFAULT_MAX_CYCLES = 200


def check_move(agent: str, a) -> int:
    """One robot's move as an int; ``ValueError`` naming the agent and value unless an integer 0..4."""
    try:
        if isinstance(a, (bool, np.bool_)):
            raise TypeError
        v = operator.index(a)
    except TypeError:
        raise ValueError(f"action for {agent} must be an integer 0..{N_ACTIONS - 1}, got {show(a)}") from None
    if not 0 <= v < N_ACTIONS:
        raise ValueError(
            f"action for {agent} is {v}; valid moves are 0..{N_ACTIONS - 1} "
            "(0 stay, 1 up, 2 down, 3 left, 4 right)"
        )
    return v


class _CheckedAEC(parallel_to_aec_wrapper):
    """PettingZoo's AEC form of the parallel env, checking each move when it is given (not when the
    last agent of the cycle acts)."""

    def step(self, action):
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):
            check_move(agent, action)
        super().step(action)


class MRMTParallelEnv(ParallelEnv):
    """Multi-robot multi-target grid world, one PettingZoo agent per robot.

    Arguments are those of :class:`mrmt_env.grid.env.MRMTEnv` (``config`` or ``height``,
    ``width``, ``obstacle_density``, ``n_robots``, ``n_targets``, ``world``,
    ``placement``, ``layout``, ``layout_options``, ``target_reward``, ``render_mode``) plus ``max_cycles``
    (steps before truncation, default 200; ``max_episode_steps`` is accepted
    as an alias).  See the module docstring for spaces, reward and ends.
    """

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "name": "mrmt_v0", "is_parallelizable": True,
                "render_fps": 4}

    def __init__(self, config: WorldConfig | None = None, *, max_cycles: int | None = None,
                 max_episode_steps: int | None = None, target_reward: float | None = None,
                 render_mode: str | None = None, **world) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        if max_cycles is not None and max_episode_steps is not None and max_cycles != max_episode_steps:
            raise ValueError(f"max_cycles={max_cycles} and max_episode_steps={max_episode_steps} disagree; give one")
        limit = max_cycles if max_cycles is not None else max_episode_steps
        limit = DEFAULT_MAX_CYCLES if limit is None else limit
        if int(limit) != limit or limit < 1:
            raise ValueError(f"max_cycles must be an integer >= 1, got {limit!r}")
        self.max_cycles = int(limit)
        self.render_mode = render_mode
        self.source = WorldConfig.of(config, **world).source(grid_env=True)
        r, h, w = self.source.n_robots, self.source.height, self.source.width
        self.n_robots = r
        self.possible_agents = [f"robot_{k}" for k in range(r)]
        self.agents: list[str] = []
        self._index = {a: k for k, a in enumerate(self.possible_agents)}
        self.observation_spaces = {a: agent_observation_space(r, h, w) for a in self.possible_agents}
        self.action_spaces = {a: spaces.Discrete(N_ACTIONS) for a in self.possible_agents}
        self.state_space = observation_space(r, h, w)
        self.core = MRMTCore(target_reward)
        self.world: World | None = None
        self._np_random: np.random.Generator | None = None

    # ------------------------------------------------------------- spaces
    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator:
        if self._np_random is None:
            self._np_random, _ = seeding.np_random()
        return self._np_random

    # ---------------------------------------------------------------- API
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._np_random, _ = seeding.np_random(seed)
        world = self.source.reset_world(options, self.np_random)
        self.world = world
        self.core.reset(world)
        self.agents = self.possible_agents[:]
        info = self.core.info()
        if self.render_mode == "human":
            self.render()
        return self._observations(), {a: dict(info) for a in self.agents}

    def step(self, actions: dict):
        core = self.core
        if not self.agents:
            raise RuntimeError("the episode is over (or reset() was never called); call reset()")
        if len(actions) != len(self.agents) or any(a not in actions for a in self.agents):
            missing = [a for a in self.agents if a not in actions]
            unknown = [a for a in actions if a not in self._index]
            raise ValueError(f"actions must name every live agent once: missing {missing}, unknown {unknown}")
        acts = [0] * self.n_robots
        for agent, a in actions.items():
            acts[self._index[agent]] = check_move(agent, a)
        reward = float(core.step(acts))
        terminated = core.n_visited == core.n_targets
        truncated = not terminated and core.steps >= self.max_cycles
        agents = self.agents
        obs = self._observations()
        info = core.info()
        rewards = {a: reward for a in agents}
        terms = {a: terminated for a in agents}
        truncs = {a: truncated for a in agents}
        infos = {a: dict(info) for a in agents}
        if terminated or truncated:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return obs, rewards, terms, truncs, infos

    def state(self) -> np.ndarray:
        if self.core.world is None:
            raise RuntimeError("call reset() before state()")
        return self.core.observation()

    def render(self):
        if self.core.world is None:
            raise RuntimeError("call reset() before render()")
        if self.render_mode is None:
            return None
        return self.core.render(self.render_mode)

    def close(self) -> None:
        pass

    # ------------------------------------------------------------ helpers
    def _observations(self) -> dict:
        g = self.core.obs
        n = g.shape[0]
        out = {}
        for agent in self.agents:
            k = self._index[agent]
            o = np.empty((n + 1,) + g.shape[1:], dtype=np.uint8)
            o[:n] = g
            o[n] = g[ROBOT_CHANNEL0 + k]
            out[agent] = o
        return out


def parallel_env(**kwargs) -> MRMTParallelEnv:
    """The PettingZoo parallel env (see :class:`MRMTParallelEnv` for arguments)."""
    return MRMTParallelEnv(**kwargs)


def env(**kwargs):
    """The PettingZoo AEC env: ``parallel_to_aec(parallel_env(**kwargs))``, each move checked when given."""
    return OrderEnforcingWrapper(_CheckedAEC(MRMTParallelEnv(**kwargs)))


def raw_env(**kwargs):
    """Alias of :func:`env` (PettingZoo's naming convention)."""
    return env(**kwargs)
