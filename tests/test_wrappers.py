"""ComputeInfoWrapper: compute keys in info only at episode end."""

from __future__ import annotations

import gymnasium as gym
import pytest

from agents.evaluation import COMPUTE_KEYS, compute_record
from agents.policy import PlannerPolicy
from agents.wrappers import ComputeInfoWrapper


def _episode(env, act):
    obs, info = env.reset(seed=3)
    infos = [info]
    done = False
    while not done:
        obs, _, term, trunc, info = env.step(act(obs, len(infos) == 1))
        infos.append(info)
        done = term or trunc
    return infos


def test_keys_only_at_episode_end_with_controller():
    policy = PlannerPolicy("strong")
    env = ComputeInfoWrapper(gym.make("mrmt_env/MRMT-v0"), controller=policy)
    infos = _episode(env, lambda obs, start: policy.predict(obs, episode_start=start)[0])
    assert infos[-1]["is_success"]
    for info in infos[:-1]:
        assert not set(COMPUTE_KEYS) & set(info)
    assert {k: infos[-1][k] for k in COMPUTE_KEYS} == compute_record(policy.episode_compute())
    assert infos[-1]["cpu_s"] > 0


def test_base_env_info_has_no_compute_keys():
    policy = PlannerPolicy("fast")
    infos = _episode(gym.make("mrmt_env/MRMT-v0"), lambda obs, start: policy.predict(obs, episode_start=start)[0])
    assert not any(set(COMPUTE_KEYS) & set(info) for info in infos)


def test_without_controller_measures_caller_time_also_on_truncation():
    import time

    env = ComputeInfoWrapper(gym.make("mrmt_env/MRMT-v0", max_episode_steps=5))

    def think(obs, start):  # the caller's own decision time: 2 ms of work before each step
        t = time.perf_counter()
        while time.perf_counter() - t < 0.002:
            pass
        return env.action_space.sample() * 0

    t0 = time.perf_counter()
    infos = _episode(env, think)
    wall = time.perf_counter() - t0
    assert len(infos) == 6 and not infos[-1]["is_success"]
    assert all(not set(COMPUTE_KEYS) & set(i) for i in infos[:-1])
    last = infos[-1]
    assert 5 * 0.002 <= last["cpu_s"] <= wall and last["chip_calls"] == 0
    assert last["host_energy_j"] == pytest.approx(15.0 * last["cpu_s"])


def test_rejects_controller_without_episode_compute():
    with pytest.raises(TypeError, match="episode_compute"):
        ComputeInfoWrapper(gym.make("mrmt_env/MRMT-v0"), controller=object())
