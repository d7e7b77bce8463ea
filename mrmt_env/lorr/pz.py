"""The LoRR env in PettingZoo parallel form: one agent per robot, the team's tasks as reward.

``lorr_parallel_env(instance=PATH, steps=None, scheduler="greedy")`` runs the same
:class:`~mrmt_env.lorr.env.LoRRSetup` as ``mrmt_env/LoRR-v0``: agents ``robot_0 ..``, each
``Discrete(4)`` (F, R, C, W), all moving at once; a robot's observation is its ``position``,
``orientation``, ``task`` and ``goal`` (scalars); ``state()`` the whole fleet's
``(R, 4)`` array of the same.  Every agent truncates after ``steps``; none terminates.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from mrmt_env.config import EnvConfig
from mrmt_env.lorr.env import LoRRSetup, render_lorr

__all__ = ["LoRRParallelEnv", "lorr_parallel_env"]


class LoRRParallelEnv(ParallelEnv):
    """A LoRR instance, one PettingZoo agent per robot (see the module docstring)."""

    metadata = {"render_modes": ["ansi", "rgb_array"], "name": "lorr_v0", "is_parallelizable": True,
                "render_fps": 8}

    def __init__(self, config: EnvConfig | None = None, *, render_mode: str | None = None, **options) -> None:
        inst = LoRRSetup.attach(self, config, render_mode, options)
        self.possible_agents = [f"robot_{k}" for k in range(inst.team_size)]
        self.agents: list[str] = []
        big = np.iinfo(np.int64).max
        obs = self.setup.observation_space(())
        self._obs_space = obs
        self._act_space = spaces.Discrete(self.setup.n_actions)
        self.state_space = spaces.Box(-1, big, (inst.team_size, 4), np.int64)

    def observation_space(self, agent):
        return self._obs_space

    def action_space(self, agent):
        return self._act_space

    def _columns(self) -> np.ndarray:
        sim = self.setup.sim
        task, goal = self.setup.goals()
        return np.stack([sim.pos, sim.orient, task, goal], axis=1).astype(np.int64)

    def _observe(self) -> dict:
        cols = self._columns()
        keys = ("position", "orientation", "task", "goal")
        return {a: {k: np.int64(cols[i, j]) for j, k in enumerate(keys)} for i, a in enumerate(self.possible_agents)
                if a in self.agents}

    def state(self) -> np.ndarray:
        return self._columns()

    def reset(self, seed: int | None = None, options: dict | None = None):
        self.setup.reset()
        self.agents = list(self.possible_agents)
        info = self.setup.info()
        return self._observe(), {a: dict(info) for a in self.agents}

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("the episode is over; call reset()")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"actions are missing for {len(missing)} agents, first {missing[0]!r} "
                             "(every robot moves every step; give 3 = wait)")
        unknown = [a for a in actions if a not in self.possible_agents]
        if unknown:
            raise ValueError(f"unknown agent {unknown[0]!r}; agents are robot_0 .. robot_{len(self.possible_agents) - 1}")
        joint = np.array([int(actions[a]) for a in self.possible_agents], dtype=np.int64)

        done = self.setup.step(joint)
        trunc = self.setup.sim.t >= self.setup.steps
        obs = self._observe()
        info = self.setup.info()
        rewards = {a: float(done) for a in self.agents}
        terms = {a: False for a in self.agents}
        truncs = {a: trunc for a in self.agents}
        infos = {a: dict(info) for a in self.agents}
        if trunc:
            self.agents = []
        return obs, rewards, terms, truncs, infos

    def render(self):
        if self.render_mode is None:
            return None
        return render_lorr(self.setup, self.render_mode)


def lorr_parallel_env(**kwargs) -> LoRRParallelEnv:
    """The LoRR env in PettingZoo parallel form (see the module docstring)."""
    return LoRRParallelEnv(**kwargs)
