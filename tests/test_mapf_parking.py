"""Parking places (``park``): the through-traffic and the nearest parking place equal a slow oracle written from the
statement, the places are the cells few routes pass, and a robot without a goal heads for one while robots with
goals plan as without the option."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.mapf import EPIBT, TurningPIBT
from planners.mapf.common import compact_grid
from planners.mapf.guides.parking import PARKING_SOURCES, ParkingPlaces
from test_mapf_turning import apply, random_instance


def oracle(nbr, share, seed):
    """The statement, slowly: BFS trees from the seeded sources, subtree sizes, the least-traffic share, and the
    nearest place by a multi-source BFS (neighbours in the order east, south, west, north)."""
    n = len(nbr)
    sources = sorted(np.random.default_rng(seed).choice(n, size=min(PARKING_SOURCES, n), replace=False).tolist())
    traffic = [0.0] * n
    for s in sources:
        parent, order, queue = {s: None}, [], deque([s])
        while queue:
            u = queue.popleft()
            order.append(u)
            for v in nbr[u].tolist():
                if v >= 0 and v not in parent:
                    parent[v] = u
                    queue.append(v)
        size = dict.fromkeys(order, 1.0)
        for u in reversed(order[1:]):
            size[parent[u]] += size[u]
        for u, k in size.items():
            traffic[u] += k
    traffic = [t / len(sources) for t in traffic]
    count = max(int(round(share * n)), 1)
    park = set(sorted(range(n), key=lambda c: (traffic[c], c))[:count])
    goal = [c if c in park else -1 for c in range(n)]
    queue = deque(sorted(park))
    while queue:
        u = queue.popleft()
        for v in nbr[u].tolist():
            if v >= 0 and goal[v] < 0:
                goal[v] = goal[u]
                queue.append(v)
    return traffic, park, goal


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(2, 9), w=st.integers(2, 9), density=st.floats(0.0, 0.4),
       share=st.floats(0.05, 1.0))
def test_traffic_places_and_nearest_equal_the_oracle(seed, h, w, density, share):
    grid = np.random.default_rng(seed).random((h, w)) < density
    grid[0, 0] = False
    _, _, nbr = compact_grid(grid)
    places = ParkingPlaces(nbr, share, seed)
    traffic, park, goal = oracle(nbr, share, seed)
    assert np.allclose(places.traffic, traffic, rtol=0, atol=1e-9)
    assert set(np.flatnonzero(places.park).tolist()) == park
    assert places.goal_of.tolist() == goal


def test_the_places_are_off_the_through_route():
    """A corridor with a dead-end stub off its middle: the stub's end and the corridor's two ends carry no
    through-traffic; the junction carries the most."""
    grid = np.ones((3, 9), dtype=bool)
    grid[1, :] = False  # the corridor, row 1
    grid[2, 4] = False  # a stub below its middle
    cid, cell_of, nbr = compact_grid(grid)
    places = ParkingPlaces(nbr, 3 / len(cell_of), seed=0)
    parked = sorted(cell_of[np.flatnonzero(places.park)].tolist())
    assert parked == [9, 17, 22]  # (1, 0), (1, 8) and (2, 4)
    assert int(cell_of[np.argmax(places.traffic)]) == 13  # (1, 4), the junction
    nearest = {c: int(cell_of[places.goal_of[cid[c]]]) for c in (10, 12, 16)}
    assert nearest == {10: 9, 12: 22, 16: 17}  # by moves: (1, 3) is 2 from the stub's end, 3 from (1, 0)


@pytest.mark.parametrize("cls, options", [(TurningPIBT, {"guidance": 0}), (EPIBT, {"flow": False})])
def test_a_robot_without_a_goal_heads_for_a_place_and_the_others_plan_as_without(cls, options):
    grid = np.ones((3, 9), dtype=bool)
    grid[1, :] = False
    grid[2, 4] = False
    pos = np.array([13, 10], dtype=np.int64)  # robot 0 idle on the junction, robot 1 heading east to (1, 8)
    orient = np.array([1, 0], dtype=np.int64)  # robot 0 faces south, towards the stub
    goals = np.array([13, 17], dtype=np.int64)
    parked = cls(grid, seed=0, park=0.35, **options)
    plain = cls(grid, seed=0, **options)
    assert parked.actions(pos, orient, goals)[0] == 0  # forward into the stub, a parking place
    assert plain.actions(pos, orient, goals)[0] == 3  # without the option it waits where it stands
    busy = np.array([16, 10], dtype=np.int64)  # no robot idle: the same plan as without the option
    assert cls(grid, seed=0, park=0.35, **options).actions(pos, orient, busy).tolist() == \
        cls(grid, seed=0, **options).actions(pos, orient, busy).tolist()


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(3, 8), w=st.integers(3, 8), density=st.floats(0.0, 0.3),
       fill=st.floats(0.1, 0.8))
def test_parking_keeps_every_joint_action_valid(seed, h, w, density, fill):
    rng = np.random.default_rng(seed)
    grid, free, pos, orient, goals = random_instance(rng, h, w, density, fill)
    ex = TurningPIBT(grid, seed=seed, park=0.3)
    for _ in range(6):
        act = ex.actions(pos, orient, goals)
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None


@pytest.mark.parametrize("park", [1.5, -0.1])
def test_a_bad_share_names_the_option_and_its_range(park):
    with pytest.raises(ValueError, match=r"park.*\[0, 1\]"):
        TurningPIBT(np.zeros((3, 3), dtype=bool), park=park)
