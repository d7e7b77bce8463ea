"""World draws for the vector envs: :func:`~mrmt_env.generation.generate_world` without the ``World`` object.

:func:`draw_world_arrays` returns the grid, robots and targets ``generate_world`` would, as flat
arrays: the ``uniform`` draws are the one :func:`~mrmt_env.generation.draw_uniform_cells` both use
(no ``World`` validated); ``centre`` placement, the map families other than ``uniform`` and fixed
worlds go through ``generate_world`` itself.
"""

from __future__ import annotations

import numba
import numpy as np

from mrmt_env.distances import bfs_flat
from mrmt_env.generation import DEFAULT_DENSITY, draw_budget, draw_uniform_cells, generate_world
from mrmt_env.world import World

__all__ = ["draw_world_arrays", "node_distances"]


@numba.njit(cache=True, nogil=True)
def node_distances(flat_grid, width, nodes, out) -> None:
    """``out[a, b]``: BFS moves between flat cells ``nodes[a]`` and ``nodes[b]`` (-1 if disconnected)."""
    field = np.empty(flat_grid.shape[0], dtype=np.int32)
    queue = np.empty(flat_grid.shape[0], dtype=np.int64)
    for a in range(nodes.shape[0]):
        field[:] = -1
        field[nodes[a]] = 0
        queue[0] = nodes[a]
        bfs_flat(flat_grid, width, field, queue, 1)
        for b in range(nodes.shape[0]):
            out[a, b] = field[nodes[b]]


def draw_world_arrays(rng: np.random.Generator, params: dict, fixed: World | None = None):
    """``(flat_grid bool (H*W,), robot cells (R,), target cells (N,))`` as flat indices ``r * W + c``.

    The same world ``generate_world(rng, **params)`` returns (and ``rng``
    advanced the same way); a fixed world is returned as it is.
    """
    if fixed is None and (params["placement"] != "uniform" or params.get("layout", "uniform") != "uniform"):
        fixed = generate_world(rng, **params)
    if fixed is not None:
        w = fixed.width
        return (fixed.grid.reshape(-1), fixed.robots[:, 0] * w + fixed.robots[:, 1],
                fixed.targets[:, 0] * w + fixed.targets[:, 1])
    height, width = int(params["height"]), int(params["width"])
    n_robots, n_targets = int(params["n_robots"]), int(params["n_targets"])
    n_cells = height * width
    density = params.get("obstacle_density")
    n_obstacles = int(round((DEFAULT_DENSITY if density is None else density) * n_cells))
    needed = n_robots + n_targets
    drawn = draw_uniform_cells(rng, n_cells, width, n_obstacles, needed, draw_budget(n_cells))
    if drawn is None:  # pragma: no cover - the env's parameters were checked by generate_world
        raise ValueError(f"no connected draw of {n_obstacles} obstacles on a {height}x{width} grid "
                         "(draw_budget); lower the density")
    flat, chosen = drawn
    return flat, chosen[:n_robots].copy(), chosen[n_robots:].copy()
