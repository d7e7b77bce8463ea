"""One frozen env config for every env: the same worlds and options as keywords, overrides, clear errors."""

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
    with pytest.raises(ValueError, match=rf"unknown env option\(s\) \['robots'\]; {cls.__name__} takes \[.*'n_robots'"):
        _new(cls, robots=3)
    with pytest.raises(TypeError, match="config must be an EnvConfig or a WorldConfig, got dict"):
        _new(cls, {"n_robots": 3})
    with pytest.raises(ValueError, match="n_robots"):
        _new(cls, WorldConfig(n_robots=0))


# ---------------------------------------------------------------- the whole env config (EnvConfig)
from mrmt_env import EnvConfig  # noqa: E402
from mrmt_env.lorr.env import LoRREnv  # noqa: E402
from mrmt_env.lorr.pz import LoRRParallelEnv  # noqa: E402

LIFELONG = EnvConfig(height=8, width=8, n_robots=3, n_targets=4, tasks="poisson", task_rate=2.0,
                     collisions="allow", target_reward=5.0)


def _lifelong_rollout(env, steps=25):
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    total = 0.0
    for _ in range(steps):
        _, r, *_ = env.step(rng.integers(0, 5, size=env.n_robots))
        total += float(r)
    return total, env.state.tasks_done.tolist() if hasattr(env.state, "tasks_done") else None


def test_one_config_holds_every_lifelong_option_and_gives_the_keywords_episode():
    a = MRMTLifelongEnv(LIFELONG)
    b = MRMTLifelongEnv(height=8, width=8, n_robots=3, n_targets=4, tasks="poisson", task_rate=2.0,
                        collisions="allow", target_reward=5.0)
    assert a.config == b.config == LIFELONG
    assert a.options.tasks == "poisson" and a.options.task_rate == 2.0 and a.options.collisions == "allow"
    assert a.setup.task_reward == 5.0
    assert _lifelong_rollout(a) == _lifelong_rollout(b)
    # the same record builds the PettingZoo and the vector form with the same options
    for env in (MRMTLifelongParallelEnv(LIFELONG), MRMTLifelongVectorEnv(2, LIFELONG)):
        assert env.config == LIFELONG and env.setup.options == a.options and env.setup.task_reward == 5.0


def test_grid_options_from_the_config():
    cfg = EnvConfig(height=6, width=6, n_robots=2, n_targets=3, observation="image", dense_reward=0.5,
                    max_episode_steps=7)
    env, vec = MRMTEnv(cfg), MRMTVectorEnv(2, cfg)
    assert env.observation_mode == vec.observation_mode == "image"
    assert env.dense_reward == vec.dense_reward == 0.5
    assert env.max_episode_steps == 7 and env.observation_space.shape == vec.single_observation_space.shape
    assert MRMTParallelEnv(EnvConfig(max_cycles=9)).max_cycles == 9
    assert MRMTAssignAECEnv(EnvConfig(max_cycles=4)).max_cycles == 4


def test_the_league_env_takes_the_config():
    a = gym.make("mrmt_env/LoRR-v0", config=EnvConfig(steps=5, action_model="MAPF")).unwrapped
    b = gym.make("mrmt_env/LoRR-v0", steps=5, action_model="MAPF").unwrapped
    assert isinstance(a, LoRREnv) and a.config == b.config
    assert a.setup.steps == b.setup.steps == 5 and a.setup.n_actions == b.setup.n_actions == 5
    assert LoRRParallelEnv(EnvConfig(scheduler=None)).setup.scheduler is None  # None: only proposals
    assert LoRREnv(EnvConfig(steps=5), steps=3).setup.steps == 3  # keywords override


@pytest.mark.parametrize("cls, config, named", [
    (MRMTAssignEnv, EnvConfig(tasks="poisson"), "MRMTAssignEnv does not take tasks='poisson'"),
    (MRMTAssignEnv, EnvConfig(target_reward=2.0), "MRMTAssignEnv does not take target_reward=2.0"),
    (MRMTEnv, EnvConfig(collisions="allow"), "MRMTEnv does not take collisions='allow'"),
    (MRMTLifelongEnv, EnvConfig(observation="image"), "MRMTLifelongEnv does not take observation='image'"),
    (MRMTParallelEnv, EnvConfig(dense_reward=1.0), "MRMTParallelEnv does not take dense_reward=1.0"),
    (LoRREnv, EnvConfig(n_robots=3), "LoRREnv does not take n_robots=3"),
    (LoRRParallelEnv, EnvConfig(max_episode_steps=10), "LoRRParallelEnv does not take max_episode_steps=10"),
])
def test_an_option_the_env_does_not_take_is_refused_by_name(cls, config, named):
    with pytest.raises(ValueError, match=named + r"; it takes \["):
        cls(config)


def test_an_option_at_its_default_is_not_foreign():
    env = MRMTAssignEnv(EnvConfig(tasks="refill", dense_reward=0, observation="binary"))
    assert env.config.tasks == "refill"


@pytest.mark.parametrize("kwargs, named", [
    ({"observation": "rgb"}, r"observation must be one of \('binary', 'image'\), got 'rgb'"),
    ({"dense_reward": -1.0}, r"dense_reward must be a finite number >= 0 \(0 = off\), got -1.0"),
    ({"dense_reward": float("nan")}, "dense_reward must be a finite number >= 0"),
    ({"max_episode_steps": 0}, "max_episode_steps must be an integer >= 1 or None, got 0"),
])
def test_bad_values_are_refused_where_the_config_is_made(kwargs, named):
    with pytest.raises(ValueError, match=named):
        EnvConfig(**kwargs)


def test_bad_lifelong_and_league_values_name_the_option():
    with pytest.raises(ValueError, match="tasks must be one of"):
        MRMTLifelongEnv(EnvConfig(tasks="burst"))
    with pytest.raises(ValueError, match="task_rate=3.0 only applies to tasks='poisson'"):
        MRMTLifelongEnv(task_rate=3.0)
    with pytest.raises(ValueError, match="steps must be an integer >= 1, got 0"):
        LoRREnv(EnvConfig(steps=0))


def test_the_env_config_is_frozen_and_its_world_part_is_a_world_config():
    cfg = EnvConfig(height=5, width=6, tasks="poisson")
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.tasks = "refill"
    assert cfg.world_config() == WorldConfig(height=5, width=6)
    assert EnvConfig.of(WorldConfig(height=5, width=6), takes=("height", "width")) == EnvConfig(height=5, width=6)
