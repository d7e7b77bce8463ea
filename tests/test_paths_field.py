"""Path layer ``field``: legs as descents of the goal's BFS field (the ``ising`` preset's legs)."""

import numpy as np
import pytest

from mrmt_env import generate_world
from mrmt_env.distances import MOVES
from mrmt_env.world import World
from planners.paths_classical import BFSPath
from planners.paths_field import FieldPath, descend
from planners.pipeline import make_pipeline
from planners.plan import path_problem, validate_plan


def descend_reference(dist, start):
    """The oracle: step to the first neighbour (MOVES order) one closer to the goal."""
    if dist[start] < 0:
        return []
    path = [tuple(start)]
    while dist[path[-1]] > 0:
        r, c = path[-1]
        for dr, dc in MOVES:
            q = (r + dr, c + dc)
            if 0 <= q[0] < dist.shape[0] and 0 <= q[1] < dist.shape[1] and dist[q] == dist[r, c] - 1:
                path.append(q)
                break
    return path


@pytest.mark.parametrize("seed", range(6))
def test_descent_is_the_oracles_shortest_path(seed):
    world = generate_world(seed, height=12, width=15, n_robots=2, n_targets=8, obstacle_density=0.3)
    for t in range(world.n_targets):
        field = world.target_fields[t]
        for start in np.concatenate([world.robots, world.targets]):
            got = descend(field, int(start[0]), int(start[1]))
            assert [tuple(x) for x in got.tolist()] == descend_reference(field, tuple(start))
            assert path_problem(world, got, start, world.targets[t]) is None
            assert len(got) - 1 == field[start[0], start[1]]


def test_find_path_failures_and_goals_off_the_targets():
    grid = np.zeros((3, 5), dtype=bool)
    grid[:, 2] = True
    world = World(grid, robots=[[0, 0], [0, 4]], targets=[[2, 0], [2, 4]])
    layer = FieldPath()
    res = layer.find_path(world, world.robots[0], world.targets[1])
    assert res.path is None and "unreachable" in res.failure
    assert "on an obstacle" in layer.find_path(world, [0, 2], world.targets[0]).failure
    res = layer.find_path(world, world.robots[0], [1, 1])  # not a target: one BFS, counted
    assert res.success and res.length == 2 and res.stats["field_bfs"] == 1
    assert res.length == BFSPath().find_path(world, world.robots[0], [1, 1]).length


def test_ising_preset_legs_are_shortest_and_make_no_chip_path_call():
    world = generate_world(7, n_robots=3, n_targets=10)
    plan = make_pipeline("ising").plan(world, seed=7)
    validate_plan(world, plan)
    path = plan.stats["layers"]["path"]
    assert path.chip_calls == path.logical_calls == 0 and path.cpu_s > 0
    assert plan.stats["field_legs"] == world.n_targets
    dist = world.distance_matrix
    for k, route in enumerate(plan.routes):  # every leg as long as the BFS distance
        nodes = [k] + [world.n_robots + t for t in route.targets]
        assert route.length == sum(dist[a, b] for a, b in zip(nodes[:-1], nodes[1:]))
    paper = make_pipeline("ising-paper").plan(world, seed=7)
    assert paper.stats["layers"]["path"].chip_calls > 0  # ising-paper keeps the chip's paths
