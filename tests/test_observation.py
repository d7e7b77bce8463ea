"""Observation encoding and world_from_observation."""

from __future__ import annotations

import numpy as np
import pytest

from mrmt_env import World, generate_world, world_from_observation
from mrmt_env.observation import agent_index_from_observation, encode_observation, observation_space
from mrmt_env.render import render_rgb


def test_encode_decode_round_trip():
    w = generate_world(8)
    obs = encode_observation(w)
    assert obs.dtype == np.uint8 and obs.shape == (5, 10, 10)
    assert observation_space(3, 10, 10).contains(obs)
    assert np.array_equal(obs[0].astype(bool), w.grid)
    assert obs[1].sum() == 10 and all(obs[2 + k].sum() == 1 for k in range(3))
    back = world_from_observation(obs)
    order = np.lexsort((w.targets[:, 1], w.targets[:, 0]))
    assert back == w.replace(targets=w.targets[order])


def test_visited_and_positions():
    w = generate_world(8)
    vis = np.zeros(10, dtype=bool)
    vis[[0, 3]] = True
    pos = w.targets[:3]
    obs = encode_observation(w, positions=pos, visited=vis)
    back = world_from_observation(obs)
    assert back.n_targets == 8 and np.array_equal(back.robots, pos)
    with pytest.raises(ValueError, match=r"visited must have shape \(10,\)"):
        encode_observation(w, visited=[True])
    with pytest.raises(ValueError, match="positions has 1 cells, the world has 3 robots"):
        encode_observation(w, positions=[[0, 0]])


def test_world_from_observation_errors():
    obs = encode_observation(World(np.zeros((2, 2), bool), [[0, 0]], [[1, 1]]))
    with pytest.raises(ValueError, match=r"shape \(2 \+ R, H, W\)"):
        world_from_observation(obs[0])
    with pytest.raises(ValueError, match="at least 3 channels"):
        world_from_observation(obs[:2])
    bad = obs.copy()
    bad[0, 0, 1] = 2
    with pytest.raises(ValueError, match="0 or 1"):
        world_from_observation(bad)
    bad = obs.copy()
    bad[2, 1, 0] = 1
    with pytest.raises(ValueError, match=r"robot channel 2 \(robot 0\) marks 2 cells"):
        world_from_observation(bad)
    bad = obs.copy()
    bad[2] = 0
    with pytest.raises(ValueError, match="marks 0 cells"):
        world_from_observation(bad)


def test_agent_index_errors():
    with pytest.raises(ValueError, match=r"\(3 \+ R, H, W\)"):
        agent_index_from_observation(np.zeros((3, 2, 2), np.uint8))
    o = np.zeros((4, 2, 2), np.uint8)
    o[2, 0, 0] = 1
    o[3, 1, 1] = 1
    with pytest.raises(ValueError, match="matches no robot channel"):
        agent_index_from_observation(o)


def test_render_rgb_rejects_tiny_cells():
    w = generate_world(0)
    with pytest.raises(ValueError, match="cell must be an integer >= 4"):
        render_rgb(w.grid, w.targets, [False] * 10, w.robots, cell=2)
