"""``mrmt_env/LoRR-v0`` and ``mrmt_env/lorr_v0``: the ecosystem's checks and the env's contract."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence
from pettingzoo.test import parallel_api_test

import mrmt_env
from mrmt_env.lorr.instance import example_instance_path
from mrmt_env.lorr.pz import lorr_parallel_env


def test_check_env_and_render_modes():
    for mode in (None, "ansi", "rgb_array"):
        env = gym.make("mrmt_env/LoRR-v0", render_mode=mode).unwrapped
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env, skip_render_check=False)
    env = gym.make("mrmt_env/LoRR-v0", render_mode="ansi")
    env.reset(seed=0)
    text = env.render()
    assert len(text.splitlines()) == 13 and text.count("@") >= int(env.unwrapped.instance.grid.sum())
    env = gym.make("mrmt_env/LoRR-v0", render_mode="rgb_array")
    env.reset(seed=0)
    assert env.render().shape == (12, 12, 3)


def _rollout(env, seed, n):
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    out = [(obs, info)]
    for _ in range(n):
        out.append(env.step(env.action_space.sample()))
    return out


def test_seeded_episodes_are_deterministic_and_pickle():
    a, b = _rollout(gym.make("mrmt_env/LoRR-v0"), 3, 150), _rollout(gym.make("mrmt_env/LoRR-v0"), 3, 150)
    assert data_equivalence(a, b)
    env = gym.make("mrmt_env/LoRR-v0")
    env.reset(seed=0)
    clone = pickle.loads(pickle.dumps(env))
    act = np.full(env.unwrapped.n_robots, 1)
    assert data_equivalence(env.step(act), clone.step(act))


def test_truncates_after_the_instances_steps_and_never_terminates():
    env = gym.make("mrmt_env/LoRR-v0", steps=5)
    env.reset(seed=0)
    for t in range(5):
        _, _, term, trunc, info = env.step(np.full(env.unwrapped.n_robots, 3))
        assert not term and trunc == (t == 4) and info["step"] == t + 1
    assert gym.make("mrmt_env/LoRR-v0").unwrapped.setup.steps == 200  # simulation_time.json beside the instance


def test_goals_follow_the_schedule_before_the_move():
    env = gym.make("mrmt_env/LoRR-v0").unwrapped
    obs, _ = env.reset(seed=0)
    sim = env.sim
    # the greedy proposal is already in the observation: every robot has a task and its first errand
    assert (obs["task"] >= 0).all()
    for a in range(env.n_robots):
        assert obs["goal"][a] == sim.tasks.errands_of(int(obs["task"][a]))[0]
    _, reward, *_ = env.step(np.full(env.n_robots, 3))
    # applied after the move: robot 2 waited on its single-errand task's cell and finished it
    done = [a for a in range(env.n_robots) if int(obs["task"][a]) not in sim.tasks.open]
    assert done == [2] and reward == 1.0 and sim.tasks.assigned[2] == -1
    keep = [a for a in range(env.n_robots) if a not in done]
    assert np.array_equal(sim.tasks.assigned[keep], obs["task"][keep])


def test_propose_overrides_the_scheduler_and_bad_schedules_are_counted():
    env = gym.make("mrmt_env/LoRR-v0", scheduler=None).unwrapped
    obs, _ = env.reset(seed=0)
    assert (obs["task"] == -1).all()
    env.propose(np.array([0, 0, -1, -1, -1, -1, -1, -1]))
    _, _, _, _, info = env.step(np.full(env.n_robots, 3))
    assert info["schedule_errors"] == 1 and (env.sim.tasks.assigned == -1).all()
    env.propose(np.array([0, 1, -1, -1, -1, -1, -1, -1]))
    _, _, _, _, info = env.step(np.full(env.n_robots, 3))
    assert info["schedule_errors"] == 1 and env.sim.tasks.assigned[:2].tolist() == [0, 1]
    with pytest.raises(ValueError, match=r"expected \(8,\) integers"):
        env.propose(np.array([0, 1]))


@pytest.mark.parametrize("bad, message", [
    (np.full(7, 3), r"expected shape \(8,\)"),
    (np.array([4, 3, 3, 3, 3, 3, 3, 3]), "robot 0: action 4 is not one of 0..3"),
])
def test_bad_actions_are_named(bad, message):
    env = gym.make("mrmt_env/LoRR-v0").unwrapped
    env.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        env.step(bad)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="steps must be an integer >= 1, got 0"):
        gym.make("mrmt_env/LoRR-v0", steps=0)
    with pytest.raises(ValueError, match="scheduler must be 'greedy', None or an object"):
        gym.make("mrmt_env/LoRR-v0", scheduler="fastest")


def test_pettingzoo_parallel_api_and_registry():
    parallel_api_test(lorr_parallel_env(steps=30), num_cycles=40)
    assert set(mrmt_env.LORR_IDS) == {"mrmt_env/LoRR-v0"}
    try:
        from pettingzoo.env_registry.registration import make
    except ImportError:
        pytest.skip("installed PettingZoo has no registry")
    par = make("parallel", "mrmt_env/lorr_v0", steps=3)
    obs, _ = par.reset(seed=0)
    assert len(obs) == 8


def test_parallel_and_gym_forms_run_the_same_episode():
    par = lorr_parallel_env(instance=example_instance_path())
    env = gym.make("mrmt_env/LoRR-v0").unwrapped
    par.reset(seed=0)
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    for _ in range(60):
        a = rng.integers(0, 4, env.n_robots)
        _, r1, *_ = env.step(a)
        _, r2, *_ = par.step({f"robot_{k}": int(x) for k, x in enumerate(a)})
        assert r1 == r2["robot_0"]
    state = par.state()
    assert np.array_equal(state[:, 0], env.sim.pos) and np.array_equal(state[:, 1], env.sim.orient)


def test_four_direction_model_moves_without_turning():
    env = gym.make("mrmt_env/LoRR-v0", action_model="MAPF").unwrapped
    assert env.action_space.nvec.tolist() == [5] * env.n_robots
    obs, _ = env.reset(seed=0)
    w = env.instance.width
    grid = env.instance.grid.reshape(-1)
    # robot 0 steps to a free neighbour, everyone else stays
    p = int(obs["position"][0])
    for action, delta in ((1, -w), (2, w), (3, -1), (4, 1)):
        q = p + delta
        if 0 <= q < grid.size and not grid[q] and q not in obs["position"] and abs(q % w - p % w) <= 1:
            a = np.zeros(env.n_robots, dtype=np.int64)
            a[0] = action
            obs, *_, info = env.step(a)
            assert obs["position"][0] == q and (obs["orientation"] == 0).all() and info["errors"] == 0
            break
    with pytest.raises(ValueError, match="action_model must be one of MAPF_T, MAPF, got 'hex'"):
        gym.make("mrmt_env/LoRR-v0", action_model="hex")
