"""World draws for the vector envs: :func:`~mrmt_env.generation.generate_world` without the ``World`` object.

:func:`draw_world_arrays` makes the same random calls, in the same order, as
``generate_world`` and returns the same grid, robots and targets as arrays,
with a compiled connectivity check instead of validating a ``World`` (about
a tenth of the time).  ``centre`` placement, the map families other than
``uniform`` and fixed worlds go through ``generate_world`` itself.  ``tests/test_vector_envs.py`` checks the two
against each other draw for draw.
"""

from __future__ import annotations

import numba
import numpy as np

from mrmt_env.distances import bfs_flat
from mrmt_env.generation import DEFAULT_DENSITY, draw_budget, generate_world
from mrmt_env.pcg64 import MAX_POP, choice_floyd, state_views
from mrmt_env.world import World

__all__ = ["draw_world_arrays", "node_distances"]


@numba.njit(cache=True, nogil=True)
def _all_connected(flat_grid, width, cells) -> bool:
    field = np.full(flat_grid.shape[0], -1, dtype=np.int32)
    queue = np.empty(flat_grid.shape[0], dtype=np.int64)
    field[cells[0]] = 0
    queue[0] = cells[0]
    bfs_flat(flat_grid, width, field, queue, 1)
    for i in range(cells.shape[0]):
        if field[cells[i]] < 0:
            return False
    return True


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


@numba.njit(cache=True, nogil=True)
def _draw_uniform(state, buf, n_cells, n_obstacles, needed, width, tries):
    """The retry loop of :func:`draw_world_arrays` on a PCG64 state (:mod:`mrmt_env.pcg64`):
    ``(flat grid, chosen cells, ok)``, the generator advanced exactly as numpy's would be
    (the caller guarantees ``needed <= n_cells - n_obstacles``)."""
    flat = np.zeros(n_cells, dtype=np.bool_)
    obstacles = np.empty(n_obstacles, dtype=np.int64)
    free_idx = np.empty(n_cells, dtype=np.int64)
    pick = np.empty(needed, dtype=np.int64)
    chosen = np.empty(needed, dtype=np.int64)
    for _ in range(tries):
        flat[:] = False
        choice_floyd(state, buf, n_cells, n_obstacles, obstacles)
        for k in range(n_obstacles):
            flat[obstacles[k]] = True
        n_free = 0
        for c in range(n_cells):
            if not flat[c]:
                free_idx[n_free] = c
                n_free += 1
        choice_floyd(state, buf, n_free, needed, pick)
        for k in range(needed):
            chosen[k] = free_idx[pick[k]]
        if _all_connected(flat, width, chosen):
            return flat, chosen, True
    return flat, chosen, False


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
    tries = draw_budget(n_cells)
    needed = n_robots + n_targets
    views = state_views(rng) if n_cells <= MAX_POP and needed >= 1 else None
    if views is not None and needed <= n_cells - n_obstacles:  # the compiled draw, draw for draw
        flat, chosen, ok = _draw_uniform(views[0], views[1], n_cells, n_obstacles, needed, width, tries)
        if ok:
            return flat, chosen[:n_robots].copy(), chosen[n_robots:].copy()
    else:  # numpy's own draws (another bit generator, a grid above MAX_POP, or too few free cells)
        for _ in range(tries):
            flat = np.zeros(n_cells, dtype=bool)
            flat[rng.choice(n_cells, size=n_obstacles, replace=False)] = True
            free_idx = np.flatnonzero(~flat)
            chosen = rng.choice(free_idx, size=needed, replace=False)
            if _all_connected(flat, width, chosen):
                return flat, chosen[:n_robots].astype(np.int64), chosen[n_robots:].astype(np.int64)
    raise ValueError(  # pragma: no cover - the same limit as generate_world's
        f"no draw of {n_obstacles} obstacles on a {height}x{width} grid put {n_robots} robots and "
        f"{n_targets} targets in one connected component in {tries} tries (draw_budget); lower the density"
    )
