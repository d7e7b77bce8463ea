"""Traffic-flow guide paths (``pibt-flow``): Dijkstra and BFS oracles, the flow recounted from the paths,
PIBT on the guide fields against the recursive oracle of test_mapf_turning."""

from __future__ import annotations

import re
import heapq
from collections import deque

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planners.mapf import TURNING_PLANNERS, make_turning_planner
from planners.mapf.guides.flow import astar_scratch, flow_astar, path_field
from planners.mapf.common import compact_grid, move_grid
from test_mapf_turning import Oracle, apply, random_instance, retarget
from test_mapf_turning import free_neighbours as neighbours


def FlowPIBT(grid, seed=0, **options):
    """PIBT with turning along traffic-flow guide paths (the planner ``pibt-flow``) on ``grid``."""
    return make_turning_planner("pibt-flow", grid, seed=seed, **options)


def move_weight(grid, flow, u, d, v):
    """The issue's rule, over flat cells: 1 move + contraflow + vertex flow (``flow`` keyed by flat cell)."""
    return 1 + (flow[u][d] + 1) * flow[v][(d + 2) % 4] + sum(flow[v]) // 2


def least_cost(grid, flow, start, goal):
    """Dijkstra over the move weights: the least total of a path ``start -> goal`` (None if unreachable)."""
    dist, heap = {start: 0}, [(0, start)]
    while heap:
        d, u = heapq.heappop(heap)
        if u == goal:
            return d
        if d > dist[u]:
            continue
        for e, v in neighbours(grid, u):
            nd = d + move_weight(grid, flow, u, e, v)
            if nd < dist.get(v, 1 << 60):
                dist[v] = nd
                heapq.heappush(heap, (nd, v))
    return None


def bfs(grid, src):
    dist, queue = {src: 0}, deque([src])
    while queue:
        p = queue.popleft()
        for _d, q in neighbours(grid, p):
            if q not in dist:
                dist[q] = dist[p] + 1
                queue.append(q)
    return dist


def guide_field(grid, path):
    """Moves to the nearest path cell + the fewest moves left among the nearest path cells."""
    per = [bfs(grid, p) for p in path]
    out = {}
    for v in per[0]:
        near = min(f[v] for f in per)
        out[v] = near + min(len(path) - 1 - i for i, f in enumerate(per) if f[v] == near)
    return out


def flat_flow(cell_of, flow):
    return {int(cell_of[i]): flow[i].tolist() for i in range(len(cell_of))}


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(2, 9), w=st.integers(2, 9), density=st.floats(0.0, 0.35))
def test_guide_paths_are_least_cost_and_fields_equal_the_bfs_oracle(seed, h, w, density):
    rng = np.random.default_rng(seed)
    grid = rng.random((h, w)) < density
    grid[0, 0] = False
    cid, cell_of, nbr = compact_grid(grid)
    n = len(cell_of)
    flow = rng.integers(0, 4, size=(n, 4)).astype(np.int64) * (nbr >= 0)
    start, goal = (int(x) for x in rng.integers(0, n, size=2))
    cost = np.ones((n, 4), dtype=np.int64)
    heuristic = (np.zeros((0, n), dtype=np.uint16), -1)  # Manhattan distance
    out = np.zeros(n, dtype=np.int32)
    length = flow_astar(move_grid(nbr, cell_of, grid.shape[1], cost), flow, heuristic, start, goal, astar_scratch(n),
                        out)
    path = [int(cell_of[v]) for v in out[:length]]
    best = least_cost(grid, flat_flow(cell_of, flow), int(cell_of[start]), int(cell_of[goal]))
    if best is None:
        assert path == [int(cell_of[start])]
        return
    assert path[0] == cell_of[start] and path[-1] == cell_of[goal]
    ff = flat_flow(cell_of, flow)
    total = 0
    for u, v in zip(path, path[1:]):
        d = next(e for e, q in neighbours(grid, u) if q == v)  # every step moves to a free neighbour
        total += move_weight(grid, ff, u, d, v)
    assert total == best
    field = np.zeros(n, dtype=np.uint16)
    path_field(nbr, out, length, field, np.uint16(65535), np.empty(n, dtype=np.int64))
    expect = guide_field(grid, path)
    assert {int(cell_of[v]): int(field[v]) for v in range(n) if field[v] != 65535} == expect


