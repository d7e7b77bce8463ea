"""The lifelong envs: collision model, task stream, metrics, PettingZoo and vector forms."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode
from hypothesis import given, settings
from hypothesis import strategies as st
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test, seed_test

import mrmt_env
from mrmt_env import MRMTEnv, MRMTLifelongEnv, World
from mrmt_env.lifelong.pz import lifelong_env, lifelong_parallel_env
from mrmt_env.lifelong.state import task_pool

SMALL = dict(height=6, width=6, obstacle_density=0.1, n_robots=4, n_targets=3)


def _env(robots, targets, grid=None, **kw):
    grid = np.zeros((3, 4), dtype=bool) if grid is None else grid
    env = MRMTLifelongEnv(world=World(grid, robots, targets), **kw)
    env.reset(seed=0)
    return env


def test_swap_is_refused_and_counted():
    env = _env([[0, 0], [0, 1]], [[2, 3]])
    *_, info = env.step(np.array([4, 3]))  # robot 0 right, robot 1 left: an exchange
    assert env.positions().tolist() == [[0, 0], [0, 1]]
    assert info["blocked_moves"] == 2 and info["conflicts"] == 0 and info["route_cost"] == 0


def test_vertex_conflict_lower_index_wins_and_stayer_keeps_its_cell():
    env = _env([[0, 0], [0, 2], [1, 1]], [[2, 3]])
    *_, info = env.step(np.array([4, 3, 0]))  # 0 and 1 both want (0, 1); robot 2 stays
    assert env.positions().tolist() == [[0, 1], [0, 2], [1, 1]]
    assert info["blocked_moves"] == 1
    *_, info = env.step(np.array([2, 0, 0]))  # into robot 2's kept cell
    assert env.positions()[0].tolist() == [0, 1] and info["blocked_moves"] == 2


def test_refusals_cascade_and_following_and_rotation_are_allowed():
    # a chain 0 -> 1 -> 2 -> wall: 2 is blocked by the wall (invalid), so 1 and 0 are refused in turn
    env = _env([[0, 1], [0, 2], [0, 3]], [[2, 0]])
    *_, info = env.step(np.array([4, 4, 4]))
    assert env.positions().tolist() == [[0, 1], [0, 2], [0, 3]]
    assert info["invalid_moves"] == 1 and info["blocked_moves"] == 2
    # following a robot that leaves is allowed
    *_, info = env.step(np.array([4, 4, 2]))
    assert env.positions().tolist() == [[0, 2], [0, 3], [1, 3]] and info["blocked_moves"] == 2
    # a rotation of four robots around a 2x2 block
    env = _env([[0, 0], [0, 1], [1, 1], [1, 0]], [[2, 3]])
    *_, info = env.step(np.array([4, 2, 3, 1]))
    assert env.positions().tolist() == [[0, 1], [1, 1], [1, 0], [0, 0]] and info["blocked_moves"] == 0


def test_allow_counts_conflicts_as_the_one_shot_env():
    world = mrmt_env.generate_world(3, height=5, width=5, obstacle_density=0.04, n_robots=4, n_targets=3)
    life = MRMTLifelongEnv(world=world, collisions="allow")
    shot = MRMTEnv(world=world, max_episode_steps=None)
    life.reset(seed=0)
    shot.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(200):
        a = rng.integers(0, 5, size=4)
        *_, li = life.step(a)
        if not shot.core.all_visited:
            *_, si = shot.step(a)
            assert (li["vertex_conflicts"], li["swap_conflicts"]) == (si["vertex_conflicts"], si["swap_conflicts"])
            assert li["route_cost"] == si["route_cost"] and li["blocked_moves"] == 0
    assert li["conflicts"] > 0


def test_refill_keeps_k_open_and_measures_service_time():
    grid = np.zeros((1, 5), dtype=bool)
    env = _env([[0, 0]], [[0, 2]], grid=grid)
    env.step(np.array([4]))
    obs, reward, term, trunc, info = env.step(np.array([4]))  # served at step 2 (arrived at 0)
    assert info["tasks_completed"] == 1 and info["open_tasks"] == 1 and info["service_time_mean"] == 2.0
    assert info["throughput"] == 0.5 and reward == env.setup.task_reward - 1 and not term
    new = env.open_tasks()
    assert new.shape == (1, 2) and new[0].tolist() != [0, 2]  # never on the cell just served
    assert obs[1].sum() == 1 and obs[1][tuple(new[0])] == 1


def test_poisson_stream_rate_and_drops():
    env = MRMTLifelongEnv(**SMALL, tasks="poisson", task_rate=2.0)
    env.reset(seed=5)
    for _ in range(300):
        *_, info = env.step(np.zeros(4, dtype=np.int64))
    pool = len(task_pool(env.world, env.source.params))
    assert info["open_tasks"] + info["tasks_completed"] + 0 == info["tasks_arrived"]
    assert info["open_tasks"] <= pool and info["tasks_dropped"] > 0  # robots idle: the pool fills up
    env = MRMTLifelongEnv(**SMALL, tasks="poisson", task_rate=0.25)
    env.reset(seed=1)
    for _ in range(2000):
        *_, info = env.step(np.zeros(4, dtype=np.int64))
    assert 0.2 < (info["tasks_arrived"] + info["tasks_dropped"] - 3) / 2000 < 0.3  # drawn at the rate


def test_warehouse_tasks_only_on_pick_cells():
    env = gym.make("mrmt_env/MRMT-Lifelong-Warehouse-v0", height=24, width=30, n_robots=20, n_targets=30)
    env.reset(seed=0)
    grid = env.unwrapped.world.grid
    beside = np.zeros_like(grid)
    beside[1:] |= grid[:-1]
    beside[:-1] |= grid[1:]
    beside[:, 1:] |= grid[:, :-1]
    beside[:, :-1] |= grid[:, 1:]
    for _ in range(100):
        env.step(env.action_space.sample())
        cells = env.unwrapped.open_tasks()
        assert len(cells) == 30 and beside[cells[:, 0], cells[:, 1]].all()
        robots = {tuple(c) for c in env.unwrapped.positions().tolist()}
        assert not robots & {tuple(c) for c in cells.tolist()}  # no open task under a robot after a step


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), robots=st.integers(2, 12))
def test_block_never_lets_robots_collide(seed, robots):
    env = MRMTLifelongEnv(height=5, width=6, obstacle_density=0.1, n_robots=robots, n_targets=2)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    prev = env.state.pos[0].copy()
    for _ in range(40):
        *_, info = env.step(rng.integers(0, 5, size=robots))
        pos = env.state.pos[0]
        assert len(set(pos.tolist())) == robots  # no vertex collision
        moved = pos != prev
        for i in np.flatnonzero(moved):  # no exchange of cells
            assert not np.any((pos == prev[i]) & (prev == pos[i]))
        assert info["conflicts"] == 0
        prev = pos.copy()


def test_bad_options_are_named():
    with pytest.raises(ValueError, match="tasks must be one of"):
        MRMTLifelongEnv(tasks="stream")
    with pytest.raises(ValueError, match="collisions must be one of"):
        MRMTLifelongEnv(collisions="soft")
    with pytest.raises(ValueError, match="task_rate=1.0 only applies to tasks='poisson'"):
        MRMTLifelongEnv(task_rate=1.0)
    with pytest.raises(ValueError, match=r"task_rate must be a number in \(0, 500\]"):
        MRMTLifelongEnv(tasks="poisson", task_rate=501)


def _same_infos(a: dict, b: dict) -> None:
    assert set(a) == set(b)
    for key in a:
        if key == "final_obs":
            assert all((x is None and y is None) or np.array_equal(x, y) for x, y in zip(a[key], b[key]))
        elif key == "final_info":
            _same_infos(a[key], b[key])
        else:
            assert a[key].dtype == b[key].dtype and np.array_equal(a[key], b[key]), key


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("kw", [dict(SMALL), dict(SMALL, tasks="poisson", task_rate=1.5, collisions="allow")])
def test_native_vector_env_equals_sync(kw, mode):
    eid = "mrmt_env/MRMT-Lifelong-v0"
    native = gym.make_vec(eid, num_envs=3, vectorization_mode="vector_entry_point", autoreset_mode=mode,
                          max_episode_steps=30, **kw)
    sync = gym.make_vec(eid, num_envs=3, vectorization_mode="sync", max_episode_steps=30,
                        vector_kwargs=dict(autoreset_mode=AutoresetMode(mode)), **kw)
    o1, i1 = native.reset(seed=4)
    o2, i2 = sync.reset(seed=4)
    assert np.array_equal(o1, o2)
    rng = np.random.default_rng(0)
    for _ in range(70):
        assert np.array_equal(native.action_masks(), np.stack([e.unwrapped.action_masks() for e in sync.envs]))
        a = rng.integers(0, 5, size=native.action_space.shape)
        r1, r2 = native.step(a), sync.step(a)
        for x, y in zip(r1[:4], r2[:4]):
            assert np.array_equal(x, y)
        _same_infos(r1[4], r2[4])


def test_pettingzoo_api_and_seeds():
    parallel_api_test(lifelong_parallel_env(**SMALL), num_cycles=100)
    api_test(lifelong_env(**SMALL, max_cycles=40), num_cycles=60)
    parallel_seed_test(lambda: lifelong_parallel_env(**SMALL, max_cycles=30), num_cycles=40)
    seed_test(lambda: lifelong_env(**SMALL, max_cycles=30), num_cycles=40)


def test_pettingzoo_steps_as_the_gym_env():
    g = MRMTLifelongEnv(**SMALL)
    p = lifelong_parallel_env(**SMALL, max_cycles=1000)
    g.reset(seed=3)
    p.reset(seed=3)
    rng = np.random.default_rng(1)
    for _ in range(100):
        a = rng.integers(0, 5, size=4)
        go, gr, _, _, gi = g.step(a)
        po, pr, _, _, pi = p.step({f"robot_{k}": int(a[k]) for k in range(4)})
        assert np.array_equal(po["robot_0"][:-1], go) and pr["robot_0"] == gr and pi["robot_0"] == gi


def resolve_oracle(pos, tgt):
    """The block rule as a fixpoint, slow and plain: stayers keep their cells, movers claim in index
    order, exchanges are refused; refusals are final and repeat until nothing changes."""
    tgt = list(tgt)
    at = {p: k for k, p in enumerate(pos)}
    while True:
        before = list(tgt)
        claimed = {pos[k]: k for k in range(len(pos)) if tgt[k] == pos[k]}
        for k in range(len(pos)):
            if tgt[k] != pos[k]:
                if tgt[k] in claimed:
                    tgt[k] = pos[k]
                else:
                    claimed[tgt[k]] = k
        for k in range(len(pos)):
            j = at.get(before[k])
            if before[k] != pos[k] and j is not None and j != k and before[j] == pos[k]:
                tgt[k], tgt[j] = pos[k], pos[j]
        if tgt == before:
            return tgt


@settings(max_examples=200, deadline=None)
@given(data=st.data(), n=st.integers(2, 9))
def test_block_resolution_equals_its_fixpoint_oracle(data, n):
    from mrmt_env.lifelong.kernels import resolve_block

    cells = data.draw(st.lists(st.integers(0, 11), min_size=n, max_size=n, unique=True))  # a 3 x 4 grid
    pos = np.array(cells, dtype=np.int64)
    tgt = pos.copy()
    for k in range(n):
        r, c = divmod(int(pos[k]), 4)
        moves = [(r, c)] + [(r + dr, c + dc) for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1))
                            if 0 <= r + dr < 3 and 0 <= c + dc < 4]
        rr, cc = data.draw(st.sampled_from(moves))
        tgt[k] = rr * 4 + cc
    at = np.full(12, -1, dtype=np.int64)
    at[pos] = np.arange(n)
    claim = np.full(12, -1, dtype=np.int64)
    want = tgt.copy()
    refused = resolve_block(pos, tgt, at, claim, np.empty(n + 1, dtype=np.int64))
    expect = resolve_oracle(pos.tolist(), want.tolist())
    assert tgt.tolist() == expect and refused == int(np.sum((want != pos) & (tgt == pos)))
    assert (claim == -1).all()


def test_pettingzoo_registry_makes_both_forms():
    try:
        from pettingzoo.env_registry.registration import make
    except ImportError:
        pytest.skip("installed PettingZoo has no registry")
    par = make("parallel", "mrmt_env/mrmt_lifelong_v0", n_robots=2, height=5, width=5, n_targets=2)
    aec = make("aec", "mrmt_env/mrmt_lifelong_v0", n_robots=2, height=5, width=5, n_targets=2)
    obs, _ = par.reset(seed=0)
    aec.reset(seed=0)
    assert set(obs) == {"robot_0", "robot_1"} and aec.agent_selection == "robot_0"


@pytest.mark.parametrize("tasks", ["refill", "poisson"])
def test_two_robots_stepping_onto_one_task_serve_it_once(tasks):
    """collisions="allow": two robots step onto the one open task in the same step; it is one task served."""
    env = _env([[0, 0], [0, 2]], [[0, 1]], collisions="allow", tasks=tasks,
               task_rate=None if tasks == "refill" else 0.01)
    obs, reward, _, _, info = env.step(np.array([4, 3]))  # both onto (0, 1)
    assert env.positions().tolist() == [[0, 1], [0, 1]] and info["vertex_conflicts"] == 1
    assert info["tasks_completed"] == 1 and info["targets_visited"] == 1
    assert info["service_time_mean"] == 1.0 and info["throughput"] == 1.0
    assert reward == env.setup.task_reward - 2  # one task's reward, two attempted moves
    assert info["open_tasks"] == info["tasks_arrived"] - 1 == int(obs[1].sum())
    assert obs[1][0, 1] == 0
    if tasks == "refill":  # one task served: one new task, not on the served cell, not under a robot
        assert info["tasks_arrived"] == 2 and info["open_tasks"] == 1


@pytest.mark.parametrize("kw", [dict(collisions="allow"), dict(collisions="allow", tasks="poisson", task_rate=0.7),
                                dict(collisions="block")])
def test_lifelong_counters_equal_an_independent_count(kw):
    """Every counter recounted from the observations step by step: a task is served when a robot
    stands on its cell after the step (once, however many robots do), new tasks appear off the robots
    and off the cells just served, refill replaces each served task (unless dropped), service time is
    counted from the step a task appeared in the observation.  Crowded: six robots on nine cells."""
    env = MRMTLifelongEnv(world=World(np.zeros((3, 3), dtype=bool), [[0, 0], [0, 2], [2, 0], [2, 2], [1, 0], [1, 2]],
                                      [[1, 1], [0, 1]]), **kw)
    obs, info = env.reset(seed=3)
    rng = np.random.default_rng(0)
    arrived_at = {tuple(c): 0 for c in np.argwhere(obs[1])}
    completed = service = shared = 0
    arrivals = len(arrived_at)
    for step in range(1, 301):
        actions = rng.integers(0, 5, size=6)
        before = set(arrived_at)
        dropped = info["tasks_dropped"]
        obs, reward, _, _, info = env.step(actions)
        robots = [tuple(np.argwhere(obs[2 + k])[0]) for k in range(6)]
        assert robots == [tuple(p) for p in env.positions().tolist()]
        served = before & set(robots)
        shared += sum(robots.count(c) > 1 for c in served)
        after = {tuple(c) for c in np.argwhere(obs[1])}
        new = after - before
        assert before - served <= after and not after & served  # open tasks stay; served ones go
        assert not new & set(robots)  # no task arrives under a robot
        if kw.get("tasks", "refill") == "refill":
            assert len(new) + info["tasks_dropped"] - dropped == len(served)
        completed += len(served)
        service += sum(step - arrived_at.pop(c) for c in served)
        arrived_at.update({c: step for c in new})
        arrivals += len(new)
        assert info["tasks_completed"] == info["targets_visited"] == completed
        assert info["open_tasks"] == len(after) and info["tasks_arrived"] == info["n_targets"] == arrivals
        assert info["service_time_mean"] == pytest.approx(service / completed if completed else 0.0)
        assert reward == len(served) * env.setup.task_reward - int(np.count_nonzero(actions))
    assert completed > 20
    if kw["collisions"] == "allow":
        assert shared > 0, shared  # the case at stake happened: two robots on one served task
