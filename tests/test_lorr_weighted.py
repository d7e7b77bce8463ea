"""``lorr-weighted``: the winner's measure as a global greedy matching, checked against a plain Python oracle."""

from __future__ import annotations

import itertools
import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lorr_reference import bfs as _bfs

from mrmt_env.lorr.output import check_output, output_dict
from agents.lorr.run import run_lorr
from agents.lorr.schedulers import make_scheduler
from agents.lorr.weighted import Crowd, WeightedScheduler, optimal_matching, weighted_matching
from mrmt_env.lorr.instance import example_instance_path, read_instance
from mrmt_env.lorr.sim import LoRRSimulator


def _oracle(dist, robots, first, legs, ids, weight, jam=0, block_of=None, load=None):
    """Repeatedly the pair of least (cost, robot, first cell, legs, id) among the robots and tasks left; the cost
    adds ``jam`` per robot in or sent to the first cell's block (``load``, grown by each pair made)."""
    left, out = set(range(len(first))), {}
    todo = set(range(len(robots)))
    load = dict(load or {})
    while todo and left:
        cands = [(weight * dist[first[k]][robots[i]] + legs[k] + (jam * load[block_of(first[k])] if jam else 0),
                  i, first[k], legs[k], ids[k], k)
                 for i in todo for k in left if dist[first[k]][robots[i]] >= 0]
        if not cands:
            break
        *_, k = min(cands)
        i = min(cands)[1]
        out[i] = k
        todo.discard(i)
        left.discard(k)
        if jam:
            load[block_of(first[k])] += 1
    return out