class FlowOracle(Oracle):
    """The recursive PIBT oracle ranking robot ``k``'s cells by its guide field (given per call)."""

    fields = None

    def distances(self, goals):
        return self.fields


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10**6), h=st.integers(3, 8), w=st.integers(3, 8),
       density=st.floats(0.0, 0.3), fill=st.floats(0.05, 0.8), replans=st.sampled_from([None, 0, 2]),
       commits=st.booleans())
def test_pibt_follows_the_guide_fields_and_the_flow_is_the_paths(seed, h, w, density, fill, replans, commits):
    rng = np.random.default_rng(seed)
    grid, free, pos, orient, goals = random_instance(rng, h, w, density, fill)
    ex = FlowPIBT(grid, seed=seed, replans=replans, commits=commits)
    oracle = FlowOracle(grid, ex.prio.seed, len(pos), commits=commits)
    cell_of = ex.site.cell_of
    for _ in range(10):
        act = ex.actions(pos, orient, goals)
        g = ex.source.guide
        oracle.fields = []
        for k in range(len(pos)):
            path = [int(cell_of[v]) for v in g.paths[k, :g.lengths[k]]]
            assert path[-1] == goals[k] or len(path) == 1  # every path ends at its robot's goal (or is unreachable)
            oracle.fields.append(guide_field(grid, path))
        recount = np.zeros_like(g.flow)
        for k in range(len(pos)):
            for u, v in zip(g.paths[k, :g.lengths[k] - 1], g.paths[k, 1:g.lengths[k]]):
                recount[u, list(ex.site.nbr[u]).index(v)] += 1
        assert np.array_equal(recount, g.flow)
        expect, targets = oracle.actions(pos, orient, goals)
        assert act.tolist() == expect and ex.decider.targets.tolist() == targets
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None, err
        goals = retarget(rng, free, pos, goals)


def test_new_goals_replan_first_and_replans_bounds_the_rest():
    grid = np.zeros((6, 6), dtype=bool)
    pos, orient = np.array([0, 5, 30, 35]), np.zeros(4, dtype=np.int64)
    goals = np.array([35, 30, 5, 0])
    ex = FlowPIBT(grid, seed=1, replans=1)
    ex.actions(pos, orient, goals)
    assert ex.source.guide.replanned == 4  # four new goals, none left to re-plan
    ex.actions(pos, orient, goals)
    assert ex.source.guide.replanned == 5  # no new goal: one more
    ex.actions(pos, orient, np.array([35, 30, 5, 1]))
    assert ex.source.guide.replanned == 7  # robot 3's new goal, then one more


def _trace(ex, grid, state, steps, redraw=None):
    """``ex``'s actions over ``steps`` steps from ``state = (pos, orient, goals)``, each checked valid; reached goals
    re-drawn from ``redraw = (rng, free)`` if given.  Returns (actions per step, final positions)."""
    pos, orient, goals = state
    trace = []
    for _ in range(steps):
        act = ex.actions(pos, orient, goals)
        trace.append(act.tolist())
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        if redraw is not None:
            goals = retarget(*redraw, pos, goals)
    return trace, pos


