"""The PettingZoo envs: official API tests plus behaviour of our own."""

from __future__ import annotations

import pickle
import warnings

import numpy as np
import pytest
from pettingzoo.test import (
    api_test,
    max_cycles_test,
    parallel_api_test,
    parallel_seed_test,
    render_test,
    seed_test,
)

import mrmt_env
from mrmt_env import MRMTEnv, World, generate_world, world_from_observation
from mrmt_env.observation import agent_index_from_observation


def test_parallel_api():
    parallel_api_test(mrmt_env.parallel_env(), num_cycles=300)
    parallel_api_test(mrmt_env.parallel_env(height=5, width=5, n_robots=1, n_targets=3), num_cycles=100)


def test_aec_api():
    api_test(mrmt_env.env(), num_cycles=200)


def test_seeds():
    parallel_seed_test(lambda: mrmt_env.parallel_env(max_cycles=60), num_cycles=150)
    seed_test(lambda: mrmt_env.env(max_cycles=60), num_cycles=150)


def test_render():
    # human mode prints text (there is no window); keep the test output clean
    render_test(lambda render_mode=None: mrmt_env.env(render_mode=render_mode))


def test_max_cycles(capsys):
    max_cycles_test(mrmt_env)


def test_same_core_as_gym_env():
    """Same world and joint actions -> same reward and info in both APIs."""
    world = generate_world(12)
    genv = MRMTEnv(world=world)
    penv = mrmt_env.parallel_env(world=world, max_cycles=1000)
    genv.reset(seed=0)
    obs, _ = penv.reset(seed=0)
    rng = np.random.default_rng(3)
    for _ in range(200):
        a = rng.integers(0, 5, size=3)
        gobs, grew, gterm, gtrunc, ginfo = genv.step(a)
        pobs, prew, pterm, ptrunc, pinfo = penv.step({f"robot_{k}": int(a[k]) for k in range(3)})
        for k in range(3):
            agent = f"robot_{k}"
            assert prew[agent] == grew and pterm[agent] == gterm and pinfo[agent] == ginfo
            assert np.array_equal(pobs[agent][:-1], gobs)
            assert np.array_equal(pobs[agent][-1], gobs[2 + k])
        assert np.array_equal(penv.state(), gobs)
        if gterm:
            assert penv.agents == []
            break


def test_agent_observation_helpers():
    penv = mrmt_env.parallel_env()
    obs, infos = penv.reset(seed=4)
    penv.step({a: 2 for a in penv.agents})
    obs, *_ = penv.step({a: 4 for a in penv.agents})
    assert penv.agents == ["robot_0", "robot_1", "robot_2"]
    current = penv.core.current_world()
    order = np.lexsort((current.targets[:, 1], current.targets[:, 0]))
    expected = current.replace(targets=current.targets[order])
    for k, agent in enumerate(penv.agents):
        o = obs[agent]
        assert o.shape == (6, 10, 10) and penv.observation_space(agent).contains(o)
        assert np.array_equal(o[-1], o[2 + k])
        j = agent_index_from_observation(o)
        assert j == k or np.array_equal(o[2 + j], o[2 + k])  # lowest index among robots sharing the cell
        assert world_from_observation(o[:-1]) == expected
    assert penv.state_space.contains(penv.state())
    assert world_from_observation(penv.state()) == expected


def test_truncation_and_episode_end():
    penv = mrmt_env.parallel_env(max_cycles=3)
    penv.reset(seed=0)
    for t in range(3):
        _, _, terms, truncs, _ = penv.step({a: 0 for a in penv.agents})
    assert all(truncs.values()) and not any(terms.values()) and penv.agents == []
    with pytest.raises(RuntimeError, match="episode is over"):
        penv.step({})
    with pytest.raises(ValueError, match="max_cycles=3 and max_episode_steps=4 disagree"):
        mrmt_env.parallel_env(max_cycles=3, max_episode_steps=4)
    assert mrmt_env.parallel_env(max_episode_steps=5).max_cycles == 5


def test_bad_actions():
    penv = mrmt_env.parallel_env()
    penv.reset(seed=0)
    with pytest.raises(ValueError, match=r"missing \['robot_2'\]"):
        penv.step({"robot_0": 0, "robot_1": 0})
    with pytest.raises(ValueError, match=r"unknown \['robot_9'\]"):
        penv.step({"robot_0": 0, "robot_1": 0, "robot_9": 0})
    with pytest.raises(ValueError, match="action for robot_1 is 5"):
        penv.step({"robot_0": 0, "robot_1": 5, "robot_2": 0})
    with pytest.raises(ValueError, match="action for robot_0 must be an integer"):
        penv.step({"robot_0": 1.5, "robot_1": 0, "robot_2": 0})
    penv.step({"robot_0": np.int64(1), "robot_1": 2, "robot_2": 0})


def test_success_terminates_every_agent():
    grid = np.zeros((1, 3), dtype=bool)
    penv = mrmt_env.parallel_env(world=World(grid, [[0, 0], [0, 2]], [[0, 1]]))
    penv.reset(seed=0)
    _, rew, terms, truncs, infos = penv.step({"robot_0": 4, "robot_1": 0})
    assert all(terms.values()) and not any(truncs.values())
    assert rew == {"robot_0": penv.core.target_reward - 1, "robot_1": penv.core.target_reward - 1}
    assert infos["robot_1"]["is_success"] and infos["robot_1"]["route_cost"] == 1
    assert penv.agents == []


def test_pettingzoo_registry_and_pickle():
    try:
        from pettingzoo.env_registry.registration import make
    except ImportError:
        pytest.skip("installed PettingZoo has no registry")
    p = make("parallel", "mrmt_env/mrmt_v0", max_cycles=10)
    assert isinstance(p, mrmt_env.MRMTParallelEnv) and p.max_cycles == 10
    p.reset(seed=1)
    clone = pickle.loads(pickle.dumps(p))
    acts = {a: 1 for a in p.agents}
    o1, r1, *_ = p.step(acts)
    o2, r2, *_ = clone.step(acts)
    assert r1 == r2 and all(np.array_equal(o1[a], o2[a]) for a in o1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        aec = make("aec", "mrmt_env/mrmt_v0")
    aec.reset(seed=0)
    assert aec.agents == ["robot_0", "robot_1", "robot_2"]
