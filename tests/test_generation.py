"""Property tests of the world generator (paper section 6.1 set-up)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrmt_env import World, bfs_distance_field, generate_world

params = st.fixed_dictionaries(
    {
        "seed": st.integers(0, 2**32 - 1),
        "height": st.integers(2, 12),
        "width": st.integers(2, 12),
        "obstacle_density": st.sampled_from([0.0, 0.1, 0.2, 0.3]),
        "placement": st.sampled_from(["uniform", "centre"]),
    }
)


def _counts(p, data):
    free = p["height"] * p["width"] - int(round(p["obstacle_density"] * (p["height"] * p["width"])))
    # stay well under the free-cell count so a connected draw exists
    budget = max(2, free // 3)
    n_robots = data.draw(st.integers(1, min(4, budget - 1)))
    n_targets = data.draw(st.integers(0, min(10, budget - n_robots)))
    return n_robots, n_targets


@settings(max_examples=60, deadline=None)
@given(p=params, data=st.data())
def test_generator_invariants(p, data):
    n_robots, n_targets = _counts(p, data)
    w = generate_world(n_robots=n_robots, n_targets=n_targets, **p)
    assert isinstance(w, World)
    h, wd = p["height"], p["width"]
    assert w.shape == (h, wd)
    # round(density x cell count), Python's round (half to even): 0.3 x 45 = 13.5 -> 14
    assert int(w.grid.sum()) == int(round(p["obstacle_density"] * (h * wd)))
    assert w.n_robots == n_robots and w.n_targets == n_targets
    cells = [tuple(c) for c in w.nodes.tolist()]
    assert len(set(cells)) == len(cells), "robots and targets must be on pairwise distinct cells"
    assert not w.grid[w.nodes[:, 0], w.nodes[:, 1]].any()
    comp = bfs_distance_field(w.grid, w.robots[0]) >= 0
    assert comp[w.nodes[:, 0], w.nodes[:, 1]].all(), "all robots and targets in one 4-connected component"
    assert np.isfinite(w.distance_matrix).all()
    # determinism: a pure function of its arguments
    assert generate_world(n_robots=n_robots, n_targets=n_targets, **p) == w


def test_different_seeds_differ_and_generator_argument():
    worlds = {generate_world(s) for s in range(20)}
    assert len(worlds) == 20
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    assert generate_world(rng_a) == generate_world(rng_b)
    assert generate_world(rng_a) != generate_world(np.random.default_rng(5))  # advanced in place


def test_paper_defaults():
    w = generate_world(0)
    assert w.shape == (10, 10) and w.n_robots == 3 and w.n_targets == 10 and int(w.grid.sum()) == 20


def test_centre_placement_puts_robots_near_centre():
    for s in range(10):
        w = generate_world(s, placement="centre")
        d2 = ((w.robots - 4.5) ** 2).sum(axis=1)
        # the 15 free cells nearest the centre lie within Euclidean distance ~3 of it
        assert d2.max() <= 3.6**2


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(n_robots=0), "n_robots must be an integer >= 1"),
        (dict(height=0), "height must be an integer >= 1"),
        (dict(obstacle_density=1.0), r"obstacle_density must be in \[0, 1\)"),
        (dict(placement="corner"), "placement must be one of"),
        (dict(height=3, width=3, n_robots=4, n_targets=6), "need 10 distinct free cells"),
    ],
)
def test_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        generate_world(0, **kwargs)


def test_obstacle_count_rounds_density_times_cells_half_to_even():
    # 0.3 x (9 x 5) = 13.5 exactly: Python's round gives 14 (half to even)
    w = generate_world(0, height=9, width=5, obstacle_density=0.3, n_robots=1, n_targets=0)
    assert int(w.grid.sum()) == 14
