"""Windowed planning with turning (LoRR's MAPF_T actions): an independent validity check, plans, progress, input."""

from __future__ import annotations

import heapq
from collections import deque

import numpy as np
import pytest

from lanes_reference import lane_cost
from planners.mapf import TURNING_EXECUTORS, TurningPIBT, WindowedTurningPlanner, make_turning_executor
from planners.mapf.pibt.windowed_turning import OrientFields

F, R, C, W = 0, 1, 2, 3
DR, DC = (0, 1, 0, -1), (1, 0, -1, 0)  # east, south, west, north


def apply(grid, pos, orient, act):
    """Next (pos, orient) under the rules, and the first rule broken (None when the joint action is valid)."""
    h, w = grid.shape
    nxt, nor = [], []
    for p, o, a in zip(pos.tolist(), orient.tolist(), act.tolist()):
        if a not in (F, R, C, W):
            return pos, orient, f"action {a}"
        r, c = divmod(p, w)
        if a == F:
            r, c = r + DR[o], c + DC[o]
            if not (0 <= r < h and 0 <= c < w) or grid[r, c]:
                return pos, orient, f"F from {p} facing {o} leaves the map or hits an obstacle"
        nxt.append(r * w + c)
        nor.append((o + (a == R) - (a == C)) % 4)
    if len(set(nxt)) != len(nxt):
        return pos, orient, "two robots end in one cell"
    moves = {(p, q) for p, q in zip(pos.tolist(), nxt) if p != q}
    if any((q, p) in moves for p, q in moves):
        return pos, orient, "two robots swap cells"
    return np.array(nxt, dtype=np.int64), np.array(nor, dtype=np.int64), None


def plan_problem(grid, paths):
    """The first rule a planned window breaks between two of its steps (``paths[k, t]`` = cell * 4 + o)."""
    for t in range(paths.shape[1] - 1):
        pos, orient, nxt = paths[:, t] >> 2, paths[:, t] & 3, paths[:, t + 1]
        step = [next((a for a in (F, R, C, W) if _after(grid, p, o, a) == q), None)
                for p, o, q in zip(pos.tolist(), orient.tolist(), nxt.tolist())]
        if None in step:
            return f"step {t}: robot {step.index(None)} jumps"
        _, _, err = apply(grid, pos, orient, np.array(step))
        if err:
            return f"step {t}: {err}"
    return None


def _after(grid, p, o, a):
    h, w = grid.shape
    r, c = divmod(p, w)
    if a == F:
        r, c = r + DR[o], c + DC[o]
        if not (0 <= r < h and 0 <= c < w) or grid[r, c]:
            return None
    return (r * w + c) * 4 + (o + (a == R) - (a == C)) % 4


def oriented_distances(grid, goal):
    """Fewest actions from every (cell, orientation) to ``goal`` (any orientation): forward BFS per source."""
    h, w = grid.shape
    out = {}
    for p in np.flatnonzero(~grid.reshape(-1)).tolist():
        for o in range(4):
            seen, queue = {(p, o): 0}, deque([(p, o)])
            while queue:
                q, d = queue.popleft()
                if q == goal:
                    out[p * 4 + o] = seen[(q, d)]
                    break
                for a in (F, R, C):
                    s = _after(grid, q, d, a)
                    if s is not None and (s >> 2, s & 3) not in seen:
                        seen[(s >> 2, s & 3)] = seen[(q, d)] + 1
                        queue.append((s >> 2, s & 3))
    return out


def crowd(rng, h, w, density, fill):
    grid = rng.random((h, w)) < density
    free = np.flatnonzero(~grid.reshape(-1))
    n = max(1, int(round(fill * len(free))))
    pos = rng.choice(free, size=n, replace=False).astype(np.int64)
    goals = np.where(rng.random(n) < 0.2, pos, rng.choice(free, size=n)).astype(np.int64)
    return grid, free, pos, rng.integers(0, 4, size=n).astype(np.int64), goals


def retarget(rng, free, pos, goals):
    return np.where((pos == goals) & (rng.random(len(pos)) < 0.8), rng.choice(free, size=len(pos)), goals)


