"""Checks run on every registered ``mrmt_env/`` Gymnasium id (new ids are
picked up automatically)."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence

import mrmt_env  # noqa: F401  (registers the ids)

# the MRMT families share world, info and observation conventions; mrmt_env/LoRR-v0 (an instance
# file, dict observations) runs the same gymnasium checks in test_lorr_env.py
IDS = sorted(i for i in gym.registry if i.startswith("mrmt_env/MRMT-"))


def test_every_id_is_checked():
    lorr = {i for i in gym.registry if i.startswith("mrmt_env/") and i not in IDS}
    assert lorr == set(mrmt_env.LORR_IDS)


def test_ids_registered():
    assert {"mrmt_env/MRMT-v0", "mrmt_env/MRMT-5x5-v0"} <= set(IDS)


@pytest.mark.parametrize("env_id", IDS)
def test_spec_keeps_env_checker_and_time_limit(env_id):
    spec = gym.spec(env_id)
    assert spec.disable_env_checker is False
    assert spec.max_episode_steps is not None and spec.max_episode_steps > 0
    assert spec.order_enforce


@pytest.mark.parametrize("env_id", IDS)
def test_gymnasium_check_env(env_id):
    env = gym.make(env_id).unwrapped
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no warning is tolerated
        check_env(env, skip_render_check=False)
    for mode in env.metadata["render_modes"]:
        if mode == "human":
            continue  # prints to stdout; covered in test_gym_env.test_render_modes
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(gym.make(env_id, render_mode=mode).unwrapped, skip_render_check=False)


def _rollout(env, seed, n):
    obs, info = env.reset(seed=seed)
    env.action_space.seed(seed)
    out = [(obs, info)]
    for _ in range(n):
        obs, r, term, trunc, info = env.step(env.action_space.sample())
        out.append((obs, r, term, trunc, info))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs, info))
    return out


def _same(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert np.array_equal(x[0], y[0])
        assert data_equivalence(x[1:], y[1:])  # infos may hold arrays (the Assign env's action_mask)


@pytest.mark.parametrize("env_id", IDS)
def test_seeded_episodes_are_deterministic(env_id):
    _same(_rollout(gym.make(env_id), 7, 300), _rollout(gym.make(env_id), 7, 300))
    a = gym.make(env_id)
    b = gym.make(env_id)
    a.reset(seed=1)
    b.reset(seed=2)
    assert a.unwrapped.world != b.unwrapped.world


@pytest.mark.parametrize("env_id", IDS)
def test_info_keys_and_types(env_id):
    env = gym.make(env_id)
    _, info = env.reset(seed=0)
    keys = {"route_cost", "makespan", "steps", "targets_visited", "n_targets", "is_success", "invalid_moves"}
    if env_id not in mrmt_env.ASSIGN_IDS:
        keys.add("conflicts")  # the plan-level env does not simulate cells over time
    assert keys <= set(info)
    _, _, _, _, info = env.step(env.action_space.sample())
    assert keys <= set(info)
    floats = {"throughput", "service_time_mean"} if env_id in mrmt_env.LIFELONG_IDS else set()  # per-step rates
    assert all(isinstance(v, float if k in floats else (int, bool)) for k, v in info.items() if k != "action_mask")
    if "action_mask" in info:
        assert np.array_equal(info["action_mask"], env.unwrapped.action_masks())


@pytest.mark.parametrize("env_id", IDS)
@pytest.mark.parametrize("mode", ["ansi", "rgb_array"])
def test_render_modes(env_id, mode):
    env = gym.make(env_id, render_mode=mode)
    env.reset(seed=0)
    out = env.render()
    h, w = env.unwrapped.world.shape
    if mode == "ansi":
        assert isinstance(out, str) and len(out.splitlines()) == h + 1
    else:
        assert out.dtype == np.uint8 and out.shape[2] == 3 and out.shape[0] % h == 0 and out.shape[1] % w == 0


@pytest.mark.parametrize("env_id", IDS)
def test_pickle_roundtrip(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    clone = pickle.loads(pickle.dumps(env))
    a = np.zeros(env.action_space.shape, dtype=np.int64)
    o1, *r1 = env.step(a)
    o2, *r2 = clone.step(a)
    assert np.array_equal(o1, o2) and data_equivalence(r1, r2)
