"""Random world generation: the paper's experimental setup (section 6.1).

``generate_world(seed, ...)`` is a pure function of its arguments: obstacles (a uniform draw, or a map family of
:mod:`mrmt_env.maps` with ``layout=``), then robots (``placement``: ``uniform`` or ``centre``) and targets on
distinct free cells of one 4-connected component. Sizes beyond :data:`MAX_GRID_CELLS` or :data:`MAX_FIELD_CELLS`
are a ``ValueError``. Design notes: docs/design/worlds.md#random-worlds.
"""

from __future__ import annotations

import numba
import numpy as np

from mrmt_env.distances import bfs_flat, component_labels
from mrmt_env.maps import LAYOUTS, build_layout, check_layout
from mrmt_env.world import World, WorldError

__all__ = ["generate_world", "PLACEMENTS", "LAYOUTS", "MAX_DRAWS", "MAX_GRID_CELLS", "MAX_FIELD_CELLS",
           "draw_budget", "DEFAULT_DENSITY"]

PLACEMENTS = ("uniform", "centre")

#: Obstacle density of the ``uniform`` layout when none is given (the paper's 20 %).
DEFAULT_DENSITY = 0.2

#: Redraws before giving up (a density near 1 may never give a connected world).
MAX_DRAWS = 10_000
#: Cells a ``uniform`` generation may visit over all its redraws (:func:`draw_budget`).
MAX_DRAW_WORK = 2**24
#: Largest grid (cells; 2048 x 2048), as the world-file readers.
MAX_GRID_CELLS = 2**22
#: Most BFS distance-field cells ``(R + N) x H x W`` of one world (int32 each: 512 MiB).
MAX_FIELD_CELLS = 2**27


