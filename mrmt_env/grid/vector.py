"""Native vector env of the grid ids (``mrmt_env/MRMT-v0`` ...): ``B`` episodes in arrays, one compiled step.

``gymnasium.make_vec("mrmt_env/MRMT-v0", num_envs=B,
vectorization_mode="vector_entry_point")`` builds it.  Dynamics are those of
:class:`mrmt_env.core.MRMTCore` (:mod:`mrmt_env.grid.kernels`); semantics,
seeding and infos those of ``SyncVectorEnv`` over the single env
(:mod:`mrmt_env.vector_base`).  Options as the single env: ``observation``
(``"binary"`` / ``"image"``), ``dense_reward``, ``target_reward``;
``action_masks()`` gives ``(B, 5 * R)`` bools.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.vector.utils import batch_space

from mrmt_env.config import EnvConfig, WorldConfig
from mrmt_env.core import N_ACTIONS, MRMTCore
from mrmt_env.fast_generation import draw_world_arrays
from mrmt_env.grid.kernels import GridArrays, grid_load, grid_masks, grid_step
from mrmt_env.grid.env import MRMTEnv
from mrmt_env.observation import image_observation_space, observation_space, to_image
from mrmt_env.vector_base import BatchedVectorEnv, check_joint_moves

__all__ = ["MRMTVectorEnv"]


class MRMTVectorEnv(BatchedVectorEnv):
    """``num_envs`` grid episodes stepped together (arguments of ``MRMTEnv`` plus ``num_envs``,
    ``autoreset_mode`` and ``copy``: return a copy of the observation buffer)."""

    metadata = {**BatchedVectorEnv.metadata, "render_modes": []}

    config_options = MRMTEnv.config_options

    def __init__(self, num_envs: int = 1, config: EnvConfig | WorldConfig | None = None, *, render_mode=None,
                 autoreset_mode="NextStep", copy: bool = True, **options) -> None:
        super().__init__(num_envs, config, render_mode, autoreset_mode, copy, options)
        cfg = self.config
        self.source = cfg.source(grid_env=True)
        target_reward, observation = cfg.target_reward, cfg.observation
        h, w, r = self.source.height, self.source.width, self.source.n_robots
        n = int(self.source.params["n_targets"])
        b = self.num_envs
        MRMTCore(target_reward)  # validates target_reward with the single env's message
        self.target_reward = MRMTCore.default_target_reward(h, w) if target_reward is None else float(target_reward)
        self.height, self.width, self.n_robots, self.n_targets = h, w, r, n
        self.observation_mode, self.dense_reward = observation, float(cfg.dense_reward)
        self.single_action_space = spaces.MultiDiscrete([N_ACTIONS] * r)
        space = image_observation_space if observation == "image" else observation_space
        self.single_observation_space = space(r, h, w)
        self.action_space = batch_space(self.single_action_space, b)
        self.observation_space = batch_space(self.single_observation_space, b)
        hw = h * w
        self.succ = np.zeros((b, hw, 5), dtype=np.int64)
        self.tgt_at = np.full((b, hw), -1, dtype=np.int64)
        self.pos = np.zeros((b, r), dtype=np.int64)
        self.visited = np.zeros((b, n), dtype=np.bool_)
        self.moves = np.zeros((b, r), dtype=np.int64)
        self.counters = np.zeros((b, 6), dtype=np.int64)  # steps, route_cost, visited, invalid, vertex, swap
        self.grids = np.zeros((b, hw), dtype=np.bool_)
        self.targets = np.zeros((b, n), dtype=np.int64)
        self.field = np.full((b, hw), -1, dtype=np.int64)
        self._obs = np.zeros((b, 2 + r, hw), dtype=np.uint8)
        self._rewards = np.zeros(b, dtype=np.float64)
        self._terminated = np.zeros(b, dtype=np.bool_)
        self._masks = np.zeros((b, N_ACTIONS * r), dtype=np.bool_)
        self._state = GridArrays(self.succ, self.tgt_at, self.pos, self.visited, self.moves, self.counters, self._obs)

    def _load(self, i: int, rng: np.random.Generator) -> None:
        flat, robots, targets = draw_world_arrays(rng, self.source.params, self.source.fixed)
        self.grids[i] = flat
        self.targets[i] = targets
        grid_load(i, self.grids[i], self.width, robots, targets, self._state, self.field, self.dense_reward > 0)

    def _check_actions(self, actions, live: np.ndarray) -> np.ndarray:
        return check_joint_moves(actions, live, self.n_robots)

    def _step(self, actions: np.ndarray, live: np.ndarray):
        grid_step(actions, live, self._state, self.target_reward, self.grids, self.width, self.targets, self.field,
                  self.dense_reward, self._rewards, self._terminated)
        return self._rewards.copy(), self._terminated.copy()

    def _observe(self) -> np.ndarray:
        obs = self._obs.reshape(self.num_envs, 2 + self.n_robots, self.height, self.width)
        return to_image(obs) if self.observation_mode == "image" else obs

    def _info_arrays(self) -> dict:
        c = self.counters
        return {
            "route_cost": c[:, 1].copy(),
            "makespan": self.moves.max(axis=1),
            "steps": c[:, 0].copy(),
            "targets_visited": c[:, 2].copy(),
            "n_targets": np.full(self.num_envs, self.n_targets, dtype=np.int64),
            "is_success": c[:, 2] == self.n_targets,
            "invalid_moves": c[:, 3].copy(),
            "conflicts": c[:, 4] + c[:, 5],
            "vertex_conflicts": c[:, 4].copy(),
            "swap_conflicts": c[:, 5].copy(),
        }

    def action_masks(self) -> np.ndarray:
        """``(B, 5 * R)``: per env and robot, stay and the moves that are not blocked."""
        grid_masks(self.succ, self.pos, self._masks)
        return self._masks.copy()
