"""A native gymnasium vector env seen as a stable-baselines3 ``VecEnv``.

SB3 steps its own ``VecEnv`` API: observations after an episode's end are
the next episode's first, the last one travels in
``infos[i]["terminal_observation"]``, and truncation is flagged by
``infos[i]["TimeLimit.truncated"]``.  That is gymnasium's ``SAME_STEP``
autoreset, so :class:`GymVecToSB3` builds the vector env in that mode and
translates.  ``env_method("action_masks")`` answers sb3-contrib's
``MaskablePPO`` from the vector env's batched ``action_masks()``.
"""

from __future__ import annotations

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvWrapper

__all__ = ["GymVecToSB3", "ScaleReward"]


class GymVecToSB3(VecEnv):
    """Wrap a gymnasium ``VectorEnv`` built with ``autoreset_mode="SameStep"``."""

    def __init__(self, venv, seed: int | None = None) -> None:
        from gymnasium.vector import AutoresetMode

        if venv.metadata.get("autoreset_mode") != AutoresetMode.SAME_STEP:
            raise ValueError(f"the vector env must use SAME_STEP autoreset, got {venv.metadata.get('autoreset_mode')}")
        self.venv = venv
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self._seed = seed
        self._actions = None
        self.render_mode = None

    def reset(self):
        obs, _ = self.venv.reset(seed=self._seed)
        self._seed = None  # later resets continue each env's generator
        return obs

    def step_async(self, actions) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self):
        obs, rewards, terminated, truncated, infos = self.venv.step(self._actions)
        dones = terminated | truncated
        out = [{} for _ in range(self.num_envs)]
        if dones.any():
            final_obs = infos["final_obs"]
            for i in np.flatnonzero(dones):
                out[i]["terminal_observation"] = final_obs[i]
                out[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
                fin = infos["final_info"]
                out[i]["is_success"] = bool(fin["is_success"][i])
                out[i]["route_cost"] = int(fin["route_cost"][i])
        return obs, rewards.astype(np.float32), dones, out

    def close(self) -> None:
        self.venv.close()

    def seed(self, seed=None):
        self._seed = seed
        return [None if seed is None else seed + i for i in range(self.num_envs)]

    def get_attr(self, attr_name, indices=None):
        return [getattr(self.venv, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name, value, indices=None) -> None:
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name, *method_args, indices=None, **method_kwargs):
        idx = list(self._get_indices(indices))
        if method_name == "action_masks":
            masks = self.venv.action_masks()
            return [masks[i] for i in idx]
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result for _ in idx]

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False for _ in self._get_indices(indices)]

    def get_images(self):
        return [None] * self.num_envs


class ScaleReward(VecEnvWrapper):
    """Multiply rewards by a constant (returns of order 1 keep the value loss in scale)."""

    def __init__(self, venv, scale: float) -> None:
        super().__init__(venv)
        self.scale = float(scale)

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        obs, rewards, dones, infos = self.venv.step_wait()
        return obs, rewards * self.scale, dones, infos
