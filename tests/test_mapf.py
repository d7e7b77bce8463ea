"""The one-step MAPF executors: PIBT against its recursive Python oracle, conflict-freedom of both."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from mrmt_env import generate_world
from mrmt_env.distances import bfs_distance_field
from planners.mapf import PIBT, WindowedPlanner, make_executor

MASK = (1 << 64) - 1


def _splitmix(z: int) -> int:
    z = (z + 0x9E3779B97F4A7C15) & MASK
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
    return z ^ (z >> 31)


def _mix(seed, a, b, c) -> int:
    z = _splitmix(seed)
    for v in (a, b, c):
        z = _splitmix(z ^ v)
    return z


def successors(grid):
    """Per flat cell ``r * W + c``: the cell itself, then up, down, left, right (a move into an obstacle or
    off the grid stays)."""
    h, w = grid.shape
    out = []
    for p in range(h * w):
        r, c = divmod(p, w)
        row = [p]
        for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
            rr, cc = r + dr, c + dc
            row.append(rr * w + cc if 0 <= rr < h and 0 <= cc < w and not grid[rr, cc] else p)
        out.append(row)
    return out


class OraclePriorities:
    """PIBT's priorities as documented (planners/mapf/pibt/grid.py), kept here: robot ``k``'s priority is the
    steps since it last stood on its goal (``elapsed``, 0 at the start and on the goal) plus a tie-breaker
    drawn once from ``np.random.default_rng(seed)`` in [0, 1); robots plan in decreasing priority."""

    def __init__(self, seed, n_robots):
        self.elapsed = [0] * n_robots
        self.tie = np.random.default_rng(seed).random(n_robots).tolist()

    def order(self):
        return sorted(range(len(self.tie)), key=lambda k: -(self.elapsed[k] + self.tie[k]))

    def advance(self, nxt, goals):
        self.elapsed = [0 if v == g else e + 1 for v, g, e in zip(nxt, goals, self.elapsed)]


def pibt_oracle(grid, pos, goals, order, seed, t):
    """PIBT as published (recursive funcPIBT), same candidate order as the kernel."""
    succ = successors(grid)
    fields = {g: bfs_distance_field(grid, divmod(g, grid.shape[1])).reshape(-1).tolist() for g in set(goals)}
    occ_now = {p: k for k, p in enumerate(pos)}
    occ_next: dict[int, int] = {}
    nxt = [None] * len(pos)

    def cands(a):
        cells = list(dict.fromkeys(succ[pos[a]]))
        f = fields[goals[a]]
        return sorted(cells, key=lambda v: (f[v] if f[v] >= 0 else 1 << 40, _mix(seed, t, a, v)))

    def func(a, b):
        for v in cands(a):
            if v in occ_next or (b is not None and v == pos[b]):
                continue
            occ_next[v] = a
            nxt[a] = v
            c = occ_now.get(v)
            if c is not None and nxt[c] is None and not func(c, a):
                continue
            return True
        occ_next[pos[a]] = a
        nxt[a] = pos[a]
        return False

    for a in order:
        if nxt[a] is None:
            func(a, None)
    return nxt


def _instance(seed, n_robots, h=8, w=9, density=0.15):
    world = generate_world(seed, height=h, width=w, obstacle_density=density, n_robots=n_robots, n_targets=n_robots)
    rng = np.random.default_rng(seed)
    pos = world.robots[:, 0] * w + world.robots[:, 1]
    goals = world.targets[:, 0] * w + world.targets[:, 1]
    goals = np.where(rng.random(n_robots) < 0.2, pos, goals)  # some robots have no task: goal = own cell
    return world.grid, pos.astype(np.int64), goals.astype(np.int64)


def _conflict_free(pos, nxt, succ):
    assert len(set(nxt.tolist())) == len(nxt)  # no vertex conflict
    for k in range(len(pos)):
        assert nxt[k] in succ[pos[k]]  # stay or a legal move
        for j in range(len(pos)):
            assert not (j != k and nxt[k] == pos[j] and nxt[j] == pos[k] and nxt[k] != pos[k])  # no swap


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), n_robots=st.integers(1, 30))
def test_pibt_kernel_equals_recursive_oracle(seed, n_robots):
    grid, pos, goals = _instance(seed, n_robots)
    planner = PIBT(grid, seed=seed)
    priorities = OraclePriorities(seed, n_robots)  # the oracle's own: nothing read from the planner
    for step in range(6):
        expect = pibt_oracle(grid, pos.tolist(), goals.tolist(), priorities.order(), seed, step)
        priorities.advance(expect, goals.tolist())
        nxt = planner.step(pos, goals)
        assert nxt.tolist() == expect
        _conflict_free(pos, nxt, successors(grid))
        pos = nxt


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10**6), n_robots=st.integers(1, 30), window=st.integers(1, 6))
def test_windowed_moves_are_conflict_free(seed, n_robots, window):
    grid, pos, goals = _instance(seed, n_robots)
    planner = WindowedPlanner(grid, seed=seed, window=window)
    succ = successors(grid)
    for _ in range(6):
        nxt = planner.step(pos, goals)
        _conflict_free(pos, nxt, succ)
        pos = nxt


@pytest.mark.parametrize("name", ["pibt", "windowed"])
def test_executors_bring_every_robot_to_its_goal(name):
    grid = np.zeros((6, 7), dtype=bool)
    grid[2, 1:6] = True  # a wall with passages at both ends
    rng = np.random.default_rng(0)
    cells = rng.choice(np.flatnonzero(~grid.reshape(-1)), size=16, replace=False)
    pos, goals = cells[:8].astype(np.int64), cells[8:].astype(np.int64)
    ex = make_executor(name, grid, seed=1)
    for _ in range(60):
        pos = ex.step(pos, goals)
        if np.array_equal(pos, goals):
            break
    assert np.array_equal(pos, goals)


def test_actions_walk_the_planned_moves_and_bad_names():
    grid = np.zeros((3, 3), dtype=bool)
    ex = PIBT(grid)
    assert ex.actions(np.array([4]), np.array([1])).tolist() == [1]  # centre -> up
    with pytest.raises(ValueError, match="unknown executor 'cbs'; known: pibt, windowed"):
        make_executor("cbs", grid)
    with pytest.raises(ValueError, match=r"window must be an integer in 1..64, got 0"):
        WindowedPlanner(grid, window=0)
