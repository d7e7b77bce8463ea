"""Controllers by spec string: pipeline presets, layer triples, saved learned models.

``fast`` / ``strong`` / ``ising`` / ``ising-paper`` / ``exact`` / ``pyvrp`` / ``ising-fleet`` / ``ortools`` (:func:`planners.pipeline.make_pipeline` presets), a layer
triple ``sharing+tour+path`` (e.g. ``ssa+3opt+astar``), ``ppo:PATH`` (a model saved by
``mrmt train``, loaded without unpickling anything from the file) or ``ppo-ms:PATH`` (the same
decoded from every legal first decision, plan-level env only).  :func:`make_controller` builds
one for an env id, on an emulated chip of a given spec when it has Ising layers.
"""

from __future__ import annotations

import os
import zipfile

from agents.errors import ControllerError

__all__ = [
    "DEFAULT_ENV_ID",
    "LEARNED_PREFIXES",
    "PIPELINE_PRESETS",
    "validate_controller_spec",
    "parse_controllers",
    "planner_pipeline",
    "uses_chip",
    "make_controller",
]

DEFAULT_ENV_ID = "mrmt_env/MRMT-v0"

#: Spec prefixes of learned models: a saved model, and the same decoded from every first decision
#: (plan-level env only; :mod:`agents.assign.search`).
LEARNED_PREFIXES = ("ppo:", "ppo-ms:")

#: Pipeline presets of :func:`planners.pipeline.make_pipeline`.
PIPELINE_PRESETS = ("fast", "strong", "ising", "ising-paper", "exact", "pyvrp", "ising-fleet", "ortools")


def _layer_names() -> dict[str, tuple[str, ...]]:
    from planners import registry

    return {layer: registry.names(layer) for layer in registry.LAYERS}


