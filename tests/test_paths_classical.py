"""Classical pathfinding: BFS, A*, GBFS on the 4-neighbour grid."""

import numpy as np
import pytest

from mrmt_env import World, generate_world
from planners.paths_classical import AStarPath, BFSPath, GreedyBestFirstPath

PLANNERS = [BFSPath(), AStarPath(), GreedyBestFirstPath()]


def _assert_legal(world, path, a, b):
    assert path.ndim == 2 and path.shape[1] == 2
    assert path[0].tolist() == list(a) and path[-1].tolist() == list(b)
    assert not world.grid[path[:, 0], path[:, 1]].any()
    assert (np.abs(np.diff(path, axis=0)).sum(axis=1) == 1).all()


@pytest.mark.parametrize("seed", range(30))
def test_bfs_and_astar_shortest_gbfs_valid(seed):
    world = generate_world(seed, height=12, width=9, obstacle_density=0.25, n_robots=2, n_targets=6)
    cells = world.nodes
    rng = np.random.default_rng(seed)
    for _ in range(6):
        i, j = rng.choice(len(cells), 2, replace=True)
        a, b = cells[i], cells[j]
        bfs = BFSPath().find_path(world, a, b)
        astar = AStarPath().find_path(world, a, b)
        gbfs = GreedyBestFirstPath().find_path(world, a, b)
        true = int(world.distance_matrix[i, j])
        assert bfs.length == astar.length == true
        assert gbfs.length >= true
        for res in (bfs, astar, gbfs):
            assert res.success and res.failure is None
            _assert_legal(world, res.path, a, b)
            assert res.stats["expanded"] >= (1 if i != j else 0)


def test_gbfs_can_be_longer_than_shortest():
    # a U-shaped wall: greedy heads into the pocket first
    grid = np.zeros((7, 7), dtype=bool)
    grid[1:6, 4] = True
    grid[5, 1:5] = True
    world = World(grid, [[3, 2]], [[3, 6]])
    g = GreedyBestFirstPath().find_path(world, world.robots[0], world.targets[0])
    b = BFSPath().find_path(world, world.robots[0], world.targets[0])
    _assert_legal(world, g.path, world.robots[0], world.targets[0])
    assert b.length == int(world.distance_matrix[0, 1])
    assert g.length >= b.length


@pytest.mark.parametrize("planner", PLANNERS, ids=lambda p: p.name)
def test_unreachable_goal_is_failure_not_path(planner):
    grid = np.zeros((3, 5), dtype=bool)
    grid[:, 2] = True  # wall splits the grid
    world = World(grid, [[0, 0], [0, 4]], [[2, 4]])
    res = planner.find_path(world, world.robots[0], world.targets[0])
    assert not res.success and res.path is None and res.length is None
    assert "unreachable" in res.failure and "[0, 0]" in res.failure and "[2, 4]" in res.failure


@pytest.mark.parametrize("planner", PLANNERS, ids=lambda p: p.name)
def test_bad_cells_are_failures(planner):
    world = generate_world(0)
    obstacle = np.argwhere(world.grid)[0]
    res = planner.find_path(world, world.robots[0], obstacle)
    assert not res.success and "obstacle" in res.failure
    res = planner.find_path(world, [-1, 0], world.targets[0])
    assert not res.success and "off the 10x10 grid" in res.failure


@pytest.mark.parametrize("planner", PLANNERS, ids=lambda p: p.name)
def test_start_equals_goal(planner):
    world = generate_world(1)
    res = planner.find_path(world, world.robots[0], world.robots[0])
    assert res.length == 0 and res.path.tolist() == [world.robots[0].tolist()]
