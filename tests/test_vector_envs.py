"""Native vector envs against N single envs (gymnasium's SyncVectorEnv) with the same seeds and actions."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import mrmt_env
from mrmt_env.fast_generation import draw_world_arrays
from mrmt_env.generation import generate_world

B = 5


def _same_infos(a: dict, b: dict) -> None:
    assert set(a) == set(b)
    for key in a:
        if key == "final_obs":
            for x, y in zip(a[key], b[key]):
                assert (x is None and y is None) or np.array_equal(x, y)
        elif key == "final_info":
            _same_infos(a[key], b[key])
        else:
            assert a[key].dtype == b[key].dtype and np.array_equal(a[key], b[key]), key


def _pair(env_id, mode, **kw):
    native = gym.make_vec(env_id, num_envs=B, vectorization_mode="vector_entry_point", autoreset_mode=mode, **kw)
    sync = gym.make_vec(env_id, num_envs=B, vectorization_mode="sync",
                        vector_kwargs=dict(autoreset_mode=AutoresetMode(mode)), **kw)
    return native, sync


def _actions(env_id, native, rng, masks):
    if env_id in mrmt_env.ASSIGN_IDS:  # mostly legal, sometimes forbidden (a counted no-op)
        return np.array([rng.choice(np.flatnonzero(m)) if rng.random() < 0.9 else rng.integers(0, m.size)
                         for m in masks])
    return rng.integers(0, 5, size=native.action_space.shape)


CASES = [
    ("mrmt_env/MRMT-5x5-v0", {}),
    ("mrmt_env/MRMT-v0", {"dense_reward": 0.5, "max_episode_steps": 40}),
    ("mrmt_env/MRMT-5x5-v0", {"observation": "image", "dense_reward": 1.0}),
    ("mrmt_env/MRMT-Centre-v0", {"max_episode_steps": 30}),
    ("mrmt_env/MRMT-Assign-v0", {}),
    ("mrmt_env/MRMT-Assign-v0", {"height": 6, "width": 6, "n_robots": 2, "n_targets": 4, "max_episode_steps": 5}),
    # map families go through generate_world in the vector envs too
    ("mrmt_env/MRMT-v0", {"layout": "rooms", "height": 9, "width": 9, "n_robots": 2, "n_targets": 4,
                          "max_episode_steps": 25, "layout_options": {"room_size": 3}}),
    ("mrmt_env/MRMT-Maze-v0", {"height": 7, "width": 8, "n_robots": 2, "n_targets": 3, "max_episode_steps": 20,
                               "placement": "centre"}),
    ("mrmt_env/MRMT-Assign-Warehouse-v0", {"height": 10, "width": 12, "n_robots": 2, "n_targets": 4,
                                           "layout_options": {"shelf_length": 3, "margin": 1}}),
]


@pytest.mark.parametrize("mode", ["NextStep", "SameStep"])
@pytest.mark.parametrize("env_id,kw", CASES)
def test_native_equals_sync_vector_env(env_id, kw, mode):
    native, sync = _pair(env_id, mode, **kw)
    assert native.metadata["autoreset_mode"] == AutoresetMode(mode)
    assert native.observation_space == sync.observation_space and native.action_space == sync.action_space
    o1, i1 = native.reset(seed=11)
    o2, i2 = sync.reset(seed=11)
    assert np.array_equal(o1, o2)
    _same_infos(i1, i2)
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(150):
        masks = native.action_masks()
        assert np.array_equal(masks, np.stack([e.unwrapped.action_masks() for e in sync.envs]))
        a = _actions(env_id, native, rng, masks)
        r1, r2 = native.step(a), sync.step(a)
        for x, y in zip(r1[:4], r2[:4]):
            assert x.dtype == y.dtype and np.array_equal(x, y)
        _same_infos(r1[4], r2[4])
        ends += int((r1[2] | r1[3]).sum())
    assert ends > 0  # autoreset was exercised


def test_partial_reset_in_disabled_mode():
    env = gym.make_vec("mrmt_env/MRMT-Assign-v0", num_envs=3, vectorization_mode="vector_entry_point",
                       autoreset_mode="Disabled")
    obs, info = env.reset(seed=0)
    while True:
        obs, r, term, trunc, info = env.step(np.argmax(info["action_mask"], axis=1))
        if (term | trunc).any():
            break
    with pytest.raises(RuntimeError, match="reset_mask"):
        env.step(np.argmax(info["action_mask"], axis=1))
    obs, info = env.reset(options={"reset_mask": term | trunc})
    assert (info["steps"][term | trunc] == 0).all()


def test_fast_draw_is_generate_world_draw_for_draw():
    params = dict(height=7, width=9, obstacle_density=0.3, n_robots=3, n_targets=8, placement="uniform")
    r1, r2 = np.random.default_rng(3), np.random.default_rng(3)
    for _ in range(100):
        w = generate_world(r1, **params)
        flat, robots, targets = draw_world_arrays(r2, params)
        assert np.array_equal(w.grid.reshape(-1), flat)
        assert np.array_equal(w.robots[:, 0] * 9 + w.robots[:, 1], robots)
        assert np.array_equal(w.targets[:, 0] * 9 + w.targets[:, 1], targets)
    assert r1.integers(1 << 30) == r2.integers(1 << 30)


def test_bad_vector_arguments_are_named():
    with pytest.raises(ValueError, match="num_envs must be an integer >= 1, got 0"):
        gym.make_vec("mrmt_env/MRMT-v0", num_envs=0, vectorization_mode="vector_entry_point")
    with pytest.raises(ValueError, match="autoreset_mode must be one of"):
        gym.make_vec("mrmt_env/MRMT-v0", num_envs=2, vectorization_mode="vector_entry_point", autoreset_mode="Later")
    env = gym.make_vec("mrmt_env/MRMT-v0", num_envs=2, vectorization_mode="vector_entry_point")
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros((2, 3), dtype=np.int64))
    env.reset(seed=0)
    with pytest.raises(ValueError, match="env 1 robot 2 is 5"):
        env.step(np.array([[0, 0, 0], [0, 0, 5]]))
    with pytest.raises(ValueError, match="seed list has 1 seeds"):
        env.reset(seed=[1])
