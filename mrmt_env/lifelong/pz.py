"""The lifelong env in PettingZoo form: one agent per robot, team reward.

``lifelong_parallel_env(**kwargs)`` returns a :class:`MRMTLifelongParallelEnv`;
``lifelong_env(**kwargs)`` the AEC form (``parallel_to_aec``, each move checked
when given).  Both run the same :class:`~mrmt_env.lifelong.state.LifelongBatch`
as the Gymnasium env (:class:`mrmt_env.lifelong.env.MRMTLifelongEnv`: task
stream, collision model, reward and ``info`` keys).

* Agents ``robot_0 .. robot_{R-1}``; ``Discrete(5)`` each; all move at once.
* Observation of ``robot_k``: ``(3 + R, H, W)`` uint8, the global channels
  (obstacles, open tasks, one channel per robot) plus its own cell.
* ``state()``: the global observation ``(2 + R, H, W)``.
* No termination (the stream does not end); every agent truncates after
  ``max_cycles`` steps (default 500; ``max_episode_steps`` is an alias).
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from mrmt_env.config import WorldConfig
from mrmt_env.core import N_ACTIONS, check_render_mode
from mrmt_env.lifelong.env import LifelongSetup, render_state
from mrmt_env.observation import agent_observation_space, observation_space
from mrmt_env.grid.pz import _CheckedAEC, check_move

__all__ = ["MRMTLifelongParallelEnv", "lifelong_parallel_env", "lifelong_env", "DEFAULT_MAX_CYCLES"]

DEFAULT_MAX_CYCLES = 500


class MRMTLifelongParallelEnv(ParallelEnv):
    """Lifelong multi-robot task serving, one PettingZoo agent per robot (see the module docstring)."""

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "name": "mrmt_lifelong_v0",
                "is_parallelizable": True, "render_fps": 4}

    def __init__(self, config: WorldConfig | None = None, *, max_cycles: int | None = None,
                 max_episode_steps: int | None = None, target_reward=None, render_mode: str | None = None,
                 tasks: str = "refill", task_rate=None, collisions: str = "block", **world) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        if max_cycles is not None and max_episode_steps is not None and max_cycles != max_episode_steps:
            raise ValueError(f"max_cycles={max_cycles} and max_episode_steps={max_episode_steps} disagree; give one")
        limit = max_cycles if max_cycles is not None else max_episode_steps
        limit = DEFAULT_MAX_CYCLES if limit is None else limit
        if isinstance(limit, bool) or int(limit) != limit or limit < 1:
            raise ValueError(f"max_cycles must be an integer >= 1, got {limit!r}")
        self.max_cycles = int(limit)
        self.render_mode = render_mode
        self.setup = LifelongSetup(WorldConfig.of(config, **world), tasks, task_rate, collisions, target_reward)
        s = self.setup.source
        r, h, w = s.n_robots, s.height, s.width
        self.n_robots = r
        self.possible_agents = [f"robot_{k}" for k in range(r)]
        self.agents: list[str] = []
        self._index = {a: k for k, a in enumerate(self.possible_agents)}
        self.observation_spaces = {a: agent_observation_space(r, h, w) for a in self.possible_agents}
        self.action_spaces = {a: spaces.Discrete(N_ACTIONS) for a in self.possible_agents}
        self.state_space = observation_space(r, h, w)
        self.batch = self.setup.batch(1)
        self.world = None
        self._np_random = None
        self._live = np.ones(1, dtype=np.bool_)

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator:
        if self._np_random is None:
            self._np_random, _ = seeding.np_random()
        return self._np_random

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self._np_random, _ = seeding.np_random(seed)
        self.world = self.setup.start(self.batch, 0, self.np_random, options)
        self.agents = self.possible_agents[:]
        info = self.batch.info(0)
        if self.render_mode == "human":
            self.render()
        return self._observations(), {a: dict(info) for a in self.agents}

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("the episode is over (or reset() was never called); call reset()")
        if len(actions) != len(self.agents) or any(a not in actions for a in self.agents):
            missing = [a for a in self.agents if a not in actions]
            unknown = [a for a in actions if a not in self._index]
            raise ValueError(f"actions must name every live agent once: missing {missing}, unknown {unknown}")
        acts = np.zeros((1, self.n_robots), dtype=np.int64)
        for agent, a in actions.items():
            acts[0, self._index[agent]] = check_move(agent, a)
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

    def close(self) -> None:
        pass

    def _observations(self) -> dict:
        g = self.batch.obs[0].reshape(self.state_space.shape)
        n = g.shape[0]
        out = {}
        for agent in self.agents:
            k = self._index[agent]
            o = np.empty((n + 1,) + g.shape[1:], dtype=np.uint8)
            o[:n] = g
            o[n] = g[2 + k]
            out[agent] = o
        return out


def lifelong_parallel_env(**kwargs) -> MRMTLifelongParallelEnv:
    """The PettingZoo parallel lifelong env (arguments of :class:`MRMTLifelongParallelEnv`)."""
    return MRMTLifelongParallelEnv(**kwargs)


def lifelong_env(**kwargs):
    """The PettingZoo AEC lifelong env: ``parallel_to_aec`` of the parallel env, each move checked when given."""
    return OrderEnforcingWrapper(_CheckedAEC(MRMTLifelongParallelEnv(**kwargs)))
