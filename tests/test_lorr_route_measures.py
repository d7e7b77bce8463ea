"""The League measurement scripts' own logic: the least-action bounds against a slow oracle, legs from both output
formats, every leg's steps at or above its bound, the waits' replay against the simulator, the record holder's
thread patch."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
from benchmark_modules import load

from agents.lorr.run import run_lorr
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.output import output_dict

detours = load("lorr_detours")
waits = load("lorr_waits")
holder = load("record_holder")


def oracle_bound(grid: np.ndarray, goal: int) -> np.ndarray:
    """Least actions (F, R, C) from every (cell, orientation) to ``goal``: a forward BFS from each state."""
    h, w = grid.shape
    out = np.full((h * w, 4), np.inf)
    steps = ((0, 1), (1, 0), (0, -1), (-1, 0))
    for p in range(h * w):
        if grid.reshape(-1)[p]:
            continue
        for o in range(4):
            seen = {(p, o): 0}
            q = deque([(p, o)])
            while q:
                c, d = q.popleft()
                if c == goal:
                    out[p, o] = seen[(c, d)]
                    break
                r, col = divmod(c, w)
                nxt = [(c, (d + 1) % 4), (c, (d + 3) % 4)]
                rr, cc = r + steps[d][0], col + steps[d][1]
                if 0 <= rr < h and 0 <= cc < w and not grid[rr, cc]:
                    nxt.append((rr * w + cc, d))
                for s in nxt:
                    if s not in seen:
                        seen[s] = seen[(c, d)] + 1
                        q.append(s)
    return out


def test_the_bounds_are_the_oracles_least_actions():
    rng = np.random.default_rng(3)
    grid = rng.random((6, 7)) < 0.25
    grid[2, 3] = False
    bounds = detours.Bounds(grid)
    oriented, cells = bounds(2 * 7 + 3)
    expect = oracle_bound(grid, 2 * 7 + 3)
    free = ~grid.reshape(-1)
    reach = np.isfinite(expect[free])
    assert np.array_equal(oriented[free][reach], expect[free][reach])
    assert np.all(np.isinf(oriented[free][~reach]))
    # the cells' distance never exceeds the least actions, and equals them facing the right way on a straight line
    assert np.all(cells[free][reach.all(axis=1)] <= oriented[free][reach.all(axis=1)].min(axis=1))


def test_legs_read_both_formats():
    w = 10
    record = {"tasks": [[0, 1, 2], [1, 3, 4]], "events": [[[0, 0, "assigned"], [0, 5, "finished"], [1, 5, "assigned"],
                                                           [1, 9, "finished"]]]}
    assert detours.legs(record, w) == [(0, 0, 5, 12, True), (0, 5, 9, 34, True)]
    ours = {"tasks": [[0, 0, [1, 2, 3, 4]]], "events": [[4, 0, 0, 1], [7, 0, 0, 2]]}
    assert detours.legs(ours, w) == [(0, 0, 4, 12, True), (0, 4, 7, 34, False)]


@pytest.fixture(scope="module")
def example_run():
    inst = read_instance(example_instance_path())
    rec, sim, _ = run_lorr(inst, "lorr-greedy", "pibt", steps=60)
    return inst, rec, sim


def test_every_leg_takes_at_least_its_bound_and_the_actions_add_up(example_run):
    inst, rec, sim = example_run
    data = output_dict(sim)
    bounds = detours.Bounds(inst.grid)
    (m,) = detours.measure(inst, data, bounds)
    assert m["legs"] == sim.tasks.errands_done == len(sim.tasks.events)
    assert m["forward"] + m["turns"] + m["waits"] == m["steps"]
    assert m["distance"] <= m["bound"] <= m["steps"]
    for r, t0, t1, goal, _ in detours.legs(data, inst.width):  # leg by leg, from the simulator's own record
        oriented, _ = bounds(goal)
        pos, ori = sim.start_pos.copy(), sim.start_orient.copy()
        from mrmt_env.lorr.rules import next_states

        for a in sim.actual[:t0]:
            pos, ori = next_states(pos, ori, a.astype(np.int64), inst.width)
        assert oriented[pos[r], ori[r]] <= t1 - t0
    halves = detours.measure(inst, data, bounds, windows=2)
    assert sum(h["legs"] for h in halves) == m["legs"] and sum(h["steps"] for h in halves) == m["steps"]


def test_the_waits_replay_counts_every_robot_step_once(example_run):
    inst, rec, sim = example_run
    wait, turn, move, per_step = waits.replay(sim)
    actions = np.array(sim.actual)
    assert wait.sum() + turn.sum() + move.sum() == sim.n_robots * sim.t
    assert wait.sum() == per_step.sum() == int(((actions == 3) | (actions == -1)).sum())
    assert move.sum() == int((actions == 0).sum())


def test_narrow_cells_count_free_neighbours():
    grid = np.array([[0, 0, 0], [1, 0, 1], [0, 0, 0]], dtype=bool)
    narrow = waits.narrow_cells(grid.reshape(-1), 3).reshape(3, 3)
    assert narrow.tolist() == [[True, False, True], [False, True, False], [True, False, True]]


def test_the_record_holders_threads_are_set_or_refused(tmp_path):
    text = "x\nstatic constexpr uint32_t THREADS = 32;\ny\n"
    assert holder.THREADS.sub(r"\g<1>2;", text) == "x\nstatic constexpr uint32_t THREADS = 2;\ny\n"
    assert holder.THREADS.search("constexpr int THREADS = 32;") is None
