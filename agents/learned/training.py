"""Learned agents: training (stable-baselines3 / sb3-contrib) on the MRMT envs, and loading.

torch, stable-baselines3 and sb3-contrib are imported lazily (the ``rl`` extra). Plan level (``MRMT-Assign-v0``):
MaskablePPO with :class:`agents.assign.net.AssignPointerPolicy`; grid level (``MRMT-v0``): PPO or MaskablePPO.
A saved model has a ``.json`` sidecar and a training curve; :func:`load_policy` (from :mod:`agents.learned.policy`,
re-exported here) unpickles nothing. Design notes: docs/design/learned-agents.md#training-and-loading.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from agents.env_ids import check_env_id as _spec
from agents.env_ids import is_assign_env, is_lifelong_env
from agents.learned.policy import (ALGORITHMS, MAX_MODEL_BYTES, MAX_MODEL_UNPACKED, MAX_SIDECAR_BYTES, LearnedPolicy,
                                    load_policy, sidecar_path)

__all__ = [
    "SMALL_ENV_ID", "ASSIGN_ENV_ID", "ALGORITHMS", "DEFAULT_TIMESTEPS", "TrainOptions", "train", "train_ppo",
    "LearnedPolicy",
    "load_policy", "sidecar_path", "curve_paths", "model_path", "is_assign_env", "MAX_MODEL_BYTES",
    "MAX_MODEL_UNPACKED", "MAX_SIDECAR_BYTES",
]

#: The small world registered for quick training.
SMALL_ENV_ID = "mrmt_env/MRMT-5x5-v0"
#: The plan-level env.
ASSIGN_ENV_ID = "mrmt_env/MRMT-Assign-v0"
#: Default training budgets (env steps): the plan-level default finishes in
#: <= 10 minutes on a 2-core machine (benchmarks/RESULTS.md).
DEFAULT_TIMESTEPS = {"assign": 300_000, "grid": 100_000, "lifelong": 100_000}

#: MaskablePPO settings for the plan-level env (see the module docstring).
ASSIGN_HYPER = dict(n_steps=128, batch_size=256, n_epochs=4, learning_rate=3e-4, lr_schedule="linear", gamma=1.0,
                    gae_lambda=0.95, ent_coef=0.01, clip_range=0.2)
ASSIGN_N_ENVS = 16
#: MaskablePPO settings for the lifelong task choice (agents.lifelong.learned): one step per decision,
#: differential reward (tasks served minus the episode's rate times the steps; agents.lifelong.learned).
LIFELONG_HYPER = dict(n_steps=256, batch_size=256, n_epochs=4, learning_rate=3e-4, lr_schedule="linear", gamma=0.99,
                      gae_lambda=0.95, ent_coef=0.01, clip_range=0.2)
LIFELONG_N_ENVS = 4


def model_path(out) -> Path:
    """The model file :func:`train` writes for ``out``: ``out`` itself if it ends in ``.zip``, else
    ``out`` with ``.zip`` appended (``m2`` -> ``m2.zip``, ``m.pt`` -> ``m.pt.zip``)."""
    p = Path(out)
    return p if p.suffix == ".zip" else p.with_name(p.name + ".zip")


def curve_paths(model_path) -> tuple[Path, Path]:
    """The training curve files next to the model: ``model.curve.csv`` and ``model.curve.png``."""
    stem = sidecar_path(model_path).with_suffix("")
    return stem.with_name(stem.name + ".curve.csv"), stem.with_name(stem.name + ".curve.png")


def _vec_env(env_id: str, env_kwargs: dict, n_envs: int, seed: int):
    """An SB3 VecEnv: the id's native vector env (SAME_STEP autoreset) when it has one, else DummyVecEnv."""
    import gymnasium as gym
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import VecMonitor

    from agents.sb3_vec import GymVecToSB3

    spec = _spec(env_id)
    if spec.vector_entry_point is None:
        return make_vec_env(env_id, n_envs=n_envs, seed=seed, env_kwargs=env_kwargs)
    venv = gym.make_vec(env_id, num_envs=n_envs, vectorization_mode="vector_entry_point",
                        autoreset_mode="SameStep", **env_kwargs)
    return VecMonitor(GymVecToSB3(venv, seed=seed))


