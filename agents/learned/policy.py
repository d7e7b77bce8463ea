"""Learned controllers from files: :class:`LearnedPolicy` and the safe loader :func:`load_policy`.

A model saved by ``mrmt train`` (PPO or MaskablePPO, a stable-baselines3 ``.zip`` with a ``.json``
sidecar) is loaded without unpickling anything from the file: sizes are limited, the spaces are
rebuilt from the env id, only known entries are read (docs/untrusted_files.md).  Compute
accounting: latency = measured inference wall time summed over the episode, energy = that time
x 15 W (the classical planners' CPU proxy); no chip.
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
from agents.errors import ControllerError
from planners.compute import ComputeReport

#: The algorithms a saved model may name (:func:`agents.learned.training.train` trains both).
ALGORITHMS = ("ppo", "maskable_ppo")

__all__ = ["ALGORITHMS", "LearnedPolicy", "load_policy", "sidecar_path", "MAX_MODEL_BYTES", "MAX_MODEL_UNPACKED", "MAX_SIDECAR_BYTES"]


def sidecar_path(model_path) -> Path:
    """Where :func:`train` writes the training config next to the model (``model.json``)."""
    p = Path(model_path)
    return p.with_name(p.name[: -len(".zip")] + ".json" if p.name.endswith(".zip") else p.name + ".json")



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

        from agents.assign.net import AssignPointerPolicy

        from agents.lifelong.net import LifelongTaskPolicy

        known = {**Algo.policy_aliases, "AssignPointerPolicy": AssignPointerPolicy,
                 "LifelongTaskPolicy": LifelongTaskPolicy}
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
    if meta.get("decision") == "lifelong-task":  # the task choice's spaces do not depend on the world
        from agents.env_ids import is_lifelong_env
        from agents.lifelong.choice import decision_spaces

        try:
            lifelong = is_lifelong_env(env_id)
        except ValueError as exc:
            raise _refuse(path, str(exc)) from None
        if not lifelong:
            raise _refuse(path, f"{where} names a lifelong task choice on {env_id!r}, which is not a lifelong id")
        return decision_spaces()
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
      pointer policy of :mod:`agents.assign.net`), the observation and action spaces rebuilt from
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
    return ("maskable_ppo" if ("sb3_contrib" in data_text or "Maskable" in data_text or "assign_net" in data_text
            or "assign.net" in data_text)
            else "ppo")
