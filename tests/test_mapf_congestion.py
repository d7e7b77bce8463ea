"""Goal fields that see the crowd (``congestion``, ``refresh``): every field a call computes equals the Dijkstra
oracle of ``test_mapf_turning.guided`` (a move into a cell a robot stands on costs ``P`` more, on top of the lanes),
the refresh recomputes the most-wanted stale fields first and no more than asked, and the joint actions stay
valid; ``congestion=0`` changes nothing."""

from __future__ import annotations

import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.mapf import make_turning_planner
from test_mapf_turning import apply, guided, random_instance, retarget


def TurningPIBT(grid, seed=0, **options):
    """PIBT with turning (the planner ``pibt``) on ``grid``."""
    return make_turning_planner("pibt", grid, seed=seed, **options)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(3, 8), w=st.integers(3, 8), density=st.floats(0.0, 0.3),
       fill=st.floats(0.1, 0.8), weight=st.integers(1, 6), lanes=st.sampled_from([0, 2]))
def test_fields_computed_in_a_call_equal_the_crowd_oracle(seed, h, w, density, fill, weight, lanes):
    rng = np.random.default_rng(seed)
    grid, free, pos, orient, goals = random_instance(rng, h, w, density, fill)
    ex = TurningPIBT(grid, seed=seed, guidance=lanes, congestion=weight, refresh=1000)
    for _ in range(4):
        at = set(pos.tolist())
        act = ex.actions(pos, orient, goals)
        f = ex.source.fields
        fresh = np.flatnonzero(f.filled[:f.used] == f.calls)
        assert len(fresh) == len(np.unique(goals))  # every goal of the call: new, or refreshed
        for row in fresh.tolist():
            want = guided(grid, int(ex.site.cell_of[f.goal_of[row]]), lanes, crowd=weight, occupied=at)
            assert [int(x) for x in f.fields[row]] == [want.get(int(c), f.far) for c in ex.site.cell_of]
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)


def test_refresh_takes_robots_times_staleness_first_and_no_more():
    grid = np.zeros((6, 6), dtype=bool)
    pos = np.arange(0, 12, dtype=np.int64)
    orient = np.zeros(12, dtype=np.int64)
    goals = np.array([35] * 5 + [30] * 4 + [24] * 2 + [18], dtype=np.int64)  # 5, 4, 2 and 1 robots per goal
    ex = TurningPIBT(grid, seed=1, congestion=3, refresh=2)
    ex.actions(pos, orient, goals)  # four new fields, none stale: no refresh
    assert ex.source.fields.computed == 4 and ex.source.congestion.refreshed == 0
    ex.actions(pos, orient, goals)
    f = ex.source.fields
    refreshed = sorted(int(f.goal_of[r]) for r in np.flatnonzero(f.filled[:f.used] == f.calls))
    assert f.computed == 6 and ex.source.congestion.refreshed == 2
    assert refreshed == sorted(ex.site.cid[[35, 30]].tolist())
    ex.actions(pos, orient, goals)  # robots x calls since computed: 35 5 x 1, 30 4 x 1, 24 2 x 2, 18 1 x 2
    refreshed = sorted(int(f.goal_of[r]) for r in np.flatnonzero(f.filled[:f.used] == f.calls))
    assert f.computed == 8 and refreshed == sorted(ex.site.cid[[35, 24]].tolist())  # 30 and 24 tie: the older first


def test_no_congestion_changes_nothing_and_a_past_deadline_refreshes_nothing():
    rng = np.random.default_rng(4)
    grid, free, pos, orient, goals = random_instance(rng, 9, 9, 0.1, 0.5)
    plain, zero = TurningPIBT(grid, seed=2), TurningPIBT(grid, seed=2, congestion=0, refresh=5)
    crowd = TurningPIBT(grid, seed=2, congestion=4)
    changed = False
    for _ in range(30):
        act = plain.actions(pos, orient, goals)
        assert np.array_equal(zero.actions(pos, orient, goals), act)
        changed |= not np.array_equal(crowd.actions(pos, orient, goals), act)
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert changed and zero.source.congestion is None and crowd.source.congestion.refreshed > 0
    late = TurningPIBT(grid, seed=2, congestion=4)
    late.actions(pos, orient, goals)
    act = late.actions(pos, orient, goals, deadline=time.perf_counter() - 1.0)
    assert late.source.congestion.refreshed == 0 and apply(grid, pos, orient, act)[2] is None


def test_epibt_takes_the_crowd_on_its_goal_fields_only():
    rng = np.random.default_rng(6)
    grid, free, pos, orient, goals = random_instance(rng, 8, 8, 0.1, 0.6)
    ex = make_turning_planner("epibt", grid, seed=1, flow=False, congestion=3, lns=20)
    for _ in range(10):
        act = ex.actions(pos, orient, goals)
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert ex.source.congestion.refreshed > 0
    with pytest.raises(ValueError, match=r"^congestion = 3 needs flow=false"):
        make_turning_planner("epibt", grid, congestion=3)
