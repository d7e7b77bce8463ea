"""The PettingZoo environments: one agent per robot, team reward.

``parallel_env(**kwargs)`` returns a :class:`MRMTParallelEnv`, ``env(**kwargs)`` the AEC form; both run the same
:class:`~mrmt_env.core.MRMTCore` as the Gymnasium env (dynamics, reward and ``info`` of
:class:`mrmt_env.grid.env.MRMTEnv`). Agents ``robot_0 .. robot_{R-1}``, ``Discrete(5)`` each.
Design notes (spaces, episode end): docs/design/envs.md#the-pettingzoo-grid-envs.
"""

from __future__ import annotations

import numpy as np
from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from mrmt_env.config import WORLD_OPTIONS, EnvConfig, WorldConfig
from mrmt_env.core import MRMTCore
from mrmt_env.observation import ROBOT_CHANNEL0
from mrmt_env.team import RobotTeamEnv, check_cycles, check_move
from mrmt_env.world import World

__all__ = ["MRMTParallelEnv", "parallel_env", "env", "DEFAULT_MAX_CYCLES"]

DEFAULT_MAX_CYCLES = 200


class _CheckedAEC(parallel_to_aec_wrapper):
    """PettingZoo's AEC form of the parallel env, checking each move when it is given (not when the
    last agent of the cycle acts)."""

    def step(self, action):
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):
            check_move(agent, action)
        super().step(action)


class MRMTParallelEnv(RobotTeamEnv):
    """Multi-robot multi-target grid world, one PettingZoo agent per robot.

    Arguments are those of :class:`mrmt_env.grid.env.MRMTEnv` (``config`` or ``height``,
    ``width``, ``obstacle_density``, ``n_robots``, ``n_targets``, ``world``,
    ``placement``, ``layout``, ``layout_options``, ``target_reward``, ``render_mode``) plus ``max_cycles``
    (steps before truncation, default 200; ``max_episode_steps`` is accepted
    as an alias).  See the module docstring for spaces, reward and ends.
    """

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "name": "mrmt_v0", "is_parallelizable": True,
                "render_fps": 4}

    #: The options of :class:`~mrmt_env.config.EnvConfig` this env takes.
    config_options = (*WORLD_OPTIONS, "max_cycles", "max_episode_steps", "target_reward")

    def __init__(self, config: EnvConfig | WorldConfig | None = None, *, render_mode: str | None = None,
                 **options) -> None:
        self.config = cfg = EnvConfig.of(config, takes=self.config_options, env=type(self).__name__, **options)
        self.source = cfg.source(grid_env=True)
        src = self.source
        self._team(src.n_robots, src.height, src.width, render_mode,
                   check_cycles(cfg.max_cycles, cfg.max_episode_steps, DEFAULT_MAX_CYCLES))
        self.core = MRMTCore(cfg.target_reward)
        self.world: World | None = None

    # ---------------------------------------------------------------- API
    def reset(self, seed: int | None = None, options: dict | None = None):
        self._reseed(seed)
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
        acts = self._moves(actions).tolist()
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

    def _observations(self) -> dict:
        return self._views(self.core.obs, ROBOT_CHANNEL0)


def parallel_env(**kwargs) -> MRMTParallelEnv:
    """The PettingZoo parallel env (see :class:`MRMTParallelEnv` for arguments)."""
    return MRMTParallelEnv(**kwargs)


def env(**kwargs):
    """The PettingZoo AEC env: ``parallel_to_aec(parallel_env(**kwargs))``, each move checked when given."""
    return OrderEnforcingWrapper(_CheckedAEC(MRMTParallelEnv(**kwargs)))


def raw_env(**kwargs):
    """Alias of :func:`env` (PettingZoo's naming convention)."""
    return env(**kwargs)