def test_robots_reach_their_goals_and_same_seed_same_run():
    rng = np.random.default_rng(3)
    grid = np.zeros((8, 8), dtype=bool)
    grid[3, 2:6] = True
    free = np.flatnonzero(~grid.reshape(-1))
    cells = rng.choice(free, size=24, replace=False).astype(np.int64)
    runs = []
    for _ in range(2):
        pos, goals, orient = cells[:12], cells[12:], np.zeros(12, dtype=np.int64)
        ex = make_turning_planner("pibt-flow", grid, seed=5)
        trace, pos = _trace(ex, grid, (pos, orient, goals), 120)
        assert np.array_equal(pos, goals)
        runs.append(trace)
    assert runs[0] == runs[1]
    assert ex.kind is TURNING_PLANNERS["pibt-flow"] and ex.name == "pibt-flow"


def test_dense_crowds_only_get_valid_joint_actions():
    rng = np.random.default_rng(11)
    grid, free, pos, orient, goals = random_instance(rng, 14, 16, 0.15, 0.6)
    ex = FlowPIBT(grid, seed=2, guidance=2)
    for step in range(100):
        pos2, orient, err = apply(grid, pos, orient, ex.actions(pos, orient, goals))
        assert err is None, f"step {step}: {err}"
        pos = pos2
        goals = retarget(rng, free, pos, goals)


def test_bad_options_name_the_value():
    grid = np.zeros((4, 4), dtype=bool)
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match=rf"replans = {re.escape(repr(bad))} must be an integer in \[0, 16777216\] or null$"):
            FlowPIBT(grid, replans=bad)
    ex = FlowPIBT(grid, field_bytes=100)
    with pytest.raises(ValueError, match=r"3 robots x 16 free cells need 288 bytes, over field_bytes = 100"):
        ex.actions(np.array([0, 1, 2]), np.zeros(3, dtype=np.int64), np.array([5, 6, 7]))
    kind = TURNING_PLANNERS["pibt-flow"]
    with pytest.raises(ValueError, match=r"3 robots x 16 free cells need 288 bytes, over field_bytes = 100"):
        kind.check_team(grid, 3, kind.Options.from_dict({"field_bytes": 100}, "pibt-flow"))
    kind.check_team(grid, 3, kind.Options.from_dict({}, "pibt-flow"))  # fits the default bound


def _goal_field(grid, goal):
    """BFS moves to flat ``goal`` as a dict over flat cells."""
    return bfs(grid, int(goal))


def test_guide_work_bounds_the_searches_and_robots_waiting_follow_their_goal_fields():
    grid = np.zeros((6, 7), dtype=bool)
    grid[2, 1:6] = True
    free = np.flatnonzero(~grid.reshape(-1))
    pos = free[[0, 3, 6, 9, 12, 15]].astype(np.int64)
    goals = free[[30, 28, 26, 24, 22, 20]].astype(np.int64)
    orient = np.zeros(6, dtype=np.int64)
    ex = FlowPIBT(grid, seed=4, replans=0, guide_work=1)  # one search per call: the check comes before a robot
    g = ex.source.guide
    for call in range(1, 4):
        ex.actions(pos, orient, goals)
        assert g.replanned == call and np.flatnonzero(g.fresh).tolist() == list(range(call))
        for k in range(6):
            path = [int(ex.site.cell_of[v]) for v in g.paths[k, :g.lengths[k]]]
            want = guide_field(grid, path) if g.fresh[k] else _goal_field(grid, goals[k])  # a waiting robot: its goal's field
            assert {int(ex.site.cell_of[v]): int(g.fields[k, v]) for v in range(len(ex.site.cell_of))} == want
        recount = np.zeros_like(g.flow)
        for k in range(6):
            for u, v in zip(g.paths[k, :g.lengths[k] - 1], g.paths[k, 1:g.lengths[k]]):
                recount[u, list(ex.site.nbr[u]).index(v)] += 1
        assert np.array_equal(recount, g.flow)
    assert g.late == 5 + 4 + 3  # robot-calls spent waiting
    goals = goals.copy()
    goals[0] = free[29]  # robot 0 wants a new path now; robots 3..5 have waited since the first call
    ex.actions(pos, orient, goals)
    assert g.fresh.tolist() == [False, True, True, True, False, False]


