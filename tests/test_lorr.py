"""League of Robot Runners: the instance reader, the MAPF_T rules, the task rules, the record replays."""

from __future__ import annotations

import json
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from lorr_reference import bfs as _bfs

from mrmt_env.lorr.greedy import GreedyScheduler
from mrmt_env.lorr.instance import LoRRFormatError, example_instance_path, read_instance
from mrmt_env.lorr.rules import first_error, next_states, parse_actions
from mrmt_env.lorr.sim import LoRRSimulator

SHARED = Path(__file__).resolve().parents[2] / "shared" / "lorr"
needs_shared = pytest.mark.skipif(not SHARED.is_dir(), reason="the LoRR instances (shared/lorr) are not beside the checkout")


def _record(path: Path) -> dict:
    with zipfile.ZipFile(path) as z:
        return json.loads(z.read(z.namelist()[0]))


def _replay(instance, record) -> LoRRSimulator:
    acts = np.stack([parse_actions(p, f"robot {k}") for k, p in enumerate(record["actualPaths"])], axis=1)
    starts = np.array([r * instance.width + c for r, c, _ in record["start"]])
    assert np.array_equal(starts, instance.starts)
    sim = LoRRSimulator(instance)
    for a in acts:
        sim.step(a)
    return sim


# ---------------------------------------------------------------- conformance with the start kit
@needs_shared
def test_mr23_i04_record_replays_to_its_1741_errands():
    inst = read_instance(SHARED / "2023-main" / "random.domain" / "MR23-I-04.json")
    rec = _record(SHARED / "2023-main" / "best_solutions" / "MR23-I-04.json.zip")
    sim = _replay(inst, rec)
    assert sim.t == 500 and sim.errors == []
    assert sim.finished == rec["numTaskFinished"] == 1741
    # every errand event the start kit logged, at the same step, robot and task id
    theirs = sorted((t, k, task) for k, evs in enumerate(rec["events"]) for task, t, what in evs if what == "finished")
    assert sorted((t, a, task) for t, a, task, _ in sim.tasks.events) == theirs
    # the revealed tasks' cells are the start kit's ``tasks`` (id, row, col)
    assert [[k, r, c] for k, _, (r, c) in sim.tasks.task_records(inst.width)] == rec["tasks"][:sim.tasks.n_ids]


@needs_shared
def test_random01_record_replays_with_no_error():
    inst = read_instance(SHARED / "2024-main" / "random.domain" / "RANDOM-01.json")
    rec = _record(SHARED / "2024-main" / "best_solutions" / "MR24-RANDOM-01.json.zip")
    sim = _replay(inst, rec)
    assert sim.t == rec["makespan"] == 600
    assert sim.errors == [] and rec["numPlannerErrors"] == 0


@needs_shared
def test_a_corrupted_record_is_caught_at_the_step_it_breaks():
    inst = read_instance(SHARED / "2024-main" / "random.domain" / "RANDOM-01.json")
    rec = _record(SHARED / "2024-main" / "best_solutions" / "MR24-RANDOM-01.json.zip")
    paths = [p.split(",") for p in rec["actualPaths"]]
    # robot 0's first forward move made a wait: every robot ahead of it that moves into its cell collides
    sim = _replay(inst, dict(rec, actualPaths=[",".join(p) for p in paths]))
    assert sim.errors == []
    first_f = paths[0].index("F")
    paths[0][first_f] = "W"
    broken = LoRRSimulator(inst)
    acts = np.stack([parse_actions(",".join(p), "x") for p in paths], axis=1)
    for a in acts:
        broken.step(a)
    assert len(broken.errors) >= 1 or not np.array_equal(broken.pos, sim.pos)


@needs_shared
@pytest.mark.parametrize("name", ["RANDOM-01", "RANDOM-05", "CITY-01", "GAME", "WAREHOUSE", "SORTATION"])
def test_2024_instances_read(name):
    path = next((SHARED / "2024-main").glob(f"*/{name}.json"))
    inst = read_instance(path)
    table = json.loads((SHARED / "best_known.json").read_text())["2024-main"][name]
    assert inst.team_size == table[0] and inst.steps == table[1]
    assert inst.n_tasks == 100000 and inst.strategy is None and inst.open_target() == int(1.5 * table[0] + 0.5)
    assert not inst.grid.reshape(-1)[inst.starts].any() and not inst.grid.reshape(-1)[inst.errands].any()