def validate_controller_spec(spec: str) -> str:
    """Check a controller spec without building it; return it normalised.

    Raises:
        ControllerError: an unknown name, a malformed layer triple, or a
            ``ppo:`` / ``ppo-ms:`` path that does not exist or is not a model zip file.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise ControllerError(f"controller spec must be a non-empty string, got {spec!r}")
    spec = spec.strip()
    prefix = next((p for p in LEARNED_PREFIXES if spec.startswith(p)), None)
    if prefix is not None:
        path = spec[len(prefix):]
        if not path:
            raise ControllerError(f"controller '{prefix}' needs a model path, e.g. {prefix}model.zip")
        if not os.path.isfile(path):
            raise ControllerError(f"PPO model file {path!r} does not exist")
        if not zipfile.is_zipfile(path):
            raise ControllerError(f"PPO model file {path!r} is not a stable-baselines3 .zip model")
        return spec
    if spec in PIPELINE_PRESETS:
        return spec
    if "+" in spec:
        parts = spec.split("+")
        if len(parts) != 3 or not all(parts):
            raise ControllerError(f"layer triple {spec!r} must be sharing+tour+path, e.g. ssa+3opt+astar")
        names = _layer_names()
        for layer, name in zip(("sharing", "tour", "path"), parts):
            known = names.get(layer)
            if known is not None and name not in known:
                raise ControllerError(
                    f"unknown {layer} method {name!r} in controller {spec!r}; known: {', '.join(known)}"
                )
        return spec
    raise ControllerError(
        f"unknown controller {spec!r}; expected one of {', '.join(PIPELINE_PRESETS)}, "
        "a layer triple sharing+tour+path (e.g. ssa+3opt+astar), ppo:PATH or ppo-ms:PATH"
    )


def parse_controllers(text: str) -> list[str]:
    """Split ``"fast,strong,ppo:model.zip"`` into validated specs (duplicates refused)."""
    specs = [validate_controller_spec(s) for s in str(text).split(",") if s.strip()]
    if not specs:
        raise ControllerError(f"no controller named in {text!r}")
    dup = {s for s in specs if specs.count(s) > 1}
    if dup:
        raise ControllerError(f"controller {sorted(dup)[0]!r} is listed twice")
    return specs


def planner_pipeline(spec: str, chip):
    """The pipeline a planner spec names, on the chip ``chip`` when given (a ``ChipSpec``: the emulator;
    a ``MachineSpec``: a sampler)
    (layers without a chip ignore it); ``None`` without a chip (the policy builds the preset)."""
    from planners.pipeline import make_pipeline

    shared = {}
    if chip is not None:
        from ising_backend import build_machine

        shared["chip"] = build_machine(chip)
    if "+" in spec:
        sharing, tour, path = spec.split("+")
        kw = dict(sharing=sharing, tour=tour, path=path)
    elif chip is None:
        return None
    else:
        kw = dict(preset=spec)
    try:
        return make_pipeline(**kw, **shared)
    except ValueError as exc:
        if shared and "accepted by no layer" in str(exc):  # a classical controller: no chip to use
            return make_pipeline(**kw)
        raise


def uses_chip(spec: str) -> bool:
    """Whether a planner spec (preset or layer triple) has a layer that runs on the chip."""
    from planners import registry
    from planners.pipeline import PRESETS

    if spec.startswith(("ppo:", "ppo-ms:")):
        return False
    layers = spec.split("+") if "+" in spec else PRESETS.get(spec, ())
    return any(registry.accepts(registry.get_factory(kind, name), "chip")
               for kind, name in zip(("sharing", "tour", "path"), layers))


def check_chip_use(specs, chip) -> None:
    """``ControllerError`` when a chip spec is given but none of the planner ``specs`` runs on a chip."""
    if chip is not None and not any(isinstance(s, str) and uses_chip(s) for s in specs):
        names = [s if isinstance(s, str) else s[0] for s in specs]
        raise ControllerError(f"a chip spec was given, but none of the controllers {names} runs on a chip "
                              "(add ising or a layer triple with an ising layer)")


def make_controller(spec: str, seed: int = 0, env_id: str | None = None, chip=None, env_kwargs: dict | None = None):
    """Build the controller a spec names (see :func:`validate_controller_spec`) for the env ``env_id``.

    Planners become :class:`agents.policy.PlannerPolicy` in a grid env and
    :class:`agents.assign.policy.AssignPlannerPolicy` in the plan-level env;
    ``ppo:PATH`` becomes :class:`agents.learned.training.LearnedPolicy` (PPO or
    MaskablePPO, as the model was trained).  Every controller has
    ``predict(obs, state, episode_start, deterministic)`` and
    ``episode_compute(index)``.  ``chip`` (an :class:`ising_backend.ChipSpec`) is the emulated
    chip of planners with Ising layers.
    ``env_id`` / ``env_kwargs`` also tell the safe model loader which env a model without a
    sidecar acts in (its spaces are rebuilt from it; nothing is unpickled from the file).
    """
    spec = validate_controller_spec(spec)
    from agents.env_ids import is_assign_env

    if spec.startswith("ppo:"):
        from agents.learned.training import load_policy

        return load_policy(spec[4:], seed=seed, env_id=env_id, env_kwargs=env_kwargs)
    if spec.startswith("ppo-ms:"):
        from agents.assign.search import MultiStartPolicy
        from agents.learned.training import load_policy

        if env_id is None or not is_assign_env(env_id):
            raise ControllerError(f"{spec!r}: multi-start decoding needs the plan-level env (mrmt_env/MRMT-Assign-v0)")
        try:
            return MultiStartPolicy(load_policy(spec[7:], seed=seed, env_id=env_id, env_kwargs=env_kwargs))
        except ValueError as exc:
            raise ControllerError(f"{spec!r}: {exc}") from None

    if env_id is not None and is_assign_env(env_id):
        from agents.assign.policy import AssignPlannerPolicy as Policy
    else:
        from agents.policy import PlannerPolicy as Policy

    pipe = planner_pipeline(spec, chip)
    if pipe is not None:
        policy = Policy(pipe, seed=seed)
        policy.name = spec
        return policy
    return Policy(spec, seed=seed)