def _curve_callback():
    from stable_baselines3.common.callbacks import BaseCallback

    class CurveCallback(BaseCallback):
        """Per rollout: env steps, episodes, mean return, success rate and mean route cost of finished episodes."""

        def __init__(self):
            super().__init__()
            self.rows: list[dict] = []
            self._ret, self._succ, self._cost = [], [], []

        def _on_step(self) -> bool:
            for done, info in zip(self.locals["dones"], self.locals["infos"]):
                if done and "episode" in info:
                    self._ret.append(float(info["episode"]["r"]))
                    self._succ.append(bool(info.get("is_success", False)))
                    if info.get("is_success") and "route_cost" in info:
                        self._cost.append(float(info["route_cost"]))
            return True

        def _on_rollout_end(self) -> None:
            if self._ret:
                self.rows.append({
                    "timesteps": int(self.num_timesteps), "episodes": len(self._ret),
                    "mean_return": float(np.mean(self._ret)), "success_rate": float(np.mean(self._succ)),
                    "mean_route_cost": float(np.mean(self._cost)) if self._cost else float("nan"),
                })
            self._ret, self._succ, self._cost = [], [], []

    return CurveCallback()


def _write_curve(rows: list[dict], model_path, title: str) -> None:
    import csv

    csv_path, png_path = curve_paths(model_path)
    with open(csv_path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=["timesteps", "episodes", "mean_return", "success_rate", "mean_route_cost"])
        w.writeheader()
        w.writerows(rows)
    if not rows:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import EngFormatter

    t = [r["timesteps"] for r in rows]
    fig, axes = plt.subplots(1, 3, figsize=(12, 3.2))
    for ax, key, label in zip(axes, ("mean_return", "success_rate", "mean_route_cost"),
                              ("mean episode return", "success rate", "route cost (successful episodes)")):
        ax.plot(t, [r[key] for r in rows])
        ax.xaxis.set_major_formatter(EngFormatter(sep=""))
        ax.set_xlabel("env steps")
        ax.set_title(label, fontsize=9)
        ax.grid(alpha=0.3)
    axes[1].set_ylim(-0.02, 1.02)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(png_path, dpi=100)
    plt.close(fig)


@dataclass(frozen=True)
class TrainOptions:
    """How :func:`train` trains, apart from the env, the budget, the output and the hyper-parameters.

    Attributes:
        algo: ``"ppo"`` or ``"maskable_ppo"`` (default: MaskablePPO on a plan-level or lifelong env,
            PPO on a grid env).
        policy: SB3 policy name (grid: default ``MlpPolicy``, ``CnnPolicy``
            for ``observation="image"``); ignored for the plan-level env.
        seed: the training seed.
        n_envs: envs stepped together (the id's native vector env; plan level
            default 16, lifelong 4, grid 1).
        verbose: SB3's verbosity.
        progress: SB3's progress bar.
        curve: write the training curve next to the model.
        torch_threads: ``torch.set_num_threads`` (default 1: the networks are
            small; ``None`` leaves torch's setting alone).
        reward_scale: multiply the rewards the learner sees (default
            ``1 / (H + W)`` on the plan-level env, 1 on a grid env); the
            curve and ``info`` keep the env's own rewards.
    """

    algo: str | None = None
    policy: str | None = None
    seed: int = 0
    n_envs: int | None = None
    verbose: int = 0
    progress: bool = False
    curve: bool = True
    torch_threads: int | None = 1
    reward_scale: float | None = None


_OPTION_NAMES = frozenset(f.name for f in fields(TrainOptions))


def _logger(verbose: int):
    """SB3's logger for a training run: its table on stdout when ``verbose``, and no files.  (Without one, SB3
    makes a ``SB3-<date>`` folder in the system's temporary directory at every ``learn`` and leaves it.)"""
    import sys

    from stable_baselines3.common.logger import HumanOutputFormat, Logger

    return Logger(folder=None, output_formats=[HumanOutputFormat(sys.stdout)] if verbose else [])


