"""Grid worlds for multi-robot multi-target planning (world model, envs, metrics).

Importing the package registers the Gymnasium ids (:data:`GYM_IDS` grid level, :data:`ASSIGN_IDS` plan level,
:data:`LIFELONG_IDS`), each with a native vector env, and the PettingZoo ids when PettingZoo has a registry.
Every id takes its options as one :class:`~mrmt_env.config.EnvConfig` or as keywords, e.g.
``gymnasium.make("mrmt_env/MRMT-v0", layout="rooms", height=32, width=32)``.
Design notes (every id): docs/design/envs.md#the-registered-ids.
"""

from mrmt_env.distances import MOVES, UNREACHABLE, bfs_distance_field, bfs_distance_fields
from mrmt_env.generation import generate_world
from mrmt_env.world import World, WorldError

__all__ = ["World", "WorldError", "generate_world", "bfs_distance_field", "bfs_distance_fields", "UNREACHABLE",
           "MOVES", "WorldConfig", "EnvConfig", "MRMTEnv", "MRMTParallelEnv", "parallel_env", "env",
           "world_from_observation", "action_between", "actions_from_path", "ACTION_NAMES", "GYM_IDS", "ASSIGN_IDS",
           "MRMTAssignEnv", "assign_aec_env", "MRMTAssignAECEnv", "LIFELONG_IDS", "MRMTLifelongEnv",
           "lifelong_parallel_env", "lifelong_env", "LORR_IDS", "LoRREnv", "lorr_parallel_env"]

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
    # big worlds (docs/maps.md): fleet-sized, 10 robots x 100 targets on 64 x 64, one per map family.
    # Step limits are ~2x the longest makespan of the strong and fast pipelines over 100 worlds
    # (377 uniform, 525 warehouse, 421 rooms); the maze's 4000 exceeds twice its free cells, so even
    # one robot walking the whole maze finishes.
    "mrmt_env/MRMT-64x64-v0": (dict(height=64, width=64, n_robots=10, n_targets=100), 1000),
    "mrmt_env/MRMT-Warehouse-v0": (dict(height=64, width=64, n_robots=10, n_targets=100, layout="warehouse"), 1000),
    "mrmt_env/MRMT-Rooms-v0": (dict(height=64, width=64, n_robots=10, n_targets=100, layout="rooms"), 1000),
    "mrmt_env/MRMT-Maze-v0": (dict(height=64, width=64, n_robots=10, n_targets=100, layout="maze"), 4000),
    # a large fleet: 50 robots x 500 targets in a 128 x 128 warehouse
    "mrmt_env/MRMT-Warehouse-128x128-v0": (
        dict(height=128, width=128, n_robots=50, n_targets=500, layout="warehouse"),
        1500,
    ),
}

#: Registered plan-level (Assign) ids -> (kwargs, max_episode_steps).
ASSIGN_IDS = {
    "mrmt_env/MRMT-Assign-v0": ({}, 200),  # the paper's set-up; a masked agent needs <= N + R steps
    # the 64 x 64 warehouse of MRMT-Warehouse-v0 at plan level (a masked agent needs <= 110 steps)
    "mrmt_env/MRMT-Assign-Warehouse-v0": (
        dict(height=64, width=64, n_robots=10, n_targets=100, layout="warehouse"),
        400,
    ),
}


#: Registered lifelong ids -> (kwargs, max_episode_steps): tasks keep arriving, collisions are refused
#: (:mod:`mrmt_env.lifelong.env`).
LIFELONG_IDS = {
    # the paper's 10x10 world, 3 robots, 10 open tasks (refilled as they are served)
    "mrmt_env/MRMT-Lifelong-v0": ({}, 500),
    # the 64 x 64 warehouse of MRMT-Warehouse-v0 with a fleet: 100 robots, 150 open tasks on pick cells
    "mrmt_env/MRMT-Lifelong-Warehouse-v0": (
        dict(height=64, width=64, n_robots=100, n_targets=150, layout="warehouse"),
        1000,
    ),
}


#: The League of Robot Runners id (:mod:`mrmt_env.lorr`): ``gymnasium.make("mrmt_env/LoRR-v0",
#: instance=PATH)`` runs a LoRR instance file under the start kit's rules (default: a small shipped one).
LORR_IDS = {"mrmt_env/LoRR-v0": "mrmt_env.lorr.env:LoRREnv"}


def _register() -> None:
    import gymnasium

    for env_id, entry in LORR_IDS.items():
        if env_id not in gymnasium.registry:
            # the env truncates itself after the instance's simulation time
            gymnasium.register(id=env_id, entry_point=entry)

    for ids, entry, vector in (
        (GYM_IDS, "mrmt_env.grid.env:MRMTEnv", "mrmt_env.grid.vector:MRMTVectorEnv"),
        (ASSIGN_IDS, "mrmt_env.assign.env:MRMTAssignEnv", "mrmt_env.assign.vector:MRMTAssignVectorEnv"),
        (LIFELONG_IDS, "mrmt_env.lifelong.env:MRMTLifelongEnv", "mrmt_env.lifelong.vector:MRMTLifelongVectorEnv"),
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
    for kind, env_id, entry in _PETTINGZOO:
        if env_id not in (aec_registry if kind == "aec" else parallel_registry):
            register(kind, env_id, entry_point=entry)


#: PettingZoo registrations: (API, id, entry point).
_PETTINGZOO = (("aec", "mrmt_env/mrmt_v0", "mrmt_env.grid.pz:env"),
               ("parallel", "mrmt_env/mrmt_v0", "mrmt_env.grid.pz:parallel_env"),
               ("aec", "mrmt_env/mrmt_assign_v0", "mrmt_env.assign.pz:assign_aec_env"),
               ("aec", "mrmt_env/mrmt_lifelong_v0", "mrmt_env.lifelong.pz:lifelong_env"),
               ("parallel", "mrmt_env/mrmt_lifelong_v0", "mrmt_env.lifelong.pz:lifelong_parallel_env"),
               ("parallel", "mrmt_env/lorr_v0", "mrmt_env.lorr.pz:lorr_parallel_env"))

_register()

#: Public names loaded on first use (PEP 562), so importing the world model --
#: as the planners do -- does not import the env classes.
_LAZY = {
    "ACTION_NAMES": "mrmt_env.core",
    "action_between": "mrmt_env.core",
    "actions_from_path": "mrmt_env.core",
    "WorldConfig": "mrmt_env.config",
    "EnvConfig": "mrmt_env.config",
    "MRMTEnv": "mrmt_env.grid.env",
    "world_from_observation": "mrmt_env.observation",
    "MRMTParallelEnv": "mrmt_env.grid.pz",
    "env": "mrmt_env.grid.pz",
    "parallel_env": "mrmt_env.grid.pz",
    "MRMTAssignEnv": "mrmt_env.assign.env",
    "assign_aec_env": "mrmt_env.assign.pz",
    "MRMTAssignAECEnv": "mrmt_env.assign.pz",
    "MRMTLifelongEnv": "mrmt_env.lifelong.env",
    "lifelong_parallel_env": "mrmt_env.lifelong.pz",
    "lifelong_env": "mrmt_env.lifelong.pz",
    "LoRREnv": "mrmt_env.lorr.env",
    "lorr_parallel_env": "mrmt_env.lorr.pz",
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
