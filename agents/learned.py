"""Learned agents: PPO (stable-baselines3) trained on the MRMT env, and its loader.

stable-baselines3 and torch are imported lazily (only when training or
loading), so the rest of the package never pays for them; install them with
the ``rl`` extra.

Choices the issue leaves open:

* Policy: ``MlpPolicy`` over the flattened ``(2 + R, H, W)`` 0/1 observation.
  SB3's ``CnnPolicy`` (NatureCNN) needs images of at least 36x36 pixels, and
  the observation's values are already 0/1, so no image normalisation is
  applied (SB3 does not treat a ``Box(0, 1)`` as an image).
* Action: the env's joint ``MultiDiscrete([5] * R)`` action, unchanged.
* Hyper-parameters: SB3's PPO defaults (``n_steps=2048``, ``batch_size=64``,
  ``lr=3e-4``, ``gamma=0.99``) except ``n_steps`` which is lowered when the
  run is shorter than one rollout, so a few hundred steps still train.
  ``device="cpu"`` always (the models are tiny).
* Worlds: a fresh random world at every ``reset`` (the env's default), so the
  agent must generalise across worlds; evaluation uses unseen world seeds.

Compute accounting of a learned agent (:class:`LearnedPolicy`): latency =
measured inference wall time (``model.predict``) summed over the episode's
steps; energy = that time x 15 W (the same CPU proxy as the classical
planners); no chip.
"""

from __future__ import annotations

import json
import os
import time
import zipfile
from pathlib import Path

import numpy as np

from agents.evaluation import ControllerError
from planners.compute import ComputeReport

__all__ = ["SMALL_ENV_ID", "train_ppo", "LearnedPolicy", "load_policy", "sidecar_path"]

#: The small world registered for quick training (falls back to MRMT-v0 with kwargs if absent).
SMALL_ENV_ID = "mrmt_env/MRMT-5x5-v0"


def sidecar_path(model_path) -> Path:
    """Where :func:`train_ppo` writes the training config next to the model (``model.json``)."""
    p = Path(model_path)
    return p.with_name(p.name[: -len(".zip")] + ".json" if p.name.endswith(".zip") else p.name + ".json")


def _make_env(env_id: str, env_kwargs: dict, seed: int):
    import gymnasium as gym

    import mrmt_env  # noqa: F401  (registers the ids)

    if env_id not in gym.registry:
        known = ", ".join(sorted(k for k in gym.registry if k.startswith("mrmt_env/")))
        raise ValueError(f"unknown env id {env_id!r}; registered: {known}")
    return gym.make(env_id, **env_kwargs)


