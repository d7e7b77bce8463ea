"""Native vector env of ``mrmt_env/MRMT-Assign-v0``: one :class:`~mrmt_env.assign.state.AssignBatch` of ``B`` episodes.

``gymnasium.make_vec("mrmt_env/MRMT-Assign-v0", num_envs=B,
vectorization_mode="vector_entry_point")`` builds it.  Semantics, seeding and
infos are those of ``SyncVectorEnv`` over the single env
(:mod:`mrmt_env.vector_base`); ``action_masks()`` gives ``(B, N + 1)`` bools.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.vector.utils import batch_space

from mrmt_env.config import EnvConfig, WorldConfig
from mrmt_env.assign.env import MRMTAssignEnv
from mrmt_env.assign.state import AssignBatch, assign_feature_count, assign_obs_high
from mrmt_env.core import show
from mrmt_env.fast_generation import draw_world_arrays
from mrmt_env.vector_base import BatchedVectorEnv

__all__ = ["MRMTAssignVectorEnv"]


class MRMTAssignVectorEnv(BatchedVectorEnv):
    """``num_envs`` plan-level episodes stepped together (arguments of ``MRMTAssignEnv`` plus
    ``num_envs``, ``autoreset_mode`` and ``copy``: return a copy of the observation buffer)."""

    metadata = {**BatchedVectorEnv.metadata, "render_modes": []}

    config_options = MRMTAssignEnv.config_options

    def __init__(self, num_envs: int = 1, config: EnvConfig | WorldConfig | None = None, *, render_mode=None,
                 autoreset_mode="NextStep", copy: bool = True, **options) -> None:
        super().__init__(num_envs, config, render_mode, autoreset_mode, copy, options)
        self.source = self.config.source()
        h, w, r = self.source.height, self.source.width, self.source.n_robots
        n = int(self.source.params["n_targets"])
        self.n_robots, self.n_targets = r, n
        self.single_action_space = spaces.Discrete(n + 1)
        self.single_observation_space = spaces.Box(0.0, assign_obs_high(h, w, n), (n + r, assign_feature_count(n)),
                                                   np.float32)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.state = AssignBatch(self.num_envs, h, w, r, n)
        self._obs = np.zeros(self.observation_space.shape, dtype=np.float32)
        self._masks = np.zeros((self.num_envs, n + 1), dtype=bool)

    def _load(self, i: int, rng: np.random.Generator) -> None:
        flat, robots, targets = draw_world_arrays(rng, self.source.params, self.source.fixed)
        self.state.load_arrays(i, flat, robots, targets)

    def _check_actions(self, actions, live: np.ndarray) -> np.ndarray:
        try:
            a = np.asarray(actions)
        except (TypeError, ValueError):
            raise ValueError(f"actions must be {self.num_envs} integers in 0..{self.n_targets}, got "
                             f"{show(actions)}") from None
        if a.shape != (self.num_envs,) or a.dtype.kind not in "iu":
            raise ValueError(f"actions must be {self.num_envs} integers in 0..{self.n_targets}, got {a.dtype} "
                             f"shape {a.shape}")
        bad = live & ((a < 0) | (a > self.n_targets))
        if bad.any():
            b = int(np.flatnonzero(bad)[0])
            raise ValueError(f"action {int(a[b])} of env {b} is outside 0..{self.n_targets} "
                             f"(targets 0..{self.n_targets - 1}, {self.n_targets} = stop)")
        return np.where(live, a, self.n_targets).astype(np.int64)  # an ignored env's action never matters

    def _step(self, actions: np.ndarray, live: np.ndarray):
        rewards, terminated = self.state.step(actions)
        return rewards.copy(), terminated.copy()

    def _observe(self) -> np.ndarray:
        return self.state.observe(self._obs)

    def _info_arrays(self) -> dict:
        st = self.state
        return {
            "route_cost": st.counters[:, 0].copy(),
            "makespan": st.free_at.max(axis=1),
            "steps": st.counters[:, 1].copy(),
            "targets_visited": st.counters[:, 2].copy(),
            "n_targets": np.full(self.num_envs, self.n_targets, dtype=np.int64),
            "is_success": st.counters[:, 2] == self.n_targets,
            "invalid_moves": st.counters[:, 3].copy(),
            "robot": st.decider.copy(),
            "action_mask": st.masks(self._masks).copy(),
        }

    def action_masks(self) -> np.ndarray:
        """``(B, N + 1)`` legal actions of each env's deciding robot."""
        return self.state.masks(self._masks).copy()

    def world(self, i: int):
        """Env ``i``'s current world (a :class:`~mrmt_env.world.World`)."""
        return self.state.world(i)
