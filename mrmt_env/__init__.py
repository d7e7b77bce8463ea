"""Grid worlds for multi-robot multi-target planning (world model, envs, metrics).

Importing the package registers the Gymnasium ids in :data:`GYM_IDS` (grid
level, ``gymnasium.make("mrmt_env/MRMT-v0")``) and :data:`ASSIGN_IDS` (plan
level, ``mrmt_env/MRMT-Assign-v0``), each with a native vector env
(``gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")``)
and, when the installed PettingZoo has a registry, the PettingZoo ids
``mrmt_env/mrmt_v0`` (AEC and parallel) and ``mrmt_env/mrmt_assign_v0`` (AEC).
"""

from mrmt_env.distances import MOVES, UNREACHABLE, bfs_distance_field, bfs_distance_fields
from mrmt_env.generation import generate_world
from mrmt_env.world import World, WorldError

__all__ = [
    "World",
    "WorldError",
    "generate_world",
    "bfs_distance_field",
    "bfs_distance_fields",
    "UNREACHABLE",
    "MOVES",
    "MRMTEnv",
    "MRMTParallelEnv",
    "parallel_env",
    "env",
    "world_from_observation",
    "action_between",
    "actions_from_path",
    "ACTION_NAMES",
    "GYM_IDS",
    "ASSIGN_IDS",
    "MRMTAssignEnv",
    "assign_aec_env",
    "MRMTAssignAECEnv",
]

#: Registered Gymnasium ids -> (kwargs, max_episode_steps).
GYM_IDS = {
    # no kwargs: the class defaults are the paper's set-up (10x10, density 0.2,
    # 3 robots, 10 targets, uniform placement), so gym.make(id, world=...) also
    # accepts a fixed world of any size
    "mrmt_env/MRMT-v0": ({}, 200),
    "mrmt_env/MRMT-Centre-v0": (dict(placement="centre"), 200),  # the paper's set-up with centre spawn
    "mrmt_env/MRMT-5x5-v0": (
        dict(height=5, width=5, obstacle_density=0.04, n_robots=2, n_targets=3, placement="uniform"),
        50,
    ),
}

#: Registered plan-level (Assign) ids -> (kwargs, max_episode_steps).
ASSIGN_IDS = {
    "mrmt_env/MRMT-Assign-v0": ({}, 200),  # the paper's set-up; a masked agent needs <= N + R steps
}


def _register() -> None:
    import gymnasium

    for ids, entry, vector in (
        (GYM_IDS, "mrmt_env.gym_env:MRMTEnv", "mrmt_env.grid_vector:MRMTVectorEnv"),
        (ASSIGN_IDS, "mrmt_env.assign_env:MRMTAssignEnv", "mrmt_env.assign_vector:MRMTAssignVectorEnv"),
    ):
        for env_id, (kwargs, steps) in ids.items():
            if env_id not in gymnasium.registry:
                # the passive env checker stays enabled (gymnasium's default)
                gymnasium.register(id=env_id, entry_point=entry, vector_entry_point=vector, kwargs=kwargs,
                                   max_episode_steps=steps)
    try:
        from pettingzoo.env_registry.registration import aec_registry, parallel_registry, register
    except ImportError:  # older PettingZoo: no registry
        return
    if "mrmt_env/mrmt_v0" not in aec_registry:
        register("aec", "mrmt_env/mrmt_v0", entry_point="mrmt_env.pz_env:env")
    if "mrmt_env/mrmt_v0" not in parallel_registry:
        register("parallel", "mrmt_env/mrmt_v0", entry_point="mrmt_env.pz_env:parallel_env")
    if "mrmt_env/mrmt_assign_v0" not in aec_registry:
        register("aec", "mrmt_env/mrmt_assign_v0", entry_point="mrmt_env.assign_pz:assign_aec_env")


_register()

#: Public names loaded on first use (PEP 562), so importing the world model --
#: as the planners do -- does not import the env classes.
_LAZY = {
    "ACTION_NAMES": "mrmt_env.core",
    "action_between": "mrmt_env.core",
    "actions_from_path": "mrmt_env.core",
    "MRMTEnv": "mrmt_env.gym_env",
    "world_from_observation": "mrmt_env.observation",
    "MRMTParallelEnv": "mrmt_env.pz_env",
    "env": "mrmt_env.pz_env",
    "parallel_env": "mrmt_env.pz_env",
    "MRMTAssignEnv": "mrmt_env.assign_env",
    "assign_aec_env": "mrmt_env.assign_pz",
    "MRMTAssignAECEnv": "mrmt_env.assign_pz",
}


def __getattr__(name: str):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'mrmt_env' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