def train_ppo(
    timesteps: int,
    out=None,
    env_id: str = "mrmt_env/MRMT-v0",
    env_kwargs: dict | None = None,
    seed: int = 0,
    n_envs: int = 1,
    verbose: int = 0,
    progress: bool = False,
    torch_threads: int | None = 1,
    **ppo_kwargs,
):
    """Train PPO on ``env_id`` for ``timesteps`` env steps; save to ``out`` if given.

    Args:
        timesteps: total environment steps (>= 1).
        out: path of the ``.zip`` to write (a ``.json`` sidecar records the
            env id, kwargs, seed, timesteps and training wall time).
        env_id, env_kwargs: the env to train on.
        seed: seeds PPO, torch and the envs.
        n_envs: parallel envs (``DummyVecEnv``: in-process).
        torch_threads: ``torch.set_num_threads`` for training (default 1: the
            networks are tiny and extra threads only contend for the cores;
            ``None`` leaves torch's setting alone).
        **ppo_kwargs: override PPO's hyper-parameters.

    Returns:
        the trained ``stable_baselines3.PPO`` model.
    """
    if int(timesteps) < 1:
        raise ValueError(f"timesteps must be >= 1, got {timesteps}")
    if int(n_envs) < 1:
        raise ValueError(f"n_envs must be >= 1, got {n_envs}")
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    if torch_threads is not None:
        torch.set_num_threads(int(torch_threads))
    env_kwargs = dict(env_kwargs or {})
    _make_env(env_id, env_kwargs, seed).close()  # validates the id and kwargs with a clear error
    venv = make_vec_env(env_id, n_envs=int(n_envs), seed=int(seed), env_kwargs=env_kwargs)
    params = dict(n_steps=2048, batch_size=64)
    rollout = max(16, min(2048, int(timesteps) // int(n_envs)))
    params["n_steps"] = rollout
    params["batch_size"] = min(64, rollout * int(n_envs))
    params.update(ppo_kwargs)
    model = PPO("MlpPolicy", venv, seed=int(seed), device="cpu", verbose=verbose, **params)
    t0 = time.perf_counter()
    model.learn(total_timesteps=int(timesteps), progress_bar=bool(progress))
    wall = time.perf_counter() - t0
    if out is not None:
        out = Path(out)
        out.parent.mkdir(parents=True, exist_ok=True)
        model.save(out)
        zpath = out if out.suffix == ".zip" else out.with_name(out.name + ".zip")
        meta = {
            "env_id": env_id,
            "env_kwargs": env_kwargs,
            "seed": int(seed),
            "timesteps": int(timesteps),
            "n_envs": int(n_envs),
            "train_wall_s": wall,
            "ppo": {k: v for k, v in params.items() if isinstance(v, (int, float, str, bool))},
        }
        sidecar_path(zpath).write_text(json.dumps(meta, indent=1))
    venv.close()
    return model


class LearnedPolicy:
    """A stable-baselines3 model as a controller for the evaluator.

    ``predict`` forwards to ``model.predict`` and adds the measured wall time
    of the call to the episode's inference time (per env index; a batched
    call's time is split evenly between its envs).
    :meth:`episode_compute` reports it as ``ComputeReport(cpu_s=...)``.
    """

    def __init__(self, model, name: str = "ppo", seed: int = 0):
        self.model = model
        self.name = name
        self.seed = int(seed)
        self._episode_s: dict[int, float] = {}
        self.total_inference_s = 0.0
        shape = getattr(getattr(model, "observation_space", None), "shape", None)
        self.observation_shape = tuple(shape) if shape is not None else None

    def reset(self) -> None:
        self._episode_s.clear()

    def _check(self, obs: np.ndarray) -> None:
        if self.observation_shape is None:
            return
        got = obs.shape[-len(self.observation_shape):]
        if obs.ndim not in (len(self.observation_shape), len(self.observation_shape) + 1) or got != self.observation_shape:
            raise ValueError(
                f"{self.name}: the model was trained on observations of shape {self.observation_shape} "
                f"but was given {obs.shape}; evaluate it on the same world size and robot count it was trained on"
            )

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True):
        obs = np.asarray(observation)
        self._check(obs)
        batched = self.observation_shape is not None and obs.ndim == len(self.observation_shape) + 1
        n = obs.shape[0] if batched else 1
        starts = np.zeros(n, dtype=bool) if episode_start is None else np.broadcast_to(np.asarray(episode_start, bool), (n,))
        for i in range(n):
            if starts[i] or i not in self._episode_s:
                self._episode_s[i] = 0.0
        t0 = time.perf_counter()
        action, state = self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic)
        dt = time.perf_counter() - t0
        self.total_inference_s += dt
        for i in range(n):
            self._episode_s[i] += dt / n
        return action, state

    __call__ = predict

    def episode_compute(self, index: int = 0) -> ComputeReport:
        """Inference time of env ``index``'s current episode as a compute report (CPU only)."""
        return ComputeReport(cpu_s=self._episode_s.get(index, 0.0))

    def __repr__(self) -> str:
        return f"LearnedPolicy({self.name!r})"


def load_policy(path, seed: int = 0) -> LearnedPolicy:
    """Load a saved PPO ``.zip`` as a :class:`LearnedPolicy`.

    Raises:
        ControllerError: the file does not exist, is not a zip, or
            stable-baselines3 cannot load it as a PPO model.
    """
    path = str(path)
    if not os.path.isfile(path):
        raise ControllerError(f"PPO model file {path!r} does not exist")
    if not zipfile.is_zipfile(path):
        raise ControllerError(f"PPO model file {path!r} is not a stable-baselines3 .zip model")
    try:
        from stable_baselines3 import PPO
    except ImportError as exc:  # pragma: no cover - depends on the install
        raise ControllerError("loading a PPO model needs stable-baselines3: pip install 'mrmt-ising[rl]'") from exc
    try:
        model = PPO.load(path, device="cpu")
    except Exception as exc:  # SB3 raises many kinds for a bad archive
        raise ControllerError(f"cannot load PPO model {path!r}: {type(exc).__name__}: {exc}") from exc
    return LearnedPolicy(model, name=f"ppo:{path}", seed=seed)