def train(
    env_id: str = "mrmt_env/MRMT-v0",
    timesteps: int | None = None,
    out=None,
    *,
    options: TrainOptions | None = None,
    env_kwargs: dict | None = None,
    callback=None,
    **algo_kwargs,
):
    """Train an agent on ``env_id`` for ``timesteps`` env steps; save to ``out`` if given.

    Args:
        env_id, env_kwargs: the env (a plan-level id gets MaskablePPO and the
            pointer policy, a grid id PPO unless ``options.algo`` says otherwise).
        timesteps: env steps (default :data:`DEFAULT_TIMESTEPS` for the kind).
        out: the model file to write (:func:`model_path`: ``.zip`` appended unless it ends so),
            with its ``.json`` sidecar and curve.
        options: :class:`TrainOptions` (algorithm, policy, seed, envs, output, threads, reward
            scale); default ``TrainOptions()``.
        callback: an extra SB3 callback.
        **algo_kwargs: override the algorithm's hyper-parameters.

    Returns:
        the trained model.
    """
    options = TrainOptions() if options is None else options
    if not isinstance(options, TrainOptions):
        raise TypeError(f"options must be an agents.learned.training.TrainOptions, got {type(options).__name__}")
    moved = sorted(_OPTION_NAMES & algo_kwargs.keys())
    if moved:
        raise TypeError(f"train() got {', '.join(moved)} as keywords: pass them as "
                        f"options=TrainOptions({', '.join(f'{k}=...' for k in moved)})")
    algo, policy, seed, n_envs = options.algo, options.policy, options.seed, options.n_envs
    verbose, progress, curve = options.verbose, options.progress, options.curve
    torch_threads, reward_scale = options.torch_threads, options.reward_scale
    assign = is_assign_env(env_id)
    lifelong = is_lifelong_env(env_id)
    kind = "assign" if assign else "lifelong" if lifelong else "grid"
    timesteps = DEFAULT_TIMESTEPS[kind] if timesteps is None else timesteps
    if isinstance(timesteps, bool) or int(timesteps) != timesteps or timesteps < 1:
        raise ValueError(f"timesteps must be an integer >= 1, got {timesteps!r}")
    n_envs = {"assign": ASSIGN_N_ENVS, "lifelong": LIFELONG_N_ENVS}.get(kind, 1) if n_envs is None else n_envs
    if isinstance(n_envs, bool) or int(n_envs) != n_envs or n_envs < 1:
        raise ValueError(f"n_envs must be an integer >= 1, got {n_envs!r}")
    algo = ("maskable_ppo" if assign or lifelong else "ppo") if algo is None else algo
    if algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {ALGORITHMS}, got {algo!r}")
    if (assign or lifelong) and algo != "maskable_ppo":
        what = "plan-level" if assign else "lifelong"
        raise ValueError(f"the {what} env {env_id} needs action masks: algo must be 'maskable_ppo', got {algo!r}")
    timesteps, n_envs = int(timesteps), int(n_envs)
    env_kwargs = dict(env_kwargs or {})

    import gymnasium as gym
    import torch

    if torch_threads is not None:
        torch.set_num_threads(int(torch_threads))
    probe = gym.make(env_id, **env_kwargs)  # validates the id and kwargs with a clear error
    probe.close()
    if lifelong:
        from agents.lifelong.learned import decision_vec_env

        venv = decision_vec_env(env_id, env_kwargs, n_envs, int(seed))
    else:
        venv = _vec_env(env_id, env_kwargs, n_envs, int(seed))
    world_h, world_w = probe.unwrapped.source.height, probe.unwrapped.source.width
    if reward_scale is None:
        reward_scale = 1.0 / (world_h + world_w) if assign else 1.0
    if not (np.isfinite(reward_scale) and reward_scale > 0):
        raise ValueError(f"reward_scale must be a finite number > 0, got {reward_scale!r}")
    if reward_scale != 1.0:
        from agents.sb3_vec import ScaleReward

        venv = ScaleReward(venv, float(reward_scale))
    if assign:
        from agents.assign.net import AssignPointerPolicy

        params = dict(ASSIGN_HYPER)
        params["n_steps"] = max(8, min(params["n_steps"], timesteps // n_envs))
        params["batch_size"] = min(params["batch_size"], params["n_steps"] * n_envs)
        policy_obj = AssignPointerPolicy
        policy_name = "AssignPointerPolicy"
    elif lifelong:
        params = dict(LIFELONG_HYPER)
        params["n_steps"] = max(8, min(params["n_steps"], timesteps // n_envs))
        params["batch_size"] = min(params["batch_size"], params["n_steps"] * n_envs)
        from agents.lifelong.net import LifelongTaskPolicy

        policy_obj, policy_name = LifelongTaskPolicy, "LifelongTaskPolicy"
    else:
        image = env_kwargs.get("observation") == "image"
        policy_name = policy or ("CnnPolicy" if image else "MlpPolicy")
        policy_obj = policy_name
        rollout = max(16, min(2048, timesteps // n_envs))
        params = dict(n_steps=rollout, batch_size=min(64, rollout * n_envs))
    params.update(algo_kwargs)
    schedule = params.pop("lr_schedule", "constant")
    if schedule not in ("constant", "linear"):
        raise ValueError(f"lr_schedule must be 'constant' or 'linear', got {schedule!r}")
    hyper = {k: v for k, v in params.items() if isinstance(v, (int, float, str, bool))}
    hyper["lr_schedule"] = schedule
    if schedule == "linear":  # from learning_rate down to 0 at the end of training
        from stable_baselines3.common.utils import LinearSchedule

        params["learning_rate"] = LinearSchedule(float(params["learning_rate"]), 0.0, 1.0)
    if algo == "maskable_ppo":
        from sb3_contrib import MaskablePPO as Algo
    else:
        from stable_baselines3 import PPO as Algo
    model = Algo(policy_obj, venv, seed=int(seed), device="cpu", verbose=verbose, **params)
    model.set_logger(_logger(verbose))
    curve_cb = _curve_callback() if curve and out is not None else None
    callbacks = [c for c in (curve_cb, callback) if c is not None]
    t0 = time.perf_counter()
    model.learn(total_timesteps=timesteps, progress_bar=bool(progress), callback=callbacks or None)
    wall = time.perf_counter() - t0
    if out is not None:
        zpath = model_path(out)
        zpath.parent.mkdir(parents=True, exist_ok=True)
        model.save(zpath)
        meta = {
            "algo": algo,
            "policy": policy_name,
            "env_id": env_id,
            "env_kwargs": env_kwargs,
            "seed": int(seed),
            "timesteps": timesteps,
            "n_envs": n_envs,
            "reward_scale": float(reward_scale),
            "train_wall_s": wall,
            "hyper": hyper,
        }
        if lifelong:
            meta["decision"] = "lifelong-task"
        sidecar_path(zpath).write_text(json.dumps(meta, indent=1))
        if curve_cb is not None:
            _write_curve(curve_cb.rows, zpath, f"{algo} {policy_name} on {env_id}, {timesteps} steps")
    venv.close()
    return model


def train_ppo(timesteps: int, out=None, env_id: str = "mrmt_env/MRMT-v0", env_kwargs: dict | None = None,
              seed: int = 0, n_envs: int = 1, verbose: int = 0, progress: bool = False,
              torch_threads: int | None = 1, **ppo_kwargs):
    """PPO on a grid env (kept for existing callers): :func:`train` with ``algo="ppo"`` unless the env needs masks."""
    algo = "maskable_ppo" if is_assign_env(env_id) else "ppo"
    given = {k: ppo_kwargs.pop(k) for k in ("policy", "curve", "reward_scale") if k in ppo_kwargs}  # train()'s own
    options = TrainOptions(algo=algo, seed=seed, n_envs=n_envs, verbose=verbose, progress=progress,
                           torch_threads=torch_threads, **given)
    return train(env_id, timesteps, out, options=options, env_kwargs=env_kwargs, **ppo_kwargs)
