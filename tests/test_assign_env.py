"""The plan-level env MRMT-Assign-v0: masks, dynamics, metrics, planner adapter, PettingZoo form."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import mrmt_env
from mrmt_env.assign.env import MRMTAssignEnv, robot_path
from mrmt_env.world import World

ENV_ID = "mrmt_env/MRMT-Assign-v0"


def _masked_random_episode(env, seed, rng):
    obs, info = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        assert np.array_equal(info["action_mask"], env.unwrapped.action_masks())
        a = int(rng.choice(np.flatnonzero(info["action_mask"])))
        obs, r, term, trunc, info = env.step(a)
        total += r
        done = term or trunc
    return total, term, info


def test_masked_episodes_visit_every_target_and_return_minus_route_cost():
    env = gym.make(ENV_ID)
    rng = np.random.default_rng(0)
    for seed in range(30):
        total, term, info = _masked_random_episode(env, seed, rng)
        assert term and info["is_success"] and info["targets_visited"] == 10
        assert total == -info["route_cost"] and info["invalid_moves"] == 0
        assert info["steps"] <= 10 + 3 and info["robot"] == -1


def test_same_world_as_grid_env_for_the_same_seed():
    a, b = gym.make(ENV_ID), gym.make("mrmt_env/MRMT-v0")
    for seed in (0, 5):
        a.reset(seed=seed)
        b.reset(seed=seed)
        assert a.unwrapped.world == b.unwrapped.world


def _world():
    grid = np.zeros((3, 5), dtype=bool)
    grid[1, 1:4] = True
    return World(grid, np.array([[0, 0], [2, 4]]), np.array([[0, 4], [2, 0], [0, 2]]))


def test_dynamics_on_a_small_world():
    env = MRMTAssignEnv(world=_world())
    obs, info = env.reset(seed=0)
    n = 3
    assert info["robot"] == 0 and obs.shape == (n + 2, 8 + n)
    assert obs[n + 0, 6] == 1 and obs[n + 1, 6] == 0  # robot 0 decides first
    assert obs[2, 4] == pytest.approx(2 / 8)  # robot 0 -> target 2 is 2 moves; distances / (H + W)
    obs, r, term, trunc, info = env.step(2)  # robot 0 to target 2 (2 moves)
    assert r == -2 and info["route_cost"] == 2 and info["robot"] == 1  # robot 1 is now the least busy
    obs, r, *_ , info = env.step(0)  # robot 1 to target 0 (2 moves)
    assert r == -2 and info["robot"] == 0 and info["makespan"] == 2
    assert not info["action_mask"][0] and not info["action_mask"][2] and info["action_mask"][1]
    obs, r, term, trunc, info = env.step(1)  # robot 0 from (0,2) to (2,0): 4 moves
    assert term and r == -4 and info["route_cost"] == 8 and info["makespan"] == 6
    assert [p.tolist()[-1] for p in env.route_paths()] == [[2, 0], [0, 4]]
    assert len(robot_path(env.world, 0, env.orders[0])) == 6 + 1


def test_stop_is_masked_for_the_last_active_robot():
    env = MRMTAssignEnv(world=_world())
    _, info = env.reset()
    assert info["action_mask"][3]  # robot 0 may retire: robot 1 can still reach everything
    _, r, _, _, info = env.step(3)
    assert r == 0 and info["robot"] == 1
    assert not info["action_mask"][3]  # robot 1 is the last active robot


def test_forbidden_action_is_a_counted_no_op_and_out_of_range_raises():
    env = MRMTAssignEnv(world=_world())
    env.reset()
    env.step(2)
    obs_before = env.state.observe()[0].copy()
    env.step(0)
    _, r, term, _, info = env.step(0)  # target 0 is taken
    assert r == -1 and not term and info["invalid_moves"] == 1 and info["steps"] == 3
    with pytest.raises(ValueError, match=r"outside 0..3"):
        env.step(7)
    with pytest.raises(ValueError, match="one integer"):
        env.step(np.array([1, 2]))
    assert obs_before.shape == env.state.observe()[0].shape


def test_targets_under_robots_are_visited_at_reset():
    grid = np.zeros((2, 3), dtype=bool)
    env = MRMTAssignEnv(world=World(grid, [[0, 0]], [[0, 0], [1, 2]]))
    _, info = env.reset()
    assert info["targets_visited"] == 1 and not info["action_mask"][0] and info["action_mask"][1]


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="max_episode_steps"):
        MRMTAssignEnv(max_episode_steps=0)
    with pytest.raises(ValueError, match="render_mode"):
        MRMTAssignEnv(render_mode="video")


def test_planner_adapter_matches_the_plan_cost():
    from agents.assign.policy import AssignPlannerPolicy
    from planners.pipeline import make_pipeline

    env = gym.make(ENV_ID)
    policy = AssignPlannerPolicy("strong")
    pipe = make_pipeline("strong")
    for seed in range(5):
        obs, info = env.reset(seed=seed)
        policy.begin_episode(env)
        start, done = True, False
        while not done:
            a, _ = policy.predict(obs, episode_start=start, action_masks=info["action_mask"])
            start = False
            obs, r, term, trunc, info = env.step(a)
            done = term or trunc
        plan = pipe.plan(env.unwrapped.world, seed=0)
        assert info["is_success"] and info["route_cost"] == plan.route_cost  # A* paths are BFS-shortest
        assert policy.fallbacks == 0


def test_planner_adapter_needs_the_world():
    from agents.assign.policy import AssignPlannerPolicy

    env = gym.make(ENV_ID)
    obs, info = env.reset(seed=0)
    with pytest.raises(RuntimeError, match="begin_episode"):
        AssignPlannerPolicy("fast").predict(obs, episode_start=True, action_masks=info["action_mask"])


def test_pettingzoo_aec_api():
    from pettingzoo.test import api_test, seed_test

    api_test(mrmt_env.assign_aec_env(), num_cycles=60)
    seed_test(lambda render_mode=None: mrmt_env.assign_aec_env(), num_cycles=30)


def test_pettingzoo_team_reward_and_turns():
    env = mrmt_env.assign_aec_env(world=_world())
    env.reset()
    assert env.agent_selection == "robot_0"
    env.step(2)
    assert env.agent_selection == "robot_1" and env.rewards == {"robot_0": -2.0, "robot_1": -2.0}
    obs = env.observe("robot_0")
    assert obs["action_mask"].sum() == 0 and env.observe("robot_1")["action_mask"].sum() > 0
    with pytest.raises(ValueError, match=r"robot_1: action 9 is outside 0..3"):
        env.step(9)


def test_world_without_open_targets_ends_on_a_free_stop():
    grid = np.zeros((2, 3), dtype=bool)
    env = MRMTAssignEnv(world=World(grid, [[0, 0]], [[0, 0]]))
    _, info = env.reset()
    assert info["robot"] == -1 and info["action_mask"].tolist() == [False, True]
    _, r, term, _, info = env.step(1)
    assert term and r == 0 and info["invalid_moves"] == 0 and info["is_success"]
