"""Grid worlds for multi-robot multi-target planning (world model, envs, metrics)."""

from mrmt_env.distances import UNREACHABLE, bfs_distance_field, bfs_distance_fields
from mrmt_env.generation import generate_world
from mrmt_env.world import World, WorldError

__all__ = [
    "World",
    "WorldError",
    "generate_world",
    "bfs_distance_field",
    "bfs_distance_fields",
    "UNREACHABLE",
]