@pytest.mark.parametrize("seed", range(6))
def test_dense_crowds_only_get_valid_joint_actions_and_conflict_free_plans(seed):
    rng = np.random.default_rng(200 + seed)
    grid, free, pos, orient, goals = crowd(rng, int(rng.integers(8, 17)), int(rng.integers(8, 17)),
                                           0.1 + 0.03 * seed, 0.5 + 0.05 * seed)
    options = [{}, {"window": 2}, {"window": 3, "passes": 2}, {"expansions": 3, "rollouts": 3},
               {"bfs_budget": 1, "work": 40},
               {"window": 12, "patience": 0, "guidance": 3}][seed]
    ex = make_turning_executor("windowed", grid, seed=seed, **options)
    moved = reached = 0
    for step in range(60):
        act = ex.actions(pos, orient, goals)
        assert act.dtype == np.int64 and act.shape == pos.shape
        assert ex.repairs == 0  # valid by construction: the repair pass never acts
        assert np.array_equal(ex.paths[:, 0], pos * 4 + orient)
        assert plan_problem(grid, ex.paths) is None, f"step {step}"
        pos2, orient, err = apply(grid, pos, orient, act)
        assert err is None, f"step {step}: {err}"
        assert np.array_equal(ex.paths[:, 1], pos2 * 4 + orient)  # the plan's first step is what runs
        moved += int((pos2 != pos).sum())
        pos = pos2
        reached += int((pos == goals).sum())
        goals = retarget(rng, free, pos, goals)
    assert moved > 0 and reached > 0


def test_one_rollout_and_no_pass_is_turning_pibt_and_a_pass_never_makes_a_plan_worse():
    rng = np.random.default_rng(5)
    grid, free, pos, orient, goals = crowd(rng, 12, 12, 0.15, 0.5)
    pibt, zero = TurningPIBT(grid, seed=3, guidance=0), WindowedTurningPlanner(grid, seed=3, passes=0, rollouts=1)
    p, o, g = pos, orient, goals
    for _ in range(30):
        act = zero.actions(p, o, g)
        assert act.tolist() == pibt.actions(p, o, g).tolist()
        p, o, _ = apply(grid, p, o, act)
        g = retarget(rng, free, p, g)
    dist = {gl: oriented_distances(grid, gl) for gl in set(g.tolist())}

    def cost(paths):
        on_goal = (paths[:, :-1] >> 2 == g[:, None]) & (paths[:, 1:] >> 2 == g[:, None])
        last = [dist[gl].get(s, 1 << 24) for gl, s in zip(g.tolist(), paths[:, -1].tolist())]
        return (~on_goal).sum(axis=1) + np.array(last)

    costs = []
    for passes in (0, 1, 2):
        ex = WindowedTurningPlanner(grid, seed=3, passes=passes)
        ex.actions(p, o, g)
        costs.append(cost(ex.paths))
    assert (costs[1] <= costs[0]).all() and (costs[2] <= costs[1]).all() and costs[1].sum() < costs[0].sum()


def test_with_guidance_one_rollout_and_no_pass_is_guided_turning_pibt():
    rng = np.random.default_rng(6)
    grid, free, pos, orient, goals = crowd(rng, 12, 12, 0.15, 0.5)
    pibt = TurningPIBT(grid, seed=4, guidance=3)
    zero = WindowedTurningPlanner(grid, seed=4, passes=0, rollouts=1, guidance=3)
    for _ in range(30):
        act = zero.actions(pos, orient, goals)
        assert act.tolist() == pibt.actions(pos, orient, goals).tolist()
        pos, orient, _ = apply(grid, pos, orient, act)
        goals = retarget(rng, free, pos, goals)


