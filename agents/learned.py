"""Learned agents: training (stable-baselines3 / sb3-contrib) on the MRMT envs, and loading.

torch, stable-baselines3 and sb3-contrib are imported lazily (only when
training or loading); install them with the ``rl`` extra.

Two set-ups (choices and measurements: docs/design/learned-agents.md):

* plan level, ``mrmt_env/MRMT-Assign-v0`` (the default for a learned
  allocator): sb3-contrib ``MaskablePPO`` with
  :class:`agents.assign_net.AssignPointerPolicy` (distance-biased attention
  encoder, pointer head), ``gamma = 1`` (the return is minus the route
  cost), rewards scaled by ``1 / (H + W)``, the native vector env;
* grid level, ``mrmt_env/MRMT-v0``: SB3 ``PPO`` (``MlpPolicy``, SB3 defaults)
  or ``MaskablePPO`` with masks for blocked moves; ``CnnPolicy`` when the
  env's ``observation="image"``.

Every saved model has a ``.json`` sidecar (algorithm, policy, env id and
kwargs, seed, timesteps, training wall time) and, unless disabled, a training
curve (``.curve.csv`` and ``.curve.png``: mean return, success and route
cost of the episodes finished in each rollout).  :func:`load_policy` reads the
algorithm from the sidecar (or from the model file), so ``ppo:model.zip`` in
``mrmt compare`` loads a PPO or a MaskablePPO model alike (``ppo-ms:`` adds
multi-start decoding on the plan-level env: :mod:`agents.assign_search`); it
unpickles nothing from the file (docs/untrusted_files.md).

Compute accounting of a learned agent (:class:`LearnedPolicy`): latency =
measured inference wall time (``model.predict``) summed over the episode's
steps; energy = that time x 15 W (the classical planners' CPU proxy); no chip.
"""

from __future__ import annotations

import json
import os
import re
import time
import zipfile
from pathlib import Path

import numpy as np

from agents.env_ids import check_env_id as _spec
from agents.env_ids import is_assign_env
from agents.errors import ControllerError
from planners.compute import ComputeReport

__all__ = [
    "SMALL_ENV_ID", "ASSIGN_ENV_ID", "ALGORITHMS", "DEFAULT_TIMESTEPS", "train", "train_ppo", "LearnedPolicy",
    "load_policy", "sidecar_path", "curve_paths", "model_path", "is_assign_env", "MAX_MODEL_BYTES",
    "MAX_MODEL_UNPACKED", "MAX_SIDECAR_BYTES",
]

#: The small world registered for quick training.
SMALL_ENV_ID = "mrmt_env/MRMT-5x5-v0"
#: The plan-level env.
ASSIGN_ENV_ID = "mrmt_env/MRMT-Assign-v0"
#: Algorithms ``train`` knows.
ALGORITHMS = ("ppo", "maskable_ppo")
#: Default training budgets (env steps): the plan-level default finishes in
#: <= 10 minutes on a 2-core machine (benchmarks/RESULTS.md).
DEFAULT_TIMESTEPS = {"assign": 300_000, "grid": 100_000}

#: MaskablePPO settings for the plan-level env (see the module docstring).
ASSIGN_HYPER = dict(n_steps=128, batch_size=256, n_epochs=4, learning_rate=3e-4, lr_schedule="linear", gamma=1.0,
                    gae_lambda=0.95, ent_coef=0.01, clip_range=0.2)
ASSIGN_N_ENVS = 16


def model_path(out) -> Path:
    """The model file :func:`train` writes for ``out``: ``out`` itself if it ends in ``.zip``, else
    ``out`` with ``.zip`` appended (``m2`` -> ``m2.zip``, ``m.pt`` -> ``m.pt.zip``)."""
    p = Path(out)
    return p if p.suffix == ".zip" else p.with_name(p.name + ".zip")


def sidecar_path(model_path) -> Path:
    """Where :func:`train` writes the training config next to the model (``model.json``)."""
    p = Path(model_path)
    return p.with_name(p.name[: -len(".zip")] + ".json" if p.name.endswith(".zip") else p.name + ".json")


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