def draw_budget(n_cells: int) -> int:
    """Tries of a ``uniform`` draw on ``n_cells`` cells: :data:`MAX_DRAWS` (10,000) up to 1,677 cells,
    fewer on bigger grids (``MAX_DRAW_WORK // n_cells``, at least 100), so a hopeless density fails in
    seconds, not hours."""
    return min(MAX_DRAWS, max(100, MAX_DRAW_WORK // max(int(n_cells), 1)))


def generate_world(
    seed: int | np.random.Generator | None = None,
    height: int = 10,
    width: int = 10,
    obstacle_density: float | None = None,
    n_robots: int = 3,
    n_targets: int = 10,
    placement: str = "uniform",
    layout: str = "uniform",
    layout_options: dict | None = None,
) -> World:
    """Draw a random world (see the module docstring for the rules).

    Args:
        seed: an int seed, a ``numpy.random.Generator`` (advanced in place),
            or ``None`` for fresh entropy.
        obstacle_density: share of obstacle cells of the ``uniform`` layout
            (``None``: 0.2); other layouts take none.
        placement: ``"uniform"`` or ``"centre"``.
        layout: ``"uniform"``, ``"warehouse"``, ``"rooms"`` or ``"maze"``.
        layout_options: the layout's options (:data:`mrmt_env.maps.LAYOUT_OPTIONS`).

    Raises:
        ValueError: bad sizes, a density outside [0, 1), a grid or world
            beyond the limits, too many robots and targets for the free
            cells, or no connected draw in :func:`draw_budget` tries.
    """
    for name, value, lo in (("height", height, 1), ("width", width, 1), ("n_robots", n_robots, 1),
                            ("n_targets", n_targets, 0)):
        whole = isinstance(value, (int, np.integer)) or (
            isinstance(value, (float, np.floating)) and bool(np.isfinite(value)) and float(value).is_integer())
        if isinstance(value, (bool, np.bool_)) or not whole or value < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {value!r}")
    height, width, n_robots, n_targets = int(height), int(width), int(n_robots), int(n_targets)
    n_cells = height * width
    if n_cells > MAX_GRID_CELLS:
        raise ValueError(f"a {height}x{width} grid has {n_cells} cells; at most {MAX_GRID_CELLS} (MAX_GRID_CELLS, "
                         "2048 x 2048)")
    needed = n_robots + n_targets
    if needed * n_cells > MAX_FIELD_CELLS:
        raise ValueError(
            f"{n_robots} robots + {n_targets} targets on a {height}x{width} grid need {needed * n_cells} BFS "
            f"distance-field cells; at most {MAX_FIELD_CELLS} (MAX_FIELD_CELLS, 512 MiB): at most "
            f"{MAX_FIELD_CELLS // n_cells} robots + targets on this grid"
        )
    options = check_layout(layout, layout_options)
    if layout != "uniform":
        if obstacle_density is not None:
            raise ValueError(f"obstacle_density={obstacle_density!r} applies to layout 'uniform' only; the "
                             f"{layout!r} layout's obstacles come from its layout_options")
    elif obstacle_density is None:
        obstacle_density = DEFAULT_DENSITY
    if layout == "uniform" and (isinstance(obstacle_density, (bool, np.bool_)) or not isinstance(
            obstacle_density, (int, float, np.integer, np.floating)) or not (
            np.isfinite(obstacle_density) and 0.0 <= obstacle_density < 1.0)):
        raise ValueError(f"obstacle_density must be in [0, 1), got {obstacle_density!r}")
    if placement not in PLACEMENTS:
        raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    if layout != "uniform":
        return _place(build_layout(layout, rng, height, width, options), rng, layout, n_robots, n_targets,
                      placement)
    n_obstacles = int(round(obstacle_density * n_cells))
    n_free = n_cells - n_obstacles
    if needed > n_free:
        raise ValueError(
            f"{n_robots} robots + {n_targets} targets need {needed} distinct free cells, "
            f"but a {height}x{width} grid with {n_obstacles} obstacles has only {n_free}"
        )
    rows, cols = np.divmod(np.arange(n_cells), width)
    centre = np.array([(height - 1) / 2.0, (width - 1) / 2.0])
    tries = draw_budget(n_cells)
    if placement == "uniform":
        drawn = draw_uniform_cells(rng, n_cells, width, n_obstacles, needed, tries)
        if drawn is not None:
            flat, chosen = drawn
            cells = np.stack([rows[chosen], cols[chosen]], axis=1)
            return World(flat.reshape(height, width), cells[:n_robots], cells[n_robots:])
    for _ in range(tries if placement != "uniform" else 0):
        flat = np.zeros(n_cells, dtype=bool)
        flat[rng.choice(n_cells, size=n_obstacles, replace=False)] = True
        grid = flat.reshape(height, width)
        # centre placement: the largest free component, then the 5R cells nearest the centre
        comp = _largest_component(grid)
        comp_idx = np.flatnonzero(comp.ravel())
        if len(comp_idx) < needed:
            continue
        d2 = (rows[comp_idx] - centre[0]) ** 2 + (cols[comp_idx] - centre[1]) ** 2
        near = comp_idx[np.argsort(d2, kind="stable")[: 5 * n_robots]]
        robots_idx = rng.choice(near, size=n_robots, replace=False)
        rest = np.setdiff1d(comp_idx, robots_idx)
        targets_idx = rng.choice(rest, size=n_targets, replace=False)
        robots = np.stack([rows[robots_idx], cols[robots_idx]], axis=1)
        targets = np.stack([rows[targets_idx], cols[targets_idx]], axis=1)
        try:
            return World(grid, robots, targets)
        except WorldError:  # pragma: no cover - connectivity is checked above
            continue
    raise ValueError(
        f"no draw of {n_obstacles} obstacles on a {height}x{width} grid put {n_robots} robots and "
        f"{n_targets} targets in one connected component in {tries} tries (draw_budget); lower the density"
    )


@numba.njit(cache=True, nogil=True)
def cells_connected(flat_grid, width, cells) -> bool:
    """Whether the flat cells ``cells`` all lie in one 4-connected free component of ``flat_grid``."""
    field = np.full(flat_grid.shape[0], -1, dtype=np.int32)
    queue = np.empty(flat_grid.shape[0], dtype=np.int64)
    field[cells[0]] = 0
    queue[0] = cells[0]
    bfs_flat(flat_grid, width, field, queue, 1)
    for i in range(cells.shape[0]):
        if field[cells[i]] < 0:
            return False
    return True


def draw_uniform_cells(rng: np.random.Generator, n_cells: int, width: int, n_obstacles: int, needed: int,
                       tries: int):
    """The ``uniform`` layout with ``uniform`` placement, written once for every env: per try,
    ``n_obstacles`` obstacle cells then ``needed`` distinct free cells (robots first) drawn by
    ``rng.choice``, until all of them are connected; ``(flat grid bool (H*W,), chosen flat cells)``,
    or ``None`` after ``tries`` draws."""
    for _ in range(tries):
        flat = np.zeros(n_cells, dtype=bool)
        flat[rng.choice(n_cells, size=n_obstacles, replace=False)] = True
        chosen = rng.choice(np.flatnonzero(~flat), size=needed, replace=False).astype(np.int64)
        if cells_connected(flat, width, chosen):
            return flat, chosen
    return None


def _largest_component(grid: np.ndarray) -> np.ndarray:
    """Mask of the largest 4-connected free component (first found in row-major order on ties)."""
    labels, sizes = component_labels(grid)
    if len(sizes) == 0:
        return np.zeros(grid.shape, dtype=bool)
    return labels == int(np.argmax(sizes))


def _place(layout, rng: np.random.Generator, name: str, n_robots: int, n_targets: int, placement: str) -> World:
    """Robots and targets on a map family's grid (see the module docstring); no retries."""
    grid = layout.grid
    height, width = grid.shape
    comp = _largest_component(grid).reshape(-1)
    free_idx = np.flatnonzero(comp)
    if layout.target_cells is None:
        target_pool, robot_pool = free_idx, free_idx
        if n_robots + n_targets > len(free_idx):
            raise ValueError(
                f"{n_robots} robots + {n_targets} targets need {n_robots + n_targets} distinct free cells, but this "
                f"{height}x{width} {name} map has only {len(free_idx)}"
            )
    else:
        pick = np.zeros(grid.size, dtype=bool)
        pick[layout.target_cells] = True
        target_pool = np.flatnonzero(pick & comp)
        robot_pool = np.flatnonzero(comp & ~pick)
        if n_targets > len(target_pool) or n_robots > len(robot_pool):
            raise ValueError(
                f"{n_robots} robots + {n_targets} targets do not fit this {height}x{width} {name} map: it has "
                f"{len(target_pool)} target (pick) cells and {len(robot_pool)} other free cells for robots"
            )
    rows, cols = np.divmod(np.arange(grid.size), width)
    if placement == "uniform":
        robots_idx = rng.choice(robot_pool, size=n_robots, replace=False)
    else:
        d2 = (rows[robot_pool] - (height - 1) / 2.0) ** 2 + (cols[robot_pool] - (width - 1) / 2.0) ** 2
        near = robot_pool[np.argsort(d2, kind="stable")[: 5 * n_robots]]
        robots_idx = rng.choice(near, size=n_robots, replace=False)
    rest = target_pool[np.isin(target_pool, robots_idx, invert=True)]  # sorted, as target_pool
    targets_idx = rng.choice(rest, size=n_targets, replace=False)
    robots = np.stack([rows[robots_idx], cols[robots_idx]], axis=1)
    targets = np.stack([rows[targets_idx], cols[targets_idx]], axis=1)
    return World(grid, robots, targets)