# ---------------------------------------------------------------- the MAPF_T rules against the start kit's loop
def _oracle_is_valid(pos, orient, actions, grid):
    """ActionModelWithRotate::is_valid, line by line."""
    h, w = grid.shape
    moves = [1, w, -1, -w]
    nxt = [p + moves[o] if a == 0 else p for p, o, a in zip(pos, orient, actions)]
    vertex, edge = {}, {}
    for i, (p, q) in enumerate(zip(pos, nxt)):
        if q < 0 or q >= h * w or abs(q // w - p // w) + abs(q % w - p % w) > 1 or grid.flat[q]:
            return ("unallowed move", i, -1)
        if q in vertex:
            return ("vertex conflict", i, vertex[q])
        if (p, q) in edge:
            return ("edge conflict", i, edge[(p, q)])
        vertex[q] = i
        edge[(q, p)] = i
    return None


@settings(max_examples=300, deadline=None)
@given(st.data())
def test_first_error_is_the_start_kits(data):
    h = data.draw(st.integers(2, 6))
    w = data.draw(st.integers(2, 6))
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    grid = rng.random((h, w)) < 0.15
    free = np.flatnonzero(~grid.reshape(-1))
    if len(free) == 0:
        return
    r = data.draw(st.integers(1, len(free)))
    pos = rng.choice(free, size=r, replace=False).astype(np.int64)
    orient = rng.integers(0, 4, r)
    actions = rng.choice(4, size=r, p=[0.7, 0.1, 0.1, 0.1])
    nxt, nori = next_states(pos, orient, actions, w)
    assert first_error(pos, nxt, grid.reshape(-1)) == _oracle_is_valid(pos.tolist(), orient.tolist(), actions.tolist(), grid)
    assert np.array_equal(nori, np.where(actions == 1, (orient + 1) % 4, np.where(actions == 2, (orient + 3) % 4, orient)))


def test_forward_off_a_row_end_is_refused_not_wrapped():
    grid = np.zeros((3, 3), dtype=bool)
    pos = np.array([2], dtype=np.int64)  # row 0, col 2, facing east
    nxt, _ = next_states(pos, np.array([0]), np.array([0]), 3)
    assert first_error(pos, nxt, grid.reshape(-1)) == ("unallowed move", 0, -1)


def test_an_invalid_joint_action_makes_everyone_wait_and_is_counted():
    sim = LoRRSimulator(read_instance(example_instance_path()))
    before = sim.pos.copy()
    bad = np.full(sim.n_robots, 3)
    bad[:] = 0  # everyone forward: somebody leaves the map or hits something on this map
    nxt, _ = next_states(sim.pos, sim.orient, bad, sim.width)
    assert first_error(sim.pos, nxt, sim.blocked) is not None
    sim.step(bad)
    assert np.array_equal(sim.pos, before) and len(sim.errors) == 1 and sim.errors[0][3] == 1
    assert sim.actual[-1].tolist() == [3] * sim.n_robots and sim.planned[-1].tolist() == bad.tolist()


# ---------------------------------------------------------------- the 2024 task rules
def _free_sim():
    return LoRRSimulator(read_instance(example_instance_path()))


def test_pool_keeps_ceil_reveal_times_team_tasks_open_and_refills_in_file_order():
    sim = _free_sim()
    pool = sim.tasks
    assert len(pool.open) == 12 == pool.target  # 1.5 x 8
    assert pool.line[:12] == list(range(12))
    pool.propose(np.array([0] + [-1] * 7), 1)
    goal = int(pool.goal[0])
    assert goal == int(sim.inst.task_errands(0)[0])


@pytest.mark.parametrize("bad, message", [
    ([5, 5, -1, -1, -1, -1, -1, -1], "already assigned"),
    ([99, -1, -1, -1, -1, -1, -1, -1], "already finished"),
])
def test_a_bad_schedule_is_rejected_and_the_previous_one_stays(bad, message):
    sim = _free_sim()
    pool = sim.tasks
    assert pool.propose(np.array([3, -1, -1, -1, -1, -1, -1, -1]), 1)
    assert not pool.propose(np.array(bad), 2)
    assert pool.schedule_errors[-1][0].find(message) >= 0
    assert pool.assigned.tolist() == [3, -1, -1, -1, -1, -1, -1, -1]


def test_an_opened_task_stays_with_its_robot():
    sim = _free_sim()
    pool = sim.tasks
    task = 4
    first = int(sim.inst.task_errands(task)[0])
    pool.propose(np.array([task] + [-1] * 7), 1)
    pool.arrive(np.array([first] + [-2] * 7), 1)  # robot 0 reaches the first errand
    assert pool.is_opened(task)
    if len(sim.inst.task_errands(task)) > 1:
        assert not pool.propose(np.array([-1, task] + [-1] * 6), 2)
        assert "opened" in pool.schedule_errors[-1][0]
        assert pool.assigned[0] == task


def test_counters_match_an_independent_count_of_events():
    from mrmt_env.lorr.env import LoRREnv

    env = LoRREnv()
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(200):
        env.step(rng.integers(0, 4, env.n_robots))
    sim = env.sim
    per_task: dict[int, int] = {}
    for _, _, task, done in sim.tasks.events:
        per_task[task] = max(per_task.get(task, 0), done)
    finished = sum(1 for k, d in per_task.items() if d == len(sim.tasks.errands_of(k)))
    assert sim.finished == finished and sim.tasks.errands_done == len(sim.tasks.events)
    # open tasks: revealed minus finished, and always the pool's size
    assert len(sim.tasks.open) == len(sim.tasks.line) - finished == sim.tasks.target


# ---------------------------------------------------------------- the start kit's default scheduler
def test_greedy_scheduler_takes_the_least_makespan_task_in_robot_order():
    sim = _free_sim()
    grid = sim.inst.grid
    proposal = GreedyScheduler().schedule(sim)
    free = sorted(sim.tasks.open)
    want = np.full(sim.n_robots, -1)
    for a in range(sim.n_robots):
        d = _bfs(grid, int(sim.pos[a]))
        best, best_cost = -1, None
        for k in free:
            e = sim.tasks.errands_of(k)
            cost = d[e[0]] + sum(_bfs(grid, int(x))[int(y)] for x, y in zip(e[:-1], e[1:]))
            if best_cost is None or cost < best_cost:
                best, best_cost = k, cost
        want[a] = best
        free.remove(best)
    assert proposal.tolist() == want.tolist()


# ---------------------------------------------------------------- malformed files: one line naming file and line
def _copy_example(tmp_path: Path) -> Path:
    src = example_instance_path().parent
    for f in src.iterdir():
        shutil.copy(f, tmp_path / f.name)
    return tmp_path / "EXAMPLE-01.json"


@pytest.mark.parametrize("target, edit, needle", [
    ("example_8.agents", lambda s: s.replace("8\n", "9\n", 1), "9 agents but 8 lines"),
    ("example_8.agents", lambda s: s.replace("8\n", "3\n", 1), "teamSize asks for 8"),
    ("example_8.agents", lambda s: s.replace("\n", "\n144\n", 1).replace("8\n", "9\n", 1), "line 2: start 144 is off the map"),
    ("example_8.agents", lambda s: s.replace("\n", "\n0\n", 1).replace("8\n", "9\n", 1), "line 2: start 0 (row 0, col 0) is on a blocked cell"),
    ("example.tasks", lambda s: s.replace("200\n", "201\n"), "201 tasks but 200 task lines"),
    ("example.tasks", lambda s: s.replace("200\n", "201\n,\n", 1), "line 3: a task with no errand"),
    ("example.tasks", lambda s: s.replace("200\n", "201\nabc\n", 1), "line 3: errand 'abc' is not an integer location"),
    ("example-12-12.map", lambda s: s.replace("height 12", "height 13"), "height 13 but the map has"),
    ("example-12-12.map", lambda s: s.replace("width 12", "width x"), "line 3: width must be an integer"),
    ("EXAMPLE-01.json", lambda s: s.replace('"teamSize": 8', '"teamSize": 0'), "teamSize must be an integer >= 1"),
    ("EXAMPLE-01.json", lambda s: s.replace("example.tasks", "missing.tasks"), "no such task file"),
    ("EXAMPLE-01.json", lambda s: s.replace("{", "[", 1), "not JSON"),
])
def test_malformed_files_are_one_line_naming_file_and_line(tmp_path, target, edit, needle):
    path = _copy_example(tmp_path)
    f = tmp_path / target
    f.write_text(edit(f.read_text()))
    with pytest.raises(LoRRFormatError) as exc:
        read_instance(path)
    msg = str(exc.value)
    assert "\n" not in msg and needle in msg
    assert str(tmp_path) in msg


def test_unsupported_assignment_strategy_is_named(tmp_path):
    path = _copy_example(tmp_path)
    path.write_text(path.read_text().replace('"version"', '"taskAssignmentStrategy": "greedy", "version"'))
    with pytest.raises(LoRRFormatError, match="'greedy' is not supported; supported: roundrobin"):
        read_instance(path)


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([1, 1, 3, 5]))
def test_greedy_kernel_is_the_sequential_greedy_on_random_grids(seed, way):
    from mrmt_env.lorr.greedy import greedy_kernel

    rng = np.random.default_rng(seed)
    h, w = int(rng.integers(3, 12)), int(rng.integers(3, 12))
    grid = rng.random((h, w)) < 0.25
    free_cells = np.flatnonzero(~grid.reshape(-1))
    if len(free_cells) < 2:
        return
    robots = rng.choice(free_cells, size=int(rng.integers(1, len(free_cells))), replace=False).astype(np.int64)
    n_tasks = int(rng.integers(1, 2 * len(free_cells)))
    first = rng.choice(free_cells, size=n_tasks).astype(np.int64)        # tasks may share a cell
    length = rng.integers(0, 12, n_tasks).astype(np.int64)
    ids = rng.permutation(n_tasks).astype(np.int64) * 3
    order = np.argsort(first, kind="stable").astype(np.int64)
    cell_start = np.zeros(grid.size + 1, dtype=np.int64)
    np.cumsum(np.bincount(first, minlength=grid.size), out=cell_start[1:])
    free = np.ones(n_tasks, dtype=bool)
    out = np.empty(len(robots), dtype=np.int64)
    assert greedy_kernel(grid.reshape(-1), w, robots, cell_start, order, length, ids, free, int(length.min()),
                         1 << 40, way, out) == len(robots)
    left = set(range(n_tasks))
    for i, r in enumerate(robots.tolist()):
        d = _bfs(grid, r)
        cands = [(way * d[first[k]] + length[k], ids[k], k) for k in left if d[first[k]] >= 0]
        want = min(cands)[2] if cands else -1
        assert out[i] == want
        left.discard(want)
