"""One frozen world config for every env: the same worlds as keywords, overrides, clear errors."""

from __future__ import annotations

import dataclasses

import gymnasium as gym
import numpy as np
import pytest

import mrmt_env  # noqa: F401 -- registers the ids
from mrmt_env import WorldConfig, generate_world
from mrmt_env.assign.env import MRMTAssignEnv
from mrmt_env.assign.pz import MRMTAssignAECEnv
from mrmt_env.assign.vector import MRMTAssignVectorEnv
from mrmt_env.grid.env import MRMTEnv
from mrmt_env.grid.pz import MRMTParallelEnv
from mrmt_env.grid.vector import MRMTVectorEnv
from mrmt_env.lifelong.env import MRMTLifelongEnv
from mrmt_env.lifelong.pz import MRMTLifelongParallelEnv
from mrmt_env.lifelong.vector import MRMTLifelongVectorEnv

CONFIG = WorldConfig(height=12, width=9, n_robots=4, n_targets=6, layout="rooms")
SINGLE = [MRMTEnv, MRMTAssignEnv, MRMTLifelongEnv]
PARALLEL = [MRMTParallelEnv, MRMTLifelongParallelEnv]
VECTOR = [MRMTVectorEnv, MRMTAssignVectorEnv, MRMTLifelongVectorEnv]
EVERY = SINGLE + PARALLEL + VECTOR + [MRMTAssignAECEnv]


def _new(cls, *args, **kwargs):
    return cls(2, *args, **kwargs) if cls in VECTOR else cls(*args, **kwargs)


@pytest.mark.parametrize("cls", EVERY)
def test_a_config_and_its_keywords_give_the_same_world_source(cls):
    a = _new(cls, CONFIG)
    b = _new(cls, **{f.name: getattr(CONFIG, f.name) for f in dataclasses.fields(CONFIG)})
    sa = a.source if hasattr(a, "source") else a.setup.source
    sb = b.source if hasattr(b, "source") else b.setup.source
    assert sa.params == sb.params and (sa.height, sa.width, sa.n_robots) == (12, 9, 4)
    assert sa.params["layout"] == "rooms" and sa.params["n_targets"] == 6


@pytest.mark.parametrize("cls", SINGLE)
def test_same_seed_same_first_world_from_config_or_keywords(cls):
    a, b = cls(CONFIG), cls(height=12, width=9, n_robots=4, n_targets=6, layout="rooms")
    oa, _ = a.reset(seed=5)
    ob, _ = b.reset(seed=5)
    assert np.array_equal(a.world.grid, b.world.grid) and np.array_equal(a.world.robots, b.world.robots)


def test_keywords_override_the_config_and_the_config_stays_frozen():
    env = MRMTEnv(CONFIG, n_robots=2)
    assert env.n_robots == 2 and CONFIG.n_robots == 4
    with pytest.raises(dataclasses.FrozenInstanceError):
        CONFIG.n_robots = 7
    assert WorldConfig.of(CONFIG, n_robots=None) is CONFIG  # None means "the default": nothing to override


def test_a_fixed_world_in_the_config():
    world = generate_world(3, height=8, width=8, n_robots=2, n_targets=4)
    env = MRMTEnv(WorldConfig(world=world))
    env.reset(seed=0)
    assert env.world == world


def test_gym_make_takes_a_config():
    env = gym.make("mrmt_env/MRMT-v0", config=WorldConfig(height=6, width=7, n_robots=2, n_targets=3))
    obs, _ = env.reset(seed=0)
    assert env.unwrapped.world.shape == (6, 7) and env.unwrapped.n_robots == 2


@pytest.mark.parametrize("cls", EVERY)
def test_bad_arguments_name_the_value(cls):
    with pytest.raises(TypeError, match=r"unknown env argument\(s\) \['robots'\]; world arguments: \[.*'n_robots'"):
        _new(cls, robots=3)
    with pytest.raises(TypeError, match="config must be a WorldConfig, got dict"):
        _new(cls, {"n_robots": 3})
    with pytest.raises(ValueError, match="n_robots"):
        _new(cls, WorldConfig(n_robots=0))