def test_a_robot_that_stays_put_longer_than_its_patience_keeps_the_pibt_plan():
    rng = np.random.default_rng(8)
    grid, free, pos, orient, goals = crowd(rng, 10, 10, 0.2, 0.7)
    ex = WindowedTurningPlanner(grid, seed=2, window=6, patience=2)
    kept = 0
    for _ in range(40):
        rollout = WindowedTurningPlanner(grid, seed=2, window=6, passes=0)
        rollout.actions(pos, orient, goals)  # compiles and sizes the priorities, then the same state as ex:
        rollout.elapsed, rollout.t = ex.elapsed.copy(), ex.t
        rollout.actions(pos, orient, goals)
        act = ex.actions(pos, orient, goals)
        keep = ex.still > 2
        assert np.array_equal(ex.paths[keep], rollout.paths[keep])
        kept += int(keep.sum())
        pos, orient, err = apply(grid, pos, orient, act)
        assert err is None
        goals = retarget(rng, free, pos, goals)
    assert kept > 0


def test_big_fleets_get_fewer_rollouts_then_a_shorter_window():
    ex = WindowedTurningPlanner(np.zeros((4, 4), dtype=bool), window=16, rollouts=8, work=1 << 17)
    assert ex.effort(800) == (16, 8) and ex.effort(2000) == (16, 4) and ex.effort(10_000) == (13, 1)
    assert ex.effort(100_000) == (2, 1)


def test_orientation_fields_equal_a_forward_search():
    rng = np.random.default_rng(1)
    grid = rng.random((5, 6)) < 0.25
    grid[0, 0] = False
    ex = WindowedTurningPlanner(grid)
    goals = ex.cid[np.flatnonzero(~grid.reshape(-1))]
    fields = OrientFields(ex.nbr)
    rows = fields.rows(goals, np.arange(len(goals)))
    for gc, row in zip(goals.tolist(), rows.tolist()):
        want = oriented_distances(grid, int(ex.cell_of[gc]))
        for v, cell in enumerate(ex.cell_of.tolist()):
            for o in range(4):
                assert fields.fields[row, v * 4 + o] == want.get(cell * 4 + o, fields.far)


def guided_oriented_costs(grid, goal, weight):
    """Least cost from every (cell, orientation) to ``goal`` (a turn 1, F its lane cost): forward Dijkstra per source."""
    out = {}
    for p in np.flatnonzero(~grid.reshape(-1)).tolist():
        for o in range(4):
            best, heap = {(p, o): 0}, [(0, p, o)]
            while heap:
                d, q, e = heapq.heappop(heap)
                if d > best[(q, e)]:
                    continue
                if q == goal:
                    out[p * 4 + o] = d
                    break
                for a in (F, R, C):
                    s = _after(grid, q, e, a)
                    if s is not None:
                        nd = d + (lane_cost(grid, q, e, weight) if a == F else 1)
                        if nd < best.get((s >> 2, s & 3), 1 << 40):
                            best[(s >> 2, s & 3)] = nd
                            heapq.heappush(heap, (nd, s >> 2, s & 3))
    return out


def test_guided_orientation_fields_equal_a_forward_search():
    rng = np.random.default_rng(4)
    grid = rng.random((5, 6)) < 0.25
    grid[0, 0] = False
    ex = WindowedTurningPlanner(grid, guidance=2)
    goals = ex.cid[np.flatnonzero(~grid.reshape(-1))]
    rows = ex.ofields.rows(goals, np.arange(len(goals)))
    for gc, row in zip(goals.tolist(), rows.tolist()):
        want = guided_oriented_costs(grid, int(ex.cell_of[gc]), 2)
        for v, cell in enumerate(ex.cell_of.tolist()):
            for o in range(4):
                assert ex.ofields.fields[row, v * 4 + o] == want.get(cell * 4 + o, ex.ofields.far)


@pytest.mark.parametrize("window", [2, 8])
def test_robots_reach_their_goals_on_an_open_map(window):
    rng = np.random.default_rng(3)
    grid = np.zeros((8, 8), dtype=bool)
    grid[3, 2:6] = True
    cells = rng.choice(np.flatnonzero(~grid.reshape(-1)), size=24, replace=False).astype(np.int64)
    pos, goals, orient = cells[:12], cells[12:], rng.integers(0, 4, size=12)
    ex = WindowedTurningPlanner(grid, seed=5, window=window)
    for _ in range(60):
        pos, orient, err = apply(grid, pos, orient, ex.actions(pos, orient, goals))
        assert err is None
        if np.array_equal(pos, goals):
            break
    assert np.array_equal(pos, goals)


