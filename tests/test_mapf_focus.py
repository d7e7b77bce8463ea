"""The robots at work (``active``): the goals kept are those of the robots of least way by the goal fields (a slow
oracle written from the statement), ``active=1`` plans as without the option, and every joint action stays valid."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.mapf import make_turning_planner
from planners.mapf.guides.focus import active_count, active_goals
from test_mapf_turning import apply, bfs, random_instance


def TurningPIBT(grid, seed=0, **options):
    return make_turning_planner("pibt", grid, seed=seed, **options)


def EPIBT(grid, seed=0, **options):
    return make_turning_planner("epibt", grid, seed=seed, **options)


def steer(ex, pos, goals):
    """The goals ``ex``'s focus leaves its robots this step (no ``rest``)."""
    return ex.focus.steer(pos, goals, None, ex.source, ex.prio)


def oracle(pos, goals, way, count):
    """The statement, slowly: robots with a goal ranked by (way, index); the first ``count`` keep theirs."""
    ranked = sorted((int(way[k]), k) for k in range(len(pos)) if goals[k] != pos[k])
    keep = {k for _, k in ranked[:count]}
    return [int(goals[k]) if k in keep else int(pos[k]) for k in range(len(pos))]


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), n=st.integers(1, 30), count=st.integers(1, 30))
def test_the_goals_kept_equal_the_oracle(seed, n, count):
    rng = np.random.default_rng(seed)
    pos = rng.choice(100, size=n, replace=False).astype(np.int64)
    goals = np.where(rng.random(n) < 0.3, pos, rng.integers(0, 100, size=n)).astype(np.int64)
    way = rng.integers(0, 5, size=n).astype(np.int64)  # many ties: the lower index first
    assert active_goals(pos, goals, way, count).tolist() == oracle(pos, goals, way, count)


@pytest.mark.parametrize("name, options", [("pibt", {"guidance": 0}), ("epibt", {"flow": False})])
def test_the_robots_of_least_way_by_the_fields_keep_their_goals(name, options):
    # a U: the two arms joined at the bottom; the wall between the arms makes Manhattan distance mislead
    grid = np.zeros((5, 5), dtype=bool)
    grid[0:4, 2] = True
    w = grid.shape[1]
    goal = 0 * w + 0  # top of the left arm
    pos = np.array([0 * w + 3, 3 * w + 0, 4 * w + 4, 2 * w + 1], dtype=np.int64)
    goals = np.array([goal, goal, goal, 2 * w + 1], dtype=np.int64)  # robot 3 has no goal (its own cell)
    ex = make_turning_planner(name, grid, seed=0, active=0.5, **options)  # 2 of 4 robots at work
    dist = bfs(grid, goal)
    way = np.array([dist[int(p)] for p in pos], dtype=np.int64)
    assert way.tolist() == [11, 3, 8, 3]  # robot 0 is 3 cells from the goal by Manhattan, 11 by moves
    assert steer(ex, pos, goals).tolist() == oracle(pos, goals, way, active_count(0.5, 4))
    assert steer(ex, pos, goals).tolist() == [pos[0], goal, goal, pos[3]]


@pytest.mark.parametrize("name, options", [("pibt", {}), ("epibt", {"flow": False})])
def test_everyone_at_work_plans_as_without_the_option(name, options):
    rng = np.random.default_rng(3)
    grid, free, pos, orient, goals = random_instance(rng, 7, 7, 0.2, 0.5)
    a, b = (make_turning_planner(name, grid, seed=1, **o, **options) for o in ({"active": 1.0}, {}))
    for _ in range(5):
        act = a.actions(pos, orient, goals)
        assert act.tolist() == b.actions(pos, orient, goals).tolist()
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(3, 8), w=st.integers(3, 8), density=st.floats(0.0, 0.3),
       fill=st.floats(0.1, 0.8), active=st.floats(0.05, 1.0))
def test_a_share_at_work_keeps_every_joint_action_valid(seed, h, w, density, fill, active):
    rng = np.random.default_rng(seed)
    grid, free, pos, orient, goals = random_instance(rng, h, w, density, fill)
    ex = EPIBT(grid, seed=seed, active=active, flow=False) if seed % 2 else TurningPIBT(grid, seed=seed, active=active)
    for _ in range(6):
        kept = steer(ex, pos, goals)
        assert int((kept != pos).sum()) == min(int((goals != pos).sum()), active_count(active, len(pos)))
        act = ex.actions(pos, orient, goals)
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None


@pytest.mark.parametrize("active", [0.0, 1.5, True])
def test_a_bad_share_names_the_option_and_its_range(active):
    with pytest.raises(ValueError, match=r"active = .*\[0\.001, 1\]"):
        TurningPIBT(np.zeros((3, 3), dtype=bool), active=active)
