"""World validation, BFS distance fields and the distance matrix."""

from __future__ import annotations

import itertools
import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrmt_env import UNREACHABLE, World, WorldError, bfs_distance_field, bfs_distance_fields
from mrmt_env.distances import MOVES

GRID = np.array(
    [
        [0, 0, 0, 1],
        [0, 1, 0, 0],
        [0, 1, 0, 0],
        [0, 0, 0, 1],
    ],
    dtype=bool,
)


def test_valid_world_properties():
    w = World(GRID, [[0, 0]], [[3, 2], [1, 3]])
    assert w.shape == (4, 4) and w.n_robots == 1 and w.n_targets == 2
    assert w.robots.dtype == np.int64 and w.targets.dtype == np.int64
    assert w.nodes.tolist() == [[0, 0], [3, 2], [1, 3]]
    d = w.distance_matrix
    assert d.shape == (3, 3)
    assert d[0, 1] == 5  # (0,0)->(1,0)->(2,0)->(3,0)->(3,1)->(3,2)
    assert d[0, 2] == 4  # (0,0)->(0,1)->(0,2)->(1,2)->(1,3)
    assert np.array_equal(d, d.T) and np.all(np.diag(d) == 0)
    assert not w.grid.flags.writeable and not w.robots.flags.writeable


@pytest.mark.parametrize(
    "robots, targets, match",
    [
        ([[4, 0]], [[0, 1]], r"robot 0 cell \[4, 0\] is out of bounds for a 4x4 grid"),
        ([[0, -1]], [[0, 1]], r"robot 0 cell \[0, -1\] is out of bounds"),
        ([[0, 0]], [[0, 4]], r"target 0 cell \[0, 4\] is out of bounds"),
        ([[1, 1]], [[0, 1]], r"robot 0 cell \[1, 1\] is on an obstacle"),
        ([[0, 0]], [[0, 1], [0, 3]], r"target 1 cell \[0, 3\] is on an obstacle"),
        ([[0, 0]], [[0, 1], [2, 2], [0, 1]], r"target 2 cell \[0, 1\] duplicates target 0"),
        ([], [[0, 1]], r"at least one of robots, got 0"),
        ([[0, 0.5]], [[0, 1]], r"robots cell \[0.0, 0.5\] is not an integer"),
    ],
)
def test_validation_errors_name_the_value(robots, targets, match):
    with pytest.raises(WorldError, match=match):
        World(GRID, robots, targets)


def test_unreachable_target_is_an_error():
    grid = np.array([[0, 1, 0], [0, 1, 0]], dtype=bool)
    with pytest.raises(WorldError, match=r"target 0 cell \[0, 2\] is unreachable from every robot"):
        World(grid, [[0, 0]], [[0, 2]])
    # reachable from a second robot in the other component is fine
    w = World(grid, [[0, 0], [1, 2]], [[0, 2]])
    assert np.isinf(w.distance_matrix[0, 2]) and w.distance_matrix[1, 2] == 1


def test_bad_grids():
    with pytest.raises(WorldError, match="non-empty 2-D"):
        World(np.zeros(4, dtype=bool), [[0]], [])
    with pytest.raises(WorldError, match="boolean"):
        World(np.full((2, 2), 2), [[0, 0]], [])
    with pytest.raises(WorldError, match=r"\[row, col\] pairs"):
        World(GRID, [[0, 0, 0]], [])


def test_robots_may_share_and_stand_on_targets():
    w = World(GRID, [[0, 0], [0, 0]], [[0, 0]])
    assert w.n_robots == 2


def test_equality_hash_replace_pickle():
    a = World(GRID, [[0, 0]], [[3, 2]])
    b = World(GRID.copy(), [[0, 0]], [[3, 2]])
    assert a == b and hash(a) == hash(b)
    c = a.replace(targets=[[1, 3]])
    assert c != a and c.targets.tolist() == [[1, 3]]
    assert pickle.loads(pickle.dumps(a)) == a


def _brute_force_distance(grid, src):
    """Bellman-Ford style relaxation to a fixed point (no queue)."""
    h, w = grid.shape
    inf = h * w + 1
    d = np.full((h, w), inf)
    d[src] = 0
    changed = True
    while changed:
        changed = False
        for r, c in itertools.product(range(h), range(w)):
            if grid[r, c]:
                continue
            for dr, dc in MOVES.tolist():
                nr, nc = r + dr, c + dc
                if 0 <= nr < h and 0 <= nc < w and not grid[nr, nc] and d[nr, nc] + 1 < d[r, c]:
                    d[r, c] = d[nr, nc] + 1
                    changed = True
    d[d == inf] = UNREACHABLE
    if grid[src]:
        d[:] = UNREACHABLE
    return d.astype(np.int32)


@settings(max_examples=60, deadline=None)
@given(
    h=st.integers(1, 6),
    w=st.integers(1, 6),
    data=st.data(),
)
def test_bfs_matches_brute_force(h, w, data):
    cells = data.draw(st.lists(st.booleans(), min_size=h * w, max_size=h * w))
    grid = np.array(cells, dtype=bool).reshape(h, w)
    src = (data.draw(st.integers(0, h - 1)), data.draw(st.integers(0, w - 1)))
    assert np.array_equal(bfs_distance_field(grid, src), _brute_force_distance(grid, src))


def test_bfs_fields_shape_and_obstacle_source():
    fields = bfs_distance_fields(GRID, [[0, 0], [1, 1]])
    assert fields.shape == (2, 4, 4) and fields.dtype == np.int32
    assert np.all(fields[1] == UNREACHABLE)
    assert fields[0][GRID].max() == UNREACHABLE


def test_distance_matrix_matches_fields():
    from mrmt_env import generate_world

    w = generate_world(3)
    d = w.distance_matrix
    for i, (r, c) in enumerate(w.nodes):
        f = bfs_distance_field(w.grid, (r, c))
        assert np.array_equal(d[i], f[w.nodes[:, 0], w.nodes[:, 1]])