def test_a_lone_robot_takes_a_shortest_route_with_turns():
    grid = np.zeros((3, 5), dtype=bool)  # from (0, 0) facing north to (2, 4): 6 forward moves and 2 turns
    ex = WindowedTurningPlanner(grid, window=8)
    pos, orient, goal = np.array([0]), np.array([3]), np.array([14])
    steps = 0
    while pos[0] != 14:
        pos, orient, err = apply(grid, pos, orient, ex.actions(pos, orient, goal))
        assert err is None
        steps += 1
    assert steps == 8


def test_same_seed_same_actions():
    runs = []
    for seed in (4, 4, 9):
        rng = np.random.default_rng(11)
        grid, free, pos, orient, goals = crowd(rng, 12, 12, 0.2, 0.6)
        ex = WindowedTurningPlanner(grid, seed=seed, window=6)
        seq = []
        for _ in range(40):
            act = ex.actions(pos, orient, goals)
            seq.append(act.tolist())
            pos, orient, _ = apply(grid, pos, orient, act)
            goals = retarget(rng, free, pos, goals)
        runs.append(seq)
    assert runs[0] == runs[1] and runs[0] != runs[2]


def test_bad_input_names_the_value():
    grid = np.zeros((3, 4), dtype=bool)
    grid[1, 1] = True  # cell 5
    ex = WindowedTurningPlanner(grid)
    ok = dict(pos=np.array([0, 2]), orient=np.array([0, 1]), goals=np.array([3, 11]))
    cases = [
        (dict(pos=np.array([0])), r"one entry per robot, got lengths 1, 2, 2"),
        (dict(orient=np.array([0, 4])), r"orient\[1\] = 4 is not an orientation 0..3"),
        (dict(pos=np.array([0, 5])), r"pos\[1\] = 5 \(row 1, col 1\) is a blocked cell"),
        (dict(goals=np.array([5, 1])), r"goals\[0\] = 5 \(row 1, col 1\) is a blocked cell"),
        (dict(goals=np.array([0, -1])), r"goals\[1\] = -1 is off the map \(flat cells 0..11\)"),
        (dict(pos=np.array([2, 2])), r"robots 0 and 1 share cell 2"),
        (dict(pos=np.array([0.5, 2.0])), r"pos must hold integers, got dtype float64"),
    ]
    for change, message in cases:
        with pytest.raises(ValueError, match=message):
            ex.actions(**{**ok, **change})
    for option, message in [({"window": 1}, r"window = 1 must be an integer in \[2, 64\]"),
                            ({"window": 65}, r"window = 65 must be an integer in \[2, 64\]"),
                            ({"window": 2.5}, r"window = 2.5 must be an integer in \[2, 64\]"),
                            ({"expansions": 0}, r"expansions = 0 must be an integer in \[1, "),
                            ({"passes": -1}, r"passes = -1 must be an integer in \[0, 1024\]"),
                            ({"passes": True}, r"passes = True must be an integer in \[0, 1024\]"),
                            ({"rollouts": 0}, r"rollouts = 0 must be an integer in \[1, 1024\]"),
                            ({"patience": -2}, r"patience = -2 must be an integer in \[0, "),
                            ({"work": 0}, r"work = 0 must be an integer in \[1, ")]:
        with pytest.raises(ValueError, match=message):
            WindowedTurningPlanner(grid, **option)
    with pytest.raises(ValueError, match="unknown turning executor 'cbs'; known: pibt, windowed"):
        make_turning_executor("cbs", grid)
    assert TURNING_EXECUTORS["windowed"] is WindowedTurningPlanner and ex.name == "windowed"
    assert apply(grid, ok["pos"], ok["orient"], ex.actions(**ok))[2] is None  # still usable after the errors
