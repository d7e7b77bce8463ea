"""Native vector env of the lifelong ids: ``B`` episodes in arrays, one compiled step.

``gymnasium.make_vec("mrmt_env/MRMT-Lifelong-v0", num_envs=B,
vectorization_mode="vector_entry_point")`` builds it.  Dynamics are those of
:class:`mrmt_env.lifelong.env.MRMTLifelongEnv` (:mod:`mrmt_env.lifelong.kernels`,
the same :class:`~mrmt_env.lifelong.state.LifelongBatch`); semantics, seeding
and infos those of ``SyncVectorEnv`` over the single env
(:mod:`mrmt_env.vector_base`); ``action_masks()`` gives ``(B, 5 * R)`` bools.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.vector.utils import batch_space

from mrmt_env.config import EnvConfig, WorldConfig
from mrmt_env.core import N_ACTIONS
from mrmt_env.lifelong.env import LifelongSetup, MRMTLifelongEnv
from mrmt_env.observation import observation_space
from mrmt_env.vector_base import BatchedVectorEnv, check_joint_moves

__all__ = ["MRMTLifelongVectorEnv"]


class MRMTLifelongVectorEnv(BatchedVectorEnv):
    """``num_envs`` lifelong episodes stepped together (arguments of ``MRMTLifelongEnv`` plus ``num_envs``,
    ``autoreset_mode`` and ``copy``: return a copy of the observation buffer)."""

    metadata = {**BatchedVectorEnv.metadata, "render_modes": []}

    config_options = MRMTLifelongEnv.config_options

    def __init__(self, num_envs: int = 1, config: EnvConfig | WorldConfig | None = None, *, render_mode=None,
                 autoreset_mode="NextStep", copy: bool = True, **options) -> None:
        super().__init__(num_envs, config, render_mode, autoreset_mode, copy, options)
        self.setup = LifelongSetup(self.config)
        s = self.setup.source
        self.height, self.width, self.n_robots = s.height, s.width, s.n_robots
        self.single_action_space = spaces.MultiDiscrete([N_ACTIONS] * self.n_robots)
        self.single_observation_space = observation_space(self.n_robots, self.height, self.width)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.state = self.setup.batch(self.num_envs)

    def _load(self, i: int, rng: np.random.Generator) -> None:
        self.setup.start(self.state, i, rng)

    def _check_actions(self, actions, live: np.ndarray) -> np.ndarray:
        return check_joint_moves(actions, live, self.n_robots)

    def _step(self, actions: np.ndarray, live: np.ndarray):
        rewards = self.state.step(actions, live).copy()
        return rewards, np.zeros(self.num_envs, dtype=bool)  # a lifelong episode only truncates

    def _observe(self) -> np.ndarray:
        return self.state.obs.reshape(self.num_envs, 2 + self.n_robots, self.height, self.width)

    def _info_arrays(self) -> dict:
        return self.state.info_arrays()

    def action_masks(self) -> np.ndarray:
        """``(B, 5 * R)``: per env and robot, stay and the moves not into an obstacle."""
        return self.state.masks()
