"""What the package's PettingZoo parallel envs share: one agent per robot and the checks of their input.

:class:`RobotTeamEnv` is a ``ParallelEnv`` with agents ``robot_0 .. robot_{R-1}``, ``Discrete(5)``
moves, per-agent observations (the global channels plus the agent's own cell), ``max_cycles``
(``max_episode_steps`` an alias) and the seeded ``np_random``; a subclass supplies ``reset``,
``step``, ``state`` and ``render``.
"""

from __future__ import annotations

import operator

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from mrmt_env.core import N_ACTIONS, check_render_mode, show
from mrmt_env.observation import agent_observation_space, observation_space

__all__ = ["RobotTeamEnv", "check_cycles", "check_move"]


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


def check_cycles(max_cycles, max_episode_steps, default: int) -> int:
    """The step limit of ``max_cycles`` or its alias ``max_episode_steps`` (``default`` without either);
    ``ValueError`` naming the value unless an integer >= 1, or when the two disagree."""
    if max_cycles is not None and max_episode_steps is not None and max_cycles != max_episode_steps:
        raise ValueError(f"max_cycles={max_cycles} and max_episode_steps={max_episode_steps} disagree; give one")
    limit = max_cycles if max_cycles is not None else max_episode_steps
    limit = default if limit is None else limit
    if isinstance(limit, bool) or int(limit) != limit or limit < 1:
        raise ValueError(f"max_cycles must be an integer >= 1, got {limit!r}")
    return int(limit)


class RobotTeamEnv(ParallelEnv):
    """One PettingZoo agent per robot (see the module docstring)."""

    def _team(self, n_robots: int, height: int, width: int, render_mode, max_cycles: int) -> None:
        check_render_mode(render_mode, self.metadata["render_modes"])
        self.render_mode = render_mode
        self.max_cycles = max_cycles
        self.n_robots = r = n_robots
        self.possible_agents = [f"robot_{k}" for k in range(r)]
        self.agents: list[str] = []
        self._index = {a: k for k, a in enumerate(self.possible_agents)}
        self.observation_spaces = {a: agent_observation_space(r, height, width) for a in self.possible_agents}
        self.action_spaces = {a: spaces.Discrete(N_ACTIONS) for a in self.possible_agents}
        self.state_space = observation_space(r, height, width)
        self._np_random: np.random.Generator | None = None

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def np_random(self) -> np.random.Generator:
        if self._np_random is None:
            self._np_random, _ = seeding.np_random()
        return self._np_random

    def _reseed(self, seed: int | None) -> None:
        if seed is not None:
            self._np_random, _ = seeding.np_random(seed)

    def _moves(self, actions: dict) -> np.ndarray:
        """``(R,)`` int64 moves of a step's ``actions``; ``ValueError`` unless they name every live agent
        once, each with a move 0..4."""
        if not self.agents:
            raise RuntimeError("the episode is over (or reset() was never called); call reset()")
        if len(actions) != len(self.agents) or any(a not in actions for a in self.agents):
            missing = [a for a in self.agents if a not in actions]
            unknown = [a for a in actions if a not in self._index]
            raise ValueError(f"actions must name every live agent once: missing {missing}, unknown {unknown}")
        acts = np.zeros(self.n_robots, dtype=np.int64)
        for agent, a in actions.items():
            acts[self._index[agent]] = check_move(agent, a)
        return acts

    def _views(self, g: np.ndarray, first_robot: int) -> dict:
        """Each live agent's observation: the global channels ``g`` plus its own robot channel again."""
        n = g.shape[0]
        out = {}
        for agent in self.agents:
            o = np.empty((n + 1,) + g.shape[1:], dtype=np.uint8)
            o[:n] = g
            o[n] = g[first_robot + self._index[agent]]
            out[agent] = o
        return out

    def close(self) -> None:
        pass
