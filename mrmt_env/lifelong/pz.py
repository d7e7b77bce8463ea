"""The lifelong env in PettingZoo form: one agent per robot, team reward.

``lifelong_parallel_env(**kwargs)`` returns a :class:`MRMTLifelongParallelEnv`, ``lifelong_env(**kwargs)`` the AEC
form; both run the Gymnasium env's :class:`~mrmt_env.lifelong.state.LifelongBatch`. No termination; truncation
after ``max_cycles`` steps. Design notes (spaces): docs/design/lifelong.md#the-pettingzoo-lifelong-env.
"""

from __future__ import annotations

import numpy as np
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from mrmt_env.config import EnvConfig, WorldConfig
from mrmt_env.grid.pz import _CheckedAEC
from mrmt_env.lifelong.env import LifelongSetup, MRMTLifelongEnv, render_state
from mrmt_env.team import RobotTeamEnv, check_cycles

__all__ = ["MRMTLifelongParallelEnv", "lifelong_parallel_env", "lifelong_env", "DEFAULT_MAX_CYCLES"]

DEFAULT_MAX_CYCLES = 500


class MRMTLifelongParallelEnv(RobotTeamEnv):
    """Lifelong multi-robot task serving, one PettingZoo agent per robot (see the module docstring)."""

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "name": "mrmt_lifelong_v0",
                "is_parallelizable": True, "render_fps": 4}

    #: The options of :class:`~mrmt_env.config.EnvConfig` this env takes.
    config_options = (*MRMTLifelongEnv.config_options, "max_cycles")

    def __init__(self, config: EnvConfig | WorldConfig | None = None, *, render_mode: str | None = None,
                 **options) -> None:
        self.config = cfg = EnvConfig.of(config, takes=self.config_options, env=type(self).__name__, **options)
        self.setup = LifelongSetup(cfg)
        s = self.setup.source
        self._team(s.n_robots, s.height, s.width, render_mode,
                   check_cycles(cfg.max_cycles, cfg.max_episode_steps, DEFAULT_MAX_CYCLES))
        self.batch = self.setup.batch(1)
        self.world = None
        self._live = np.ones(1, dtype=np.bool_)

    def reset(self, seed: int | None = None, options: dict | None = None):
        self._reseed(seed)
        self.world = self.setup.start(self.batch, 0, self.np_random, options)
        self.agents = self.possible_agents[:]
        info = self.batch.info(0)
        if self.render_mode == "human":
            self.render()
        return self._observations(), {a: dict(info) for a in self.agents}

    def step(self, actions: dict):
        acts = self._moves(actions)[None]
        reward = float(self.batch.step(acts, self._live)[0])
        info = self.batch.info(0)
        truncated = info["steps"] >= self.max_cycles
        agents = self.agents
        obs = self._observations()
        out = (obs, {a: reward for a in agents}, {a: False for a in agents}, {a: truncated for a in agents},
               {a: dict(info) for a in agents})
        if truncated:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return out

    def state(self) -> np.ndarray:
        if self.world is None:
            raise RuntimeError("call reset() before state()")
        return self.batch.obs[0].reshape(self.state_space.shape).copy()

    def render(self):
        if self.world is None:
            raise RuntimeError("call reset() before render()")
        if self.render_mode is None:
            return None
        return render_state(self.batch, 0, self.render_mode)

    def _observations(self) -> dict:
        return self._views(self.batch.obs[0].reshape(self.state_space.shape), 2)


def lifelong_parallel_env(**kwargs) -> MRMTLifelongParallelEnv:
    """The PettingZoo parallel lifelong env (arguments of :class:`MRMTLifelongParallelEnv`)."""
    return MRMTLifelongParallelEnv(**kwargs)


def lifelong_env(**kwargs):
    """The PettingZoo AEC lifelong env: ``parallel_to_aec`` of the parallel env, each move checked when given."""
    return OrderEnforcingWrapper(_CheckedAEC(MRMTLifelongParallelEnv(**kwargs)))