def test_goal_fields_not_computed_yet_leave_a_waiting_robot_on_manhattan_distance():
    grid = np.zeros((5, 5), dtype=bool)
    pos, orient = np.array([0, 4, 20]), np.zeros(3, dtype=np.int64)
    goals = np.array([24, 12, 2])
    ex = FlowPIBT(grid, seed=0, replans=0, guide_work=1, bfs_budget=1)  # one goal field and one search per call
    heuristic_rows = []
    real = ex.source.guide.update
    ex.source.guide.update = lambda *a: heuristic_rows.append(real(*a)) or heuristic_rows[-1]
    for call in range(3):
        ex.actions(pos, orient, goals)
        has_field = ex.source.fields.row_of[ex.site.cid[goals]] >= 0
        assert has_field.sum() == call + 1  # one new goal field a call
        expect = [k if ex.source.guide.fresh[k] or has_field[k] else -1 for k in range(3)]
        assert heuristic_rows[call].tolist() == expect
        assert ex.source.guide.fresh.tolist() == [k <= call for k in range(3)]
        if call == 0:
            assert -1 in expect  # a waiting robot whose goal has no field yet: Manhattan distance


def test_longer_paths_grow_the_rows_and_wider_values_the_dtype_with_the_same_run(monkeypatch):
    import planners.mapf.guides.flow as flow

    def run(h=18, w=18):
        rng = np.random.default_rng(8)
        grid, free, pos, orient, goals = random_instance(rng, h, w, 0.2, 0.3)
        ex = FlowPIBT(grid, seed=3)
        return _trace(ex, grid, (pos, orient, goals), 25, (rng, free))[0], ex.source.guide

    plain, guide = run()
    assert guide.paths.shape[1] == min(flow.FIRST_PATH_CELLS, len(guide.cell_of)) and guide.dtype == np.uint16
    monkeypatch.setattr(flow, "FIRST_PATH_CELLS", 2)
    real = flow.field_dtype
    monkeypatch.setattr(flow, "field_dtype", lambda nbr: (np.dtype(np.uint16), 65534 - 6))  # room for 7-cell paths
    grown, guide = run()
    assert grown == plain
    assert guide.paths.shape[1] >= guide.lengths.max() > 7 and guide.dtype == np.uint32
    assert real(guide.nbr)[0] == np.uint16


def test_under_a_clock_past_its_stop_no_path_is_planned_and_the_actions_stay_valid():
    import time

    rng = np.random.default_rng(2)
    grid, free, pos, orient, goals = random_instance(rng, 9, 9, 0.1, 0.4)
    for name in ("pibt-flow", "epibt"):  # EPIBT ranks by the same guide paths and keeps the same stop
        ex = make_turning_planner(name, grid, seed=1)
        act = ex.actions(pos, orient, goals, deadline=time.perf_counter() - 1.0)
        assert ex.source.guide.replanned == 0 and not ex.source.guide.fresh.any(), name
        _pos, _orient, err = apply(grid, pos, orient, act)
        assert err is None, name
        late = make_turning_planner(name, grid, seed=1)
        late.actions(pos, orient, goals, deadline=time.perf_counter() + 60.0)  # far off: every path planned
        assert late.source.guide.fresh.all(), name


@pytest.mark.parametrize("bad", [0, -3, 1.5, True, "many"])
def test_bad_guide_work_names_the_value(bad):
    grid = np.zeros((4, 4), dtype=bool)
    with pytest.raises(ValueError, match=rf"guide_work = {re.escape(repr(bad))} must be an integer in \[1, 1099511627776\] or null$"):
        FlowPIBT(grid, guide_work=bad)
    with pytest.raises(ValueError, match="guide_work = "):
        make_turning_planner("epibt", grid, guide_work=bad)