@settings(max_examples=80, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 6), st.sampled_from([0, 0, 1, 3]), st.integers(1, 4))
def test_the_matching_is_the_global_greedy_of_the_oracle(seed, weight, jam, side):
    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(3, 10)), int(rng.integers(3, 10))
    grid = rng.random((h, w)) < 0.3
    free = np.flatnonzero(~grid.reshape(-1))
    if len(free) < 2:
        return
    robots = rng.choice(free, size=int(rng.integers(1, len(free))), replace=False).astype(np.int64)
    n = int(rng.integers(1, 2 * len(free)))
    first = rng.choice(free, size=n).astype(np.int64)     # tasks share cells
    legs = rng.integers(0, 9, n).astype(np.int64)
    ids = rng.permutation(n).astype(np.int64) * 7
    dist = {int(c): _bfs(grid, int(c)) for c in np.unique(first)}
    order = np.lexsort((ids, legs, first))
    cells, start = np.unique(first[order], return_index=True)
    way = np.array([[dist[int(c)][r] for c in cells] for r in robots.tolist()], dtype=np.int32)
    out = np.empty(len(robots), dtype=np.int64)
    across = -(-w // side)

    def block_of(c):
        return (c // w // side) * across + c % w // side

    load = rng.integers(0, 4, -(-h // side) * across).astype(np.int64)
    crowd = Crowd(np.array([block_of(int(c)) for c in cells], dtype=np.int64), load.copy(), jam)
    made = weighted_matching(way, np.append(start, n).astype(np.int64), legs[order], weight, out, crowd)
    want = _oracle(dist, robots.tolist(), first.tolist(), legs.tolist(), ids.tolist(), weight, jam, block_of,
                   dict(enumerate(load.tolist())))
    got = {i: int(order[s]) for i, s in enumerate(out.tolist()) if s >= 0}
    assert got == want and made == len(want)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 12))
def test_the_optimal_matching_is_the_least_total_of_every_matching(seed, weight):
    """Every injective choice of slots (or none) per robot enumerated: most reachable pairs, then least total."""
    rng = np.random.default_rng(seed)
    n, cells = int(rng.integers(1, 5)), int(rng.integers(1, 4))
    per_cell = rng.integers(1, 3, cells)
    cell_start = np.append(0, np.cumsum(per_cell)).astype(np.int64)
    slots = int(cell_start[-1])
    length = np.concatenate([np.sort(rng.integers(0, 9, k)) for k in per_cell]).astype(np.int64)
    way = rng.integers(0, 12, (n, cells)).astype(np.int32)
    way[rng.random((n, cells)) < 0.25] = -1  # cut off
    cell_of = np.repeat(np.arange(cells), per_cell)
    best = None
    for choice in itertools.product(range(-1, slots), repeat=n):
        taken = [c for c in choice if c >= 0]
        if len(taken) != len(set(taken)) or any(c >= 0 and way[i, cell_of[c]] < 0 for i, c in enumerate(choice)):
            continue
        key = (-len(taken), sum(weight * int(way[i, cell_of[c]]) + int(length[c]) for i, c in enumerate(choice)
                                if c >= 0))
        best = key if best is None or key < best else best
    out = np.empty(n, dtype=np.int64)
    made = optimal_matching(way, cell_start, length, weight, out)
    got = [int(c) for c in out]
    assert len(set(c for c in got if c >= 0)) == made == -best[0]
    assert all(way[i, cell_of[c]] >= 0 for i, c in enumerate(got) if c >= 0)
    assert sum(weight * int(way[i, cell_of[c]]) + int(length[c]) for i, c in enumerate(got) if c >= 0) == best[1]


def test_the_optimal_matching_beats_the_greedy_where_the_greedy_takes_the_shared_best():
    # robot 0 is 1 from cell A and 2 from B; robot 1 is 2 from A and 9 from B: greedy 1 + 9, optimal 2 + 2
    way = np.array([[1, 2], [2, 9]], dtype=np.int32)
    cell_start, length = np.array([0, 1, 2], dtype=np.int64), np.zeros(2, dtype=np.int64)
    greedy, best = np.empty(2, dtype=np.int64), np.empty(2, dtype=np.int64)
    weighted_matching(way, cell_start, length, 1, greedy, Crowd(np.zeros(2, np.int64), np.zeros(1, np.int64), 0))
    optimal_matching(way, cell_start, length, 1, best)
    assert greedy.tolist() == [0, 1] and best.tolist() == [1, 0]
    sim = LoRRSimulator(read_instance(example_instance_path()))
    proposal = WeightedScheduler(weight=10, optimal=True).schedule(sim)
    assert sim.tasks.check(proposal, 1) is None and (proposal >= 0).all()
    with pytest.raises(ValueError, match=r"optimal=true takes no jam term \(jam=2"):
        WeightedScheduler(optimal=True, jam=2)


def test_a_robot_whose_task_is_not_opened_gives_it_to_a_closer_robot():
    sim = LoRRSimulator(read_instance(example_instance_path()))
    sched = WeightedScheduler(weight=5)
    proposal = sched.schedule(sim)
    assert sim.tasks.check(proposal, 1) is None
    assert (proposal >= 0).all()  # 12 open tasks, 8 robots, all reachable
    # a second scheduler's view after robot 0 took robot 1's task by hand: the first step's choice comes back
    forced = proposal.copy()
    forced[0], forced[1] = proposal[1], proposal[0]
    sim.tasks.propose(forced, 1)
    again = WeightedScheduler(weight=5).schedule(sim)
    assert again.tolist() == proposal.tolist()
    kept = WeightedScheduler(weight=5, reassign=False).schedule(sim)
    assert kept.tolist() == forced.tolist()


def test_the_jam_term_counts_robots_standing_and_bound_per_block():
    sim = LoRRSimulator(read_instance(example_instance_path()))
    proposal = WeightedScheduler().schedule(sim)
    sim.tasks.propose(proposal, 1)
    sched = WeightedScheduler(jam=2, block=3)
    cells = np.flatnonzero(~sim.inst.grid.reshape(-1))[:10]
    crowd = sched.crowd(sim, proposal, cells)
    h, w = sim.inst.grid.shape
    count = {}
    for k in range(len(sim.pos)):  # an independent count: where each robot stands, where its task sends it
        for cell in (int(sim.pos[k]), sim.tasks.errands_of(int(proposal[k]))[0] if proposal[k] >= 0 else None):
            if cell is not None:
                key = (cell // w // 3, cell % w // 3)
                count[key] = count.get(key, 0) + 1
    across = -(-w // 3)
    assert {(b // across, b % across): int(v) for b, v in enumerate(crowd.load) if v} == count
    assert crowd.block.tolist() == [(int(c) // w // 3) * across + int(c) % w // 3 for c in cells]
    assert crowd.weight == 2 and not WeightedScheduler().crowd(sim, proposal, cells).load.any()
    for bad, match in (({"jam": -1}, r"jam = -1 must be an integer in \[0, 1000\]"),
                       ({"block": 0}, r"block = 0 must be an integer in \[1, 4096\]"), ({"jam": 1.5}, "jam = 1.5 must be")):
        with pytest.raises(ValueError, match=match):
            WeightedScheduler(**bad)


def test_every_task_costs_the_winners_measure_from_bfs():
    sim = LoRRSimulator(read_instance(example_instance_path()))
    sched = WeightedScheduler(weight=3)
    sched.reset(sim)
    grid = sim.inst.grid
    ids = sorted(sim.tasks.open)
    got = sched.legs(sim.tasks, ids)
    for k, v in zip(ids, got.tolist()):
        e = sim.tasks.errands_of(k)
        assert v == sum(int(_bfs(grid, int(a))[int(b)]) for a, b in zip(e[:-1], e[1:]))


def test_a_run_rechecks_to_its_count():
    record, sim, step_s = run_lorr(example_instance_path(), "lorr-weighted", "pibt", steps=120, seed=0)
    assert record["scheduler"] == "lorr-weighted"
    assert record["errors"] == 0 and record["schedule_errors"] == 0
    data = json.loads(json.dumps(output_dict(sim, step_s)))
    result = check_output(read_instance(example_instance_path()), data)
    assert result.tasks_finished == record["tasks_finished"] == sim.finished > 5


def test_tables_stay_within_the_memory_asked():
    sim = LoRRSimulator(read_instance(example_instance_path()))
    sched = WeightedScheduler(memory_mb=1)
    sched.reset(sim)
    assert sched.fields.fields.nbytes <= 1 << 20


@pytest.mark.parametrize("options, needle", [
    ({"weight": -1}, "weight = -1 must be an integer in [0, 1000]"),
    ({"weight": 2.5}, "weight = 2.5 must be an integer in [0, 1000]"),
    ({"reassign": "yes"}, "reassign = 'yes' must be true or false"),
    ({"memory_mb": 0}, "memory_mb = 0 must be an integer in [1, 1048576]"),
    ({"radius": 3}, "lorr-weighted takes no option 'radius'; its options: weight, reassign, memory_mb, jam, block"),
])
def test_bad_options_name_the_option_and_the_limit(options, needle):
    with pytest.raises(ValueError) as exc:
        make_scheduler("lorr-weighted", **options)
    assert needle in str(exc.value)


def _mrmt(*args):
    import subprocess
    import sys

    return subprocess.run([sys.executable, "-m", "agents.cli", *args], capture_output=True, text=True, timeout=600)


def test_scheduler_options_reach_the_scheduler_and_the_record():
    p = _mrmt("lorr", "run", str(example_instance_path()), "--scheduler", "lorr-weighted", "--scheduler-option",
              "weight=1", "--scheduler-option", "reassign=false", "--steps", "30", "--json", "--no-progress")
    assert p.returncode == 0, p.stderr
    record = json.loads(p.stdout.strip().splitlines()[-1])
    assert record["scheduler_options"] == {"weight": 1, "reassign": False}


@pytest.mark.parametrize("item, needle", [("weight=x", "weight = 'x' must be an integer in [0, 1000]"),
                                          ("weight", "--scheduler-option 'weight' must look like KEY=VALUE")])
def test_a_bad_scheduler_option_is_one_line_and_exit_2(item, needle):
    p = _mrmt("lorr", "run", str(example_instance_path()), "--scheduler", "lorr-weighted", "--scheduler-option", item,
              "--steps", "5")
    assert p.returncode == 2 and needle in p.stderr and len(p.stderr.strip().splitlines()) == 1


def test_an_entry_gives_its_scheduler_options(tmp_path):
    from agents.lorr.entry import load_entry

    f = tmp_path / "e.toml"
    f.write_text('[[rule]]\nscheduler = "lorr-weighted"\nplanner = "pibt"\nscheduler_options = { weight = 2 }\n')
    choice = load_entry(f).choose(read_instance(example_instance_path()))
    assert choice.scheduler.options == {"weight": 2}
    f.write_text('[[rule]]\nscheduler = "lorr-weighted"\nplanner = "pibt"\nscheduler_options = 3\n')
    with pytest.raises(ValueError, match="scheduler_options must be a table of the scheduler's options"):
        load_entry(f)


def test_goal_fields_keep_only_the_tables_asked_and_reuse_the_rows_of_the_rest():
    from planners.mapf.common import GoalFields

    grid = read_instance(example_instance_path()).grid
    free = np.flatnonzero(~grid.reshape(-1))[:5]
    fields = GoalFields(grid, capacity=8)
    rows = fields.rows(free)
    want = {int(c): fields.fields[r].copy() for c, r in zip(free, rows)}
    fields.keep([int(free[3]), int(free[1])])
    assert len(fields) == 2 and fields.has(int(free[3])) and not fields.has(int(free[0]))
    kept_rows = fields.rows(free[[3, 1]]).tolist()
    assert kept_rows == [rows[3], rows[1]]  # kept fields stay where they were: nothing is copied
    more = np.flatnonzero(~grid.reshape(-1))[5:11]  # six new goals: three freed rows reused, then new ones
    assert sorted(fields.rows(more).tolist()) == sorted([rows[0], rows[2], rows[4], 5, 6, 7])
    for c in free.tolist():
        assert (fields.fields[fields.rows(np.array([c]))[0]] == want[c]).all()
        assert (want[c] == _bfs(grid, c)).all()


@pytest.mark.parametrize("name", ["lorr-greedy", "lorr-weighted", "strong"])
def test_every_scheduler_plays_the_start_kits_scheduler_role(name):
    from agents.lorr.roles import Scheduler

    assert isinstance(make_scheduler(name), Scheduler)


def test_every_planner_plays_the_start_kits_planner_role():
    from agents.lorr.roles import Planner
    from planners.mapf import TURNING_PLANNERS, make_turning_planner

    grid = read_instance(example_instance_path()).grid
    for name in TURNING_PLANNERS:
        assert isinstance(make_turning_planner(name, grid), Planner), name


def test_turns_added_to_the_way_are_the_fewest_before_a_shortest_first_move():
    """``add_turns`` against a plain count: for every robot cell, orientation and goal of a random map, the way plus
    the fewest turns (0-2) to face a neighbour one move closer."""
    from agents.lorr.weighted import add_turns
    from planners.mapf.common import GoalFields

    rng = np.random.default_rng(4)
    grid = rng.random((7, 9)) < 0.25
    free = np.flatnonzero(~grid.reshape(-1))
    fields = GoalFields(grid, capacity=64)
    goals = free[:12]
    rows = fields.rows(goals)
    pos = np.repeat(free, 4)
    orient = np.tile(np.arange(4), len(free))
    way = np.ascontiguousarray(fields.fields[np.ix_(rows, pos)].T)
    plain = way.astype(np.int64)
    add_turns(fields.fields, rows, pos, orient, fields.grid, 9, way)
    step = {0: (0, 1), 1: (1, 0), 2: (0, -1), 3: (-1, 0)}
    for i, (p, o) in enumerate(zip(pos.tolist(), orient.tolist())):
        r, c = divmod(p, 9)
        for j, g in enumerate(goals.tolist()):
            f = plain[i, j]
            if f <= 0:
                assert way[i, j] == f
                continue
            closer = [d for d, (dr, dc) in step.items() if 0 <= r + dr < 7 and 0 <= c + dc < 9
                      and not grid[r + dr, c + dc] and _bfs(grid, g)[(r + dr) * 9 + c + dc] == f - 1]
            assert way[i, j] == f + min({0: 0, 1: 1, 2: 2, 3: 1}[(d - o) % 4] for d in closer)
