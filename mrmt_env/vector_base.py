"""Shared machinery of the native (batched) vector envs: seeding, autoreset, infos.

A subclass holds ``B`` episodes in arrays and implements ``_load(i, rng)``, ``_step(actions)``, ``_observe()`` and
``_info_arrays()``; its batches are those of ``gymnasium.vector.SyncVectorEnv`` over the registered single env
for the same seeds and actions. Design notes: docs/design/envs.md#native-vector-envs,
docs/design/learned-agents.md#3-native-vector-envs.
"""

from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from mrmt_env.config import EnvConfig
from mrmt_env.core import N_ACTIONS, check_step_limit, show

__all__ = ["BatchedVectorEnv", "check_joint_moves"]


def check_joint_moves(actions, live: np.ndarray, n_robots: int) -> np.ndarray:
    """``(B, R)`` joint moves of a batch of robot envs as contiguous int64 (ignored envs' moves 0), or a
    ``ValueError`` that names the first bad env and robot."""
    shape = (live.shape[0], n_robots)
    try:
        a = np.asarray(actions)
    except (TypeError, ValueError):
        raise ValueError(f"actions must be integers 0..{N_ACTIONS - 1} of shape {shape}, got {show(actions)}") \
            from None
    if a.shape != shape or a.dtype.kind not in "iu":
        raise ValueError(f"actions must be integers 0..{N_ACTIONS - 1} of shape {shape}, got {a.dtype} "
                         f"shape {a.shape}")
    if a.dtype == np.int64 and a.flags.c_contiguous and a.min() >= 0 and a.max() < N_ACTIONS:
        return a  # the common case; an ignored env's action never matters
    bad = live[:, None] & ((a < 0) | (a >= N_ACTIONS))
    if bad.any():
        b, k = (int(v) for v in np.argwhere(bad)[0])
        raise ValueError(f"action for env {b} robot {k} is {int(a[b, k])}; valid moves are 0..{N_ACTIONS - 1} "
                         "(0 stay, 1 up, 2 down, 3 left, 4 right)")
    return np.ascontiguousarray(np.where(live[:, None], a, 0), dtype=np.int64)


class BatchedVectorEnv(VectorEnv):
    """Base class: see the module docstring."""

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int, config, render_mode, autoreset_mode, copy: bool, options: dict) -> None:
        """The subclasses' common arguments: ``config`` and ``options`` as the single env's (its
        ``config_options``), read into ``self.config``; no rendering."""
        if render_mode is not None:
            raise ValueError(f"the vector env does not render (render_mode={render_mode!r}); render a single env")
        self.config = EnvConfig.of(config, takes=self.config_options, env=type(self).__name__, **options)
        max_episode_steps = self.config.max_episode_steps
        if isinstance(num_envs, bool) or int(num_envs) != num_envs or num_envs < 1:
            raise ValueError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            valid = [m.value for m in AutoresetMode]
            raise ValueError(f"autoreset_mode must be one of {valid}, got {autoreset_mode!r}") from None
        self.num_envs = int(num_envs)
        self.max_episode_steps = check_step_limit(max_episode_steps)
        self.autoreset_mode = mode
        self.metadata = {**type(self).metadata, "autoreset_mode": mode}
        self.copy = bool(copy)
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._elapsed = np.zeros(self.num_envs, dtype=np.int64)
        self._autoreset = np.zeros(self.num_envs, dtype=np.bool_)
        self._started = False

    # ----------------------------------------------------------- subclass API
    def _load(self, i: int, rng: np.random.Generator) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _step(self, actions: np.ndarray, live: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover
        raise NotImplementedError

    def _check_actions(self, actions, live: np.ndarray) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def _observe(self) -> np.ndarray:  # pragma: no cover
        raise NotImplementedError

    def _info_arrays(self) -> dict:  # pragma: no cover
        raise NotImplementedError

    # ---------------------------------------------------------------- resets
    def _seeds(self, seed) -> list:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
            if seed < 0:
                raise ValueError(f"seed must be >= 0, got {seed}")
            return [int(seed) + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(f"seed list has {len(seeds)} seeds; this vector env has {self.num_envs} envs")
        return seeds

    def _reset_env(self, i: int, seed) -> None:
        if seed is not None or self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random(seed)
        self._load(i, self._rngs[i])
        self._elapsed[i] = 0
        self._autoreset[i] = False

    def reset(self, *, seed=None, options: dict | None = None):
        seeds = self._seeds(seed)
        mask = None if not options or "reset_mask" not in options else np.asarray(options["reset_mask"], dtype=bool)
        if mask is not None and mask.shape != (self.num_envs,):
            raise ValueError(f"options['reset_mask'] must have shape ({self.num_envs},), got {mask.shape}")
        for i in range(self.num_envs):
            if mask is None or mask[i]:
                self._reset_env(i, seeds[i])
        self._started = True
        obs = self._observe()
        return (obs.copy() if self.copy else obs), self._infos(np.ones(self.num_envs, dtype=bool))

    # ------------------------------------------------------------------ step
    def step(self, actions):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        n = self.num_envs
        mode = self.autoreset_mode
        resetting = self._autoreset.copy() if mode == AutoresetMode.NEXT_STEP else np.zeros(n, dtype=bool)
        if mode == AutoresetMode.DISABLED and self._autoreset.any():
            i = int(np.flatnonzero(self._autoreset)[0])
            raise RuntimeError(f"env {i}'s episode is over; reset it with reset(options={{'reset_mask': mask}})")
        live = ~resetting
        all_live = not resetting.any()
        acts = self._check_actions(actions, live)
        rewards, terminated = self._step(acts, live)
        if not all_live:
            rewards[resetting] = 0.0
            terminated[resetting] = False
        self._elapsed += live
        if self.max_episode_steps is not None:
            truncated = live & (self._elapsed >= self.max_episode_steps)
        else:
            truncated = np.zeros(n, dtype=bool)
        for i in np.flatnonzero(resetting):
            self._reset_env(int(i), None)
        done = terminated | truncated
        infos = self._infos(np.ones(n, dtype=bool))
        if mode == AutoresetMode.SAME_STEP and done.any():
            final_obs = np.full(n, None, dtype=object)
            obs_now = self._observe()
            for i in np.flatnonzero(done):
                final_obs[i] = obs_now[i].copy()
            final_info = self._infos(done)
            for i in np.flatnonzero(done):
                self._reset_env(int(i), None)
            infos = self._infos(np.ones(n, dtype=bool))
            infos["final_obs"], infos["_final_obs"] = final_obs, done.copy()
            infos["final_info"], infos["_final_info"] = final_info, done.copy()
        self._autoreset = done.copy()
        obs = self._observe()
        return (obs.copy() if self.copy else obs), rewards, terminated, truncated, infos

    def _infos(self, mask: np.ndarray) -> dict:
        out = {}
        full = mask.all()
        shared = mask.copy()  # one "_key" mask array shared by every key of this info dict
        for key, arr in self._info_arrays().items():
            if not full:
                arr = np.where(mask.reshape((-1,) + (1,) * (arr.ndim - 1)), arr, np.zeros_like(arr))
            out[key] = arr
            out["_" + key] = shared
        return out

    def close_extras(self, **kwargs) -> None:
        pass