def train(
    env_id: str = "mrmt_env/MRMT-v0",
    timesteps: int | None = None,
    out=None,
    *,
    algo: str | None = None,
    policy: str | None = None,
    env_kwargs: dict | None = None,
    seed: int = 0,
    n_envs: int | None = None,
    verbose: int = 0,
    progress: bool = False,
    curve: bool = True,
    torch_threads: int | None = 1,
    callback=None,
    reward_scale: float | None = None,
    **algo_kwargs,
):
    """Train an agent on ``env_id`` for ``timesteps`` env steps; save to ``out`` if given.

    Args:
        env_id, env_kwargs: the env (a plan-level id gets MaskablePPO and the
            pointer policy, a grid id PPO unless ``algo`` says otherwise).
        timesteps: env steps (default :data:`DEFAULT_TIMESTEPS` for the kind).
        out: the model file to write (:func:`model_path`: ``.zip`` appended unless it ends so),
            with its ``.json`` sidecar and curve.
        algo: ``"ppo"`` or ``"maskable_ppo"``.
        policy: SB3 policy name (grid: default ``MlpPolicy``, ``CnnPolicy``
            for ``observation="image"``); ignored for the plan-level env.
        n_envs: envs stepped together (the id's native vector env; plan level
            default 16, grid default 1).
        torch_threads: ``torch.set_num_threads`` (default 1: the networks are
            small; ``None`` leaves torch's setting alone).
        callback: an extra SB3 callback.
        reward_scale: multiply the rewards the learner sees (default
            ``1 / (H + W)`` on the plan-level env, 1 on a grid env); the
            curve and ``info`` keep the env's own rewards.
        **algo_kwargs: override the algorithm's hyper-parameters.

    Returns:
        the trained model.
    """
    assign = is_assign_env(env_id)
    kind = "assign" if assign else "grid"
    timesteps = DEFAULT_TIMESTEPS[kind] if timesteps is None else timesteps
    if isinstance(timesteps, bool) or int(timesteps) != timesteps or timesteps < 1:
        raise ValueError(f"timesteps must be an integer >= 1, got {timesteps!r}")
    n_envs = (ASSIGN_N_ENVS if assign else 1) if n_envs is None else n_envs
    if isinstance(n_envs, bool) or int(n_envs) != n_envs or n_envs < 1:
        raise ValueError(f"n_envs must be an integer >= 1, got {n_envs!r}")
    algo = ("maskable_ppo" if assign else "ppo") if algo is None else algo
    if algo not in ALGORITHMS:
        raise ValueError(f"algo must be one of {ALGORITHMS}, got {algo!r}")
    if assign and algo != "maskable_ppo":
        raise ValueError(f"the plan-level env {env_id} needs action masks: algo must be 'maskable_ppo', got {algo!r}")
    timesteps, n_envs = int(timesteps), int(n_envs)
    env_kwargs = dict(env_kwargs or {})

    import gymnasium as gym
    import torch

    if torch_threads is not None:
        torch.set_num_threads(int(torch_threads))
    probe = gym.make(env_id, **env_kwargs)  # validates the id and kwargs with a clear error
    probe.close()
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
        from agents.assign_net import AssignPointerPolicy

        params = dict(ASSIGN_HYPER)
        params["n_steps"] = max(8, min(params["n_steps"], timesteps // n_envs))
        params["batch_size"] = min(params["batch_size"], params["n_steps"] * n_envs)
        policy_obj = AssignPointerPolicy
        policy_name = "AssignPointerPolicy"
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
    return train(env_id, timesteps, out, algo=algo, env_kwargs=env_kwargs, seed=seed, n_envs=n_envs,
                 verbose=verbose, progress=progress, torch_threads=torch_threads, **ppo_kwargs)


class LearnedPolicy:
    """A stable-baselines3 / sb3-contrib model as a controller for the evaluator.

    ``predict`` forwards to ``model.predict`` (with ``action_masks`` for a
    MaskablePPO model: :attr:`uses_action_masks`) and adds the measured wall
    time of the call to the episode's inference time (per env index; a
    batched call's time is split evenly between its envs).
    :meth:`episode_compute` reports it as ``ComputeReport(cpu_s=...)``.
    A model trained on image observations (``observation="image"``) gets the
    env's binary observation converted (:func:`mrmt_env.observation.to_image`).
    """

    def __init__(self, model, name: str = "ppo", seed: int = 0, meta: dict | None = None):
        self.model = model
        self.name = name
        self.seed = int(seed)
        self.meta = dict(meta or {})
        self._episode_s: dict[int, float] = {}
        self.total_inference_s = 0.0
        self.uses_action_masks = type(model).__name__ == "MaskablePPO"
        self.image = self.meta.get("env_kwargs", {}).get("observation") == "image"
        shape = getattr(getattr(model, "observation_space", None), "shape", None)
        self.observation_shape = tuple(shape) if shape is not None else None

    def reset(self) -> None:
        self._episode_s.clear()

    def _convert(self, obs: np.ndarray) -> np.ndarray:
        if not self.image or obs.dtype != np.uint8 or obs.shape[-3:] == self.observation_shape or obs.max(initial=0) > 1:
            return obs
        from mrmt_env.observation import to_image

        return to_image(obs)

    def _check(self, obs: np.ndarray) -> None:
        if self.observation_shape is None:
            return
        got = obs.shape[-len(self.observation_shape):]
        if obs.ndim not in (len(self.observation_shape), len(self.observation_shape) + 1) or got != self.observation_shape:
            raise ValueError(
                f"{self.name}: the model was trained on observations of shape {self.observation_shape} "
                f"but was given {obs.shape}; evaluate it on the env, world size and robot/target counts it was "
                f"trained on ({self.meta.get('env_id', 'see its .json sidecar')})"
            )

    def predict(self, observation, state=None, episode_start=None, deterministic: bool = True, action_masks=None):
        obs = self._convert(np.asarray(observation))
        self._check(obs)
        batched = self.observation_shape is not None and obs.ndim == len(self.observation_shape) + 1
        n = obs.shape[0] if batched else 1
        starts = np.zeros(n, dtype=bool) if episode_start is None else np.broadcast_to(np.asarray(episode_start, bool), (n,))
        for i in range(n):
            if starts[i] or i not in self._episode_s:
                self._episode_s[i] = 0.0
        kwargs = {"action_masks": action_masks} if self.uses_action_masks and action_masks is not None else {}
        t0 = time.perf_counter()
        action, state = self.model.predict(obs, state=state, episode_start=episode_start, deterministic=deterministic,
                                           **kwargs)
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


def _algo_name(algo: str) -> str:
    return {"ppo": "PPO", "maskable_ppo": "MaskablePPO"}[algo]


#: Largest model file :func:`load_policy` reads (bytes), and the most its zip entries may unpack to.
MAX_MODEL_BYTES = 256 * 2**20
MAX_MODEL_UNPACKED = 1024 * 2**20
#: Largest sidecar (``.json``) :func:`load_policy` reads (bytes).
MAX_SIDECAR_BYTES = 2**20
#: Pickled (cloudpickle) entries of an SB3 model's ``data`` and what the safe loader puts in their
#: place (never the file's objects): classes come from a fixed list, spaces from the env, and what
#: only training uses (schedules, buffers, the last rollout) gets a neutral value.
_REBUILT = ("policy_class", "observation_space", "action_space", "lr_schedule", "learning_rate", "clip_range",
            "clip_range_vf", "rollout_buffer_class", "_last_obs", "_last_episode_starts", "_last_original_obs",
            "ep_info_buffer", "ep_success_buffer", "action_noise")
#: ``data`` keys a model file may not set on the loaded model (SB3 would act on them: ``env`` is made
#: with ``gym.make``, which can import a module named in the id).
_DENIED = frozenset({"env", "policy", "device", "_vec_normalize_env", "replay_buffer", "rollout_buffer", "_logger",
                     "_custom_logger"})


def _zero_schedule(_progress: float) -> float:
    return 0.0


def _refuse(path: str, why: str) -> ControllerError:
    return ControllerError(f"refusing to load model {path!r}: {why}")


def _read_limited(path: str, limit: int, what: str) -> bytes:
    size = os.path.getsize(path)
    if size > limit:
        raise _refuse(path, f"{what} has {size} bytes; at most {limit} are read")
    with open(path, "rb") as fh:
        return fh.read(limit + 1)


def _sidecar(path: str) -> dict:
    side = sidecar_path(path)
    if not side.is_file():
        return {}
    try:
        meta = json.loads(_read_limited(str(side), MAX_SIDECAR_BYTES, f"its sidecar {side}").decode("utf-8"))
    except (ValueError, RecursionError) as exc:
        raise _refuse(path, f"its sidecar {side} is not JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise _refuse(path, f"its sidecar {side} must be a JSON object, got {type(meta).__name__}")
    return meta


def _policy_class(path: str, algo: str, meta: dict, data: dict):
    """The policy class, from a fixed list: the sidecar's name and/or the class the file names."""
    if algo == "maskable_ppo":
        from sb3_contrib import MaskablePPO as Algo

        from agents.assign_net import AssignPointerPolicy

        known = {**Algo.policy_aliases, "AssignPointerPolicy": AssignPointerPolicy}
    else:
        from stable_baselines3 import PPO as Algo

        known = dict(Algo.policy_aliases)
    by_class = {cls.__name__: cls for cls in known.values()}
    entry = data.get("policy_class")
    named = None
    if isinstance(entry, dict):  # the readable parts SB3 writes beside the pickle: method names give the class
        for value in entry.values():
            m = re.match(r"<function (\w+)\.\w+ at ", str(value))
            if m:
                named = m.group(1)
                break
        module = entry.get("__module__")
        if named is not None and named in by_class and module != by_class[named].__module__:
            raise _refuse(path, f"its policy class {named} names module {module!r}, not {by_class[named].__module__!r}")
    wanted = meta.get("policy")
    cls = None
    if wanted is not None:
        cls = known.get(wanted) or by_class.get(wanted)
        if cls is None:
            raise _refuse(path, f"policy {wanted!r} (sidecar) is not one of {sorted(known)}")
    if named is not None:
        if named not in by_class:
            raise _refuse(path, f"its policy class {named} is not one the safe loader builds ({sorted(by_class)})")
        if cls is not None and cls is not by_class[named]:
            raise _refuse(path, f"the sidecar says policy {wanted!r} but the file holds {named}")
        cls = by_class[named]
    if cls is None:
        raise _refuse(path, "neither a sidecar nor the file names its policy class")
    return cls


def _env_spaces(path: str, meta: dict, env_id, env_kwargs):
    """Observation and action spaces rebuilt from the env the model was trained on (sidecar first)."""
    import gymnasium as gym

    if meta.get("env_id") is not None:
        env_id, env_kwargs, where = meta["env_id"], meta.get("env_kwargs") or {}, "its sidecar"
    elif env_id is not None:
        env_kwargs, where = env_kwargs or {}, "the given env"
    else:
        raise _refuse(path, f"it has no sidecar {sidecar_path(path).name} naming its env, so its spaces could only "
                            "come from pickles in the file (which can run code); pass env_id= (the env it was "
                            "trained on) or write the sidecar")
    if not isinstance(env_id, str) or not env_id.startswith("mrmt_env/"):
        raise _refuse(path, f"{where} names env {env_id!r}; the safe loader builds only this package's "
                            "mrmt_env/ ids")
    if not isinstance(env_kwargs, dict) or any(
            not isinstance(k, str) or k == "world" or not isinstance(v, (bool, int, float, str, type(None)))
            for k, v in env_kwargs.items()):
        raise _refuse(path, f"{where}'s env_kwargs must map names to numbers or strings (no world), got "
                            f"{str(env_kwargs)[:120]}")
    try:
        _spec(env_id)
        env = gym.make(env_id, **env_kwargs)
    except (ValueError, TypeError) as exc:
        raise _refuse(path, f"cannot build its env {env_id} {env_kwargs}: {exc}") from None
    spaces = env.observation_space, env.action_space
    env.close()
    return spaces


def _check_spaces(path: str, data: dict, observation_space, action_space) -> None:
    """The rebuilt spaces must be the ones the file describes (its readable shape / dtype / n fields)."""
    for key, space in (("observation_space", observation_space), ("action_space", action_space)):
        entry = data.get(key)
        if not isinstance(entry, dict):
            continue
        got = {"_shape": str(list(space.shape)).replace(",", "").replace("[", "").replace("]", ""),
               "dtype": str(space.dtype)}
        if hasattr(space, "n"):
            got["n"] = str(int(space.n))
        for field, value in got.items():
            saved = entry.get(field)
            if field == "_shape" and saved is not None:
                saved = str(saved).replace(",", "").replace("[", "").replace("]", "").replace("(", "").replace(")", "")
                saved = " ".join(saved.split())
            if saved is not None and str(saved) != value:
                raise _refuse(path, f"the model's {key} has {field.strip('_')} {entry.get(field)} but its env gives "
                                    f"{space}; evaluate it on the env it was trained on")


def _check_policy_kwargs(path: str, value) -> None:
    def walk(v, depth=0):
        if depth > 8:
            raise _refuse(path, "policy_kwargs are nested too deeply")
        if isinstance(v, dict):
            for w in v.values():
                walk(w, depth + 1)
        elif isinstance(v, list):
            for w in v:
                walk(w, depth + 1)
        elif isinstance(v, bool) or v is None or isinstance(v, str):
            return
        elif isinstance(v, (int, float)):
            if not abs(v) <= 65536:
                raise _refuse(path, f"policy_kwargs hold the number {v}; a layer size or count is at most 65536")
        else:
            raise _refuse(path, f"policy_kwargs hold a {type(v).__name__}")

    if not isinstance(value, dict):
        raise _refuse(path, f"policy_kwargs must be a JSON object, got {type(value).__name__}")
    walk(value)


def _safe_custom_objects(path: str, Algo, algo: str, meta: dict, data: dict, env_id, env_kwargs) -> dict:
    import inspect

    serialized = sorted(k for k, v in data.items() if isinstance(v, dict) and ":serialized:" in v)
    unknown = [k for k in serialized if k not in _REBUILT]
    if unknown:
        raise _refuse(path, f"its data entry {unknown[0]!r} is a pickle (cloudpickle), which can run code; the safe "
                            f"loader rebuilds only {list(_REBUILT)}")
    for key in data:
        attr = inspect.getattr_static(Algo, key, None)
        if key in _DENIED or key.startswith("__") or callable(attr) or isinstance(attr, property):
            raise _refuse(path, f"its data entry {key!r} would replace the model's own {key!r}")
    if "policy_kwargs" in data:
        _check_policy_kwargs(path, data["policy_kwargs"])
    observation_space, action_space = _env_spaces(path, meta, env_id, env_kwargs)
    _check_spaces(path, data, observation_space, action_space)
    hyper = meta.get("hyper") if isinstance(meta.get("hyper"), dict) else {}
    clip = hyper.get("clip_range", 0.2)
    neutral = {
        "policy_class": _policy_class(path, algo, meta, data),
        "observation_space": observation_space,
        "action_space": action_space,
        "lr_schedule": _zero_schedule,
        "learning_rate": 0.0,
        "clip_range": float(clip) if isinstance(clip, (int, float)) and not isinstance(clip, bool) else 0.2,
        "clip_range_vf": None,
        "rollout_buffer_class": None,
    }
    custom = {k: neutral.get(k) for k in _REBUILT}  # the rest: None
    custom.update({"n_envs": 1, "n_steps": 1})  # no rollout buffer of the file's size (inference only)
    return custom


def _check_tensors(path: str, archive: zipfile.ZipFile) -> None:
    """Every ``.pth`` entry must load with ``torch.load(weights_only=True)``: tensors and plain
    containers only, no pickled code; ``pytorch_variables`` must be empty (PPO saves none)."""
    import io
    import pickle

    import torch

    for name in archive.namelist():
        if not name.endswith(".pth"):
            continue
        try:
            obj = torch.load(io.BytesIO(archive.read(name)), map_location="cpu", weights_only=True)
        except (pickle.UnpicklingError, RuntimeError, ValueError, EOFError, AttributeError, TypeError) as exc:
            first = " ".join(str(exc).split())[:200]
            raise _refuse(path, f"its entry {name!r} holds more than tensors (torch.load with weights_only=True "
                                f"refused it: {first})") from None
        if name in ("pytorch_variables.pth", "tensors.pth") and obj:
            raise _refuse(path, f"its entry {name!r} names variables {sorted(obj)[:5]}; PPO saves none")


def load_policy(path, seed: int = 0, torch_threads: int | None = 1, env_id: str | None = None,
                env_kwargs: dict | None = None) -> LearnedPolicy:
    """Load a model saved by :func:`train` (PPO or MaskablePPO) as a :class:`LearnedPolicy`, safely.

    A stable-baselines3 ``.zip`` stores classes, spaces and schedules as cloudpickle entries, and
    unpickling runs whatever code the file names.  This loader unpickles nothing from the file:

    * every pickled entry of ``data`` is replaced (SB3's ``custom_objects``) before SB3 could read
      it: the policy class from a fixed list (SB3's and sb3-contrib's actor-critic policies, the
      pointer policy of :mod:`agents.assign_net`), the observation and action spaces rebuilt from
      the env the sidecar names (or ``env_id`` / ``env_kwargs`` when there is no sidecar; only
      ``mrmt_env/`` ids) and checked against the shapes the file describes, and what only training
      uses (schedules, rollout buffer, last rollout) set to neutral values; a pickled entry of any
      other name is refused;
    * the weights (``*.pth``) must load with ``torch.load(weights_only=True)``;
    * files are size-limited (:data:`MAX_MODEL_BYTES`, :data:`MAX_MODEL_UNPACKED`,
      :data:`MAX_SIDECAR_BYTES`) and the zip is read from memory once.

    The loaded model acts exactly as SB3's own ``load`` would; it is meant for acting (its
    learning-rate schedule is not restored).  To continue training a model you trust, use
    ``PPO.load`` / ``MaskablePPO.load`` directly.

    ``torch_threads`` sets ``torch.set_num_threads`` for inference (default 1: one small forward
    pass per step gains nothing from more threads and the evaluator's workers would contend;
    ``None`` leaves torch alone).

    Raises:
        ControllerError: the file does not exist, is not a zip, the needed library is missing, it
            would need unpickling, or it cannot be loaded (the message says which).
    """
    import io

    path = str(path)
    if not os.path.isfile(path):
        raise ControllerError(f"model file {path!r} does not exist")
    raw = _read_limited(path, MAX_MODEL_BYTES, "the file")
    try:
        archive = zipfile.ZipFile(io.BytesIO(raw))
    except zipfile.BadZipFile:
        raise ControllerError(f"model file {path!r} is not a stable-baselines3 .zip model") from None
    with archive:
        unpacked = sum(i.file_size for i in archive.infolist())
        if unpacked > MAX_MODEL_UNPACKED:
            raise _refuse(path, f"its entries unpack to {unpacked} bytes; at most {MAX_MODEL_UNPACKED}")
        if "data" not in archive.namelist():
            raise ControllerError(f"model file {path!r} is not a stable-baselines3 .zip model (no 'data' entry)")
        try:
            text = archive.read("data").decode("utf-8")
            data = json.loads(text)
        except (ValueError, RecursionError) as exc:
            raise _refuse(path, f"its 'data' entry is not JSON ({' '.join(str(exc).split())[:120]})") from None
        if not isinstance(data, dict):
            raise _refuse(path, f"its 'data' entry must be a JSON object, got {type(data).__name__}")
        meta = _sidecar(path)
        algo = _algorithm_of(text, meta)
        try:
            if algo == "maskable_ppo":
                from sb3_contrib import MaskablePPO as Algo
            else:
                from stable_baselines3 import PPO as Algo
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ControllerError(f"loading a {_algo_name(algo)} model needs the rl extra: pip install "
                                  f"'mrmt-ising[rl]' ({exc})") from exc
        custom = _safe_custom_objects(path, Algo, algo, meta, data, env_id, env_kwargs)
        _check_tensors(path, archive)
    if torch_threads is not None:
        import torch

        torch.set_num_threads(int(torch_threads))
    try:
        model = Algo.load(io.BytesIO(raw), device="cpu", custom_objects=custom)
    except Exception as exc:  # SB3 raises many kinds for a bad archive
        first = " ".join(str(exc).split())[:300]
        raise ControllerError(f"cannot load {_algo_name(algo)} model {path!r}: {type(exc).__name__}: {first}") from exc
    return LearnedPolicy(model, name=f"ppo:{path}", seed=seed, meta=meta)


def _algorithm_of(data_text: str, meta: dict) -> str:
    if meta.get("algo") in ALGORITHMS:
        return meta["algo"]
    # no sidecar: the policy class the file names gives the algorithm
    return ("maskable_ppo" if ("sb3_contrib" in data_text or "Maskable" in data_text or "assign_net" in data_text)
            else "ppo")
