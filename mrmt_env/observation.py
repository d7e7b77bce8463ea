"""Observation encoding shared by the Gymnasium and PettingZoo environments.

A channel-first binary image ``Box(0, 1, (2 + R, H, W), uint8)``: obstacles, unvisited targets, one channel per
robot (a PettingZoo agent's observation adds a channel for its own cell). :func:`world_from_observation` rebuilds a world from it;
:func:`agent_index_from_observation` recovers an agent's robot.
Design notes: docs/design/envs.md#observations.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from mrmt_env.world import World

__all__ = [
    "OBSTACLE_CHANNEL",
    "TARGET_CHANNEL",
    "ROBOT_CHANNEL0",
    "observation_space",
    "agent_observation_space",
    "encode_observation",
    "world_from_observation",
    "agent_index_from_observation",
    "MIN_IMAGE_SIDE",
    "image_scale",
    "image_observation_space",
    "to_image",
]

OBSTACLE_CHANNEL = 0
TARGET_CHANNEL = 1
ROBOT_CHANNEL0 = 2


def observation_space(n_robots: int, height: int, width: int) -> spaces.Box:
    """The global observation space ``Box(0, 1, (2 + R, H, W), uint8)``."""
    return spaces.Box(0, 1, (2 + n_robots, height, width), np.uint8)


#: Smallest image side SB3's ``CnnPolicy`` (NatureCNN) accepts.
MIN_IMAGE_SIDE = 36


def image_scale(height: int, width: int) -> int:
    """Pixels per cell of the image observation: the least ``s`` with ``s * min(H, W) >= 36``."""
    return max(1, -(-MIN_IMAGE_SIDE // min(int(height), int(width))))


def image_observation_space(n_robots: int, height: int, width: int) -> spaces.Box:
    """The image form of the global observation: ``Box(0, 255, (2 + R, s*H, s*W), uint8)``, ``s = image_scale(H, W)``."""
    s = image_scale(height, width)
    return spaces.Box(0, 255, (2 + n_robots, s * height, s * width), np.uint8)


def to_image(obs: np.ndarray) -> np.ndarray:
    """A binary observation ``(..., C, H, W)`` as an image ``(..., C, s*H, s*W)``: 0 -> 0, 1 -> 255,
    each cell an ``s x s`` block (SB3 treats a uint8 ``Box(0, 255)`` of side >= 36 as an image)."""
    a = np.asarray(obs)
    s = image_scale(a.shape[-2], a.shape[-1])
    img = a * np.uint8(255)
    return np.repeat(np.repeat(img, s, axis=-2), s, axis=-1)


def agent_observation_space(n_robots: int, height: int, width: int) -> spaces.Box:
    """A PettingZoo agent's space: the global channels plus its own cell, ``(3 + R, H, W)``."""
    return spaces.Box(0, 1, (3 + n_robots, height, width), np.uint8)


def encode_observation(world: World, positions=None, visited=None) -> np.ndarray:
    """Encode a world (optionally with current robot cells and visited flags).

    Args:
        world: the world (grid and targets; robots are its start cells unless
            ``positions`` is given).
        positions: ``(R, 2)`` current robot cells, default ``world.robots``.
        visited: length-``N`` booleans, ``True`` = target already visited
            (its channel-1 cell is 0); default none visited.
    """
    h, w = world.shape
    pos = world.robots if positions is None else np.asarray(positions, dtype=np.int64).reshape(-1, 2)
    if len(pos) != world.n_robots:
        raise ValueError(f"positions has {len(pos)} cells, the world has {world.n_robots} robots")
    obs = np.zeros((2 + world.n_robots, h, w), dtype=np.uint8)
    obs[OBSTACLE_CHANNEL] = world.grid
    vis = np.zeros(world.n_targets, dtype=bool) if visited is None else np.asarray(visited, dtype=bool)
    if vis.shape != (world.n_targets,):
        raise ValueError(f"visited must have shape ({world.n_targets},), got {vis.shape}")
    todo = world.targets[~vis]
    obs[TARGET_CHANNEL, todo[:, 0], todo[:, 1]] = 1
    for k, (r, c) in enumerate(pos):
        obs[ROBOT_CHANNEL0 + k, r, c] = 1
    return obs


def world_from_observation(obs) -> World:
    """Rebuild the :class:`World` an observation shows.

    Args:
        obs: a global observation ``(2 + R, H, W)`` (for a PettingZoo agent
            observation pass ``obs[:-1]``).

    Returns:
        ``World(grid=channel 0, robots=current robot cells in robot order,
        targets=unvisited targets in row-major order)``.

    Raises:
        ValueError: wrong rank, fewer than 3 channels, values other than
            0/1, or a robot channel without exactly one marked cell.
    """
    a = np.asarray(obs)
    if a.ndim != 3:
        raise ValueError(f"observation must have shape (2 + R, H, W), got shape {a.shape}")
    if a.shape[0] < 3:
        raise ValueError(f"observation needs at least 3 channels (obstacles, targets, >= 1 robot), got {a.shape[0]}")
    bad = ~((a == 0) | (a == 1))
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(
            f"observation values must be 0 or 1, got {a[where].item()!r} at [channel, row, col] = {list(where)} "
            f"({int(bad.sum())} bad value(s))"
        )
    grid = a[OBSTACLE_CHANNEL].astype(bool)
    targets = np.argwhere(a[TARGET_CHANNEL] == 1)  # row-major order
    robots = []
    for k in range(a.shape[0] - ROBOT_CHANNEL0):
        cells = np.argwhere(a[ROBOT_CHANNEL0 + k] == 1)
        if len(cells) != 1:
            raise ValueError(f"robot channel {ROBOT_CHANNEL0 + k} (robot {k}) marks {len(cells)} cells, expected exactly 1")
        robots.append(cells[0])
    return World(grid, np.array(robots, dtype=np.int64), targets.astype(np.int64))


def agent_index_from_observation(agent_obs) -> int:
    """Which robot a PettingZoo agent observation ``(3 + R, H, W)`` belongs to.

    Robots sharing the agent's cell are indistinguishable in the observation;
    the lowest such index is returned (the agent name ``robot_k`` is exact).
    """
    a = np.asarray(agent_obs)
    if a.ndim != 3 or a.shape[0] < 4:
        raise ValueError(f"agent observation must have shape (3 + R, H, W), got shape {a.shape}")
    own = a[-1]
    for k in range(a.shape[0] - 3):
        if np.array_equal(a[ROBOT_CHANNEL0 + k], own):
            return k
    raise ValueError("the own-cell channel matches no robot channel")
