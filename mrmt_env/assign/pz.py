"""The PettingZoo form of the plan-level env: an AEC env where the idle robot is the agent to act.

``assign_aec_env(**kwargs)`` takes the arguments of :class:`mrmt_env.assign.env.MRMTAssignEnv` plus ``max_cycles``
(decisions before truncation, default 200); ``agent_selection`` is the deciding robot, action masks come in the
observation as in PettingZoo's classic games.
Design notes (spaces, reward, episode end): docs/design/envs.md#the-pettingzoo-plan-level-env.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import AECEnv

from mrmt_env.config import WORLD_OPTIONS, EnvConfig, WorldConfig
from mrmt_env.assign.env import _check_action
from mrmt_env.assign.state import AssignBatch, assign_feature_count, assign_obs_high
from mrmt_env.core import check_render_mode
from mrmt_env.render import render_ansi, render_rgb
from mrmt_env.team import check_cycles
from mrmt_env.world import World

__all__ = ["MRMTAssignAECEnv", "assign_aec_env", "DEFAULT_MAX_CYCLES"]

DEFAULT_MAX_CYCLES = 200


class MRMTAssignAECEnv(AECEnv):
    """Plan-level MRMT as a PettingZoo AEC env (see the module docstring)."""

    metadata = {"render_modes": ["ansi", "rgb_array", "human"], "name": "mrmt_assign_v0", "is_parallelizable": False,
                "render_fps": 2}

    #: The options of :class:`~mrmt_env.config.EnvConfig` this env takes.
    config_options = (*WORLD_OPTIONS, "max_cycles")

    def __init__(self, config: EnvConfig | WorldConfig | None = None, *, render_mode: str | None = None,
                 **options) -> None:
        super().__init__()
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.config = cfg = EnvConfig.of(config, takes=self.config_options, env=type(self).__name__, **options)
        self.max_cycles = check_cycles(cfg.max_cycles, None, DEFAULT_MAX_CYCLES)
        self.render_mode = render_mode
        self.source = cfg.source()
        h, w, r = self.source.height, self.source.width, self.source.n_robots
        n = int(self.source.params["n_targets"])
        self.n_robots, self.n_targets = r, n
        self.possible_agents = [f"robot_{k}" for k in range(r)]
        obs_space = spaces.Dict({
            "observation": spaces.Box(0.0, assign_obs_high(h, w, n), (n + r, assign_feature_count(n)), np.float32),
            "action_mask": spaces.Box(0, 1, (n + 1,), np.int8),
        })
        self.observation_spaces = {a: obs_space for a in self.possible_agents}
        self.action_spaces = {a: spaces.Discrete(n + 1) for a in self.possible_agents}
        self.state_ = AssignBatch(1, h, w, r, n)
        self.world: World | None = None
        self._np_random: np.random.Generator | None = None

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None) -> None:
        if seed is not None or self._np_random is None:
            self._np_random, _ = seeding.np_random(seed)
        world = self.source.reset_world(options, self._np_random, self.n_targets)
        self.world = world
        self.state_.load(0, world)
        self.agents = self.possible_agents[:]
        self.rewards = {a: 0.0 for a in self.agents}
        self._cumulative_rewards = {a: 0.0 for a in self.agents}
        self.terminations = {a: False for a in self.agents}
        self.truncations = {a: False for a in self.agents}
        self.infos = {a: self.state_.info(0) for a in self.agents}
        decider = int(self.state_.decider[0])
        self.agent_selection = self.possible_agents[max(decider, 0)]
        if decider < 0:  # nothing to visit: every agent is done at once
            self.terminations = {a: True for a in self.agents}

    def observe(self, agent):
        obs = self.state_.observe()[0]
        mask = np.zeros(self.n_targets + 1, dtype=np.int8)
        if agent == self.agent_selection and not (self.terminations[agent] or self.truncations[agent]):
            mask[:] = self.state_.masks()[0]
        return {"observation": obs, "action_mask": mask}

    def step(self, action) -> None:
        if not getattr(self, "agents", None):
            raise RuntimeError("the episode is over (or reset() was never called); call reset()")
        agent = self.agent_selection
        if self.terminations[agent] or self.truncations[agent]:
            self._was_dead_step(action)
            return
        try:
            a = int(_check_action(action, self.n_targets)[0])
        except ValueError as exc:
            raise ValueError(f"{agent}: {exc}") from None
        self._cumulative_rewards[agent] = 0.0
        k = self.possible_agents.index(agent)
        was_active = bool(self.state_.active[0, k])
        rewards, terminated = self.state_.step(np.array([a], dtype=np.int64))
        reward = float(rewards[0])
        for ag in self.agents:
            self.rewards[ag] = reward
        if was_active and not self.state_.active[0, k]:
            self.terminations[agent] = True  # the robot retired
        if terminated[0]:
            self.terminations = {ag: True for ag in self.agents}
        elif int(self.state_.counters[0, 1]) >= self.max_cycles:
            self.truncations = {ag: True for ag in self.agents}
        info = self.state_.info(0)
        self.infos = {ag: dict(info) for ag in self.agents}
        decider = int(self.state_.decider[0])
        if decider >= 0:
            self.agent_selection = self.possible_agents[decider]
        self._accumulate_rewards()
        self._deads_step_first()
        if self.render_mode == "human":
            self.render()

    def render(self):
        if self.world is None:
            raise RuntimeError("call reset() before render()")
        if self.render_mode is None:
            return None
        pos, visited = self.state_.positions(0), self.state_.visited(0)
        if self.render_mode == "rgb_array":
            return render_rgb(self.world.grid, self.world.targets, visited, pos)
        info = self.state_.info(0)
        text = render_ansi(self.world.grid, self.world.targets, visited, pos,
                           f"step {info['steps']}  targets {info['targets_visited']}/{info['n_targets']}  "
                           f"route_cost {info['route_cost']}")
        if self.render_mode == "human":
            print(text, end="")
            return None
        return text

    def close(self) -> None:
        pass


def assign_aec_env(**kwargs) -> MRMTAssignAECEnv:
    """The plan-level PettingZoo AEC env (arguments: see :class:`MRMTAssignAECEnv`)."""
    return MRMTAssignAECEnv(**kwargs)
