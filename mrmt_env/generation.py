"""Random world generation: the paper's experimental setup (section 6.1).

``generate_world(seed, ...)`` is a pure function of its arguments:

* exactly ``round(obstacle_density * (H * W))`` obstacle cells (Python's
  round, half to even), sampled
  uniformly without replacement (20 on the paper's 10x10 grid);
* robots and targets on pairwise distinct free cells;
* the draw is repeated (from the same random stream) until every robot and
  target lies in one 4-connected free component.

Two robot placements:

``uniform``
    robots uniform over the free cells, like the targets.
``centre``
    the placement of the first author's public course project: robots drawn
    from the ``5 * R`` free cells of the largest component nearest the grid
    centre (Euclidean, ties by row-major order), targets uniform over the
    remaining cells of that component.  With it, SSA + exact tours gives the
    paper's median total 28 and makespan 16 on 3 robots x 10 targets.
"""

from __future__ import annotations

import numpy as np

from mrmt_env.distances import bfs_distance_field
from mrmt_env.world import World, WorldError

__all__ = ["generate_world", "PLACEMENTS", "MAX_DRAWS"]

PLACEMENTS = ("uniform", "centre")

#: Redraws before giving up (a density near 1 may never give a connected world).
MAX_DRAWS = 10_000


def _component_of(grid: np.ndarray, cell) -> np.ndarray:
    return bfs_distance_field(grid, cell) >= 0


def generate_world(
    seed: int | np.random.Generator | None = None,
    height: int = 10,
    width: int = 10,
    obstacle_density: float = 0.2,
    n_robots: int = 3,
    n_targets: int = 10,
    placement: str = "uniform",
) -> World:
    """Draw a random world (see the module docstring for the rules).

    Args:
        seed: an int seed, a ``numpy.random.Generator`` (advanced in place),
            or ``None`` for fresh entropy.
        placement: ``"uniform"`` or ``"centre"``.

    Raises:
        ValueError: bad sizes, a density outside [0, 1), too many robots and
            targets for the free cells, or no connected draw in
            :data:`MAX_DRAWS` tries.
    """
    for name, value, lo in (("height", height, 1), ("width", width, 1), ("n_robots", n_robots, 1),
                            ("n_targets", n_targets, 0)):
        if int(value) != value or value < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {value!r}")
    if not (np.isfinite(obstacle_density) and 0.0 <= obstacle_density < 1.0):
        raise ValueError(f"obstacle_density must be in [0, 1), got {obstacle_density!r}")
    if placement not in PLACEMENTS:
        raise ValueError(f"placement must be one of {PLACEMENTS}, got {placement!r}")
    n_cells = height * width
    n_obstacles = int(round(obstacle_density * n_cells))
    n_free = n_cells - n_obstacles
    needed = n_robots + n_targets
    if needed > n_free:
        raise ValueError(
            f"{n_robots} robots + {n_targets} targets need {needed} distinct free cells, "
            f"but a {height}x{width} grid with {n_obstacles} obstacles has only {n_free}"
        )
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    rows, cols = np.divmod(np.arange(n_cells), width)
    centre = np.array([(height - 1) / 2.0, (width - 1) / 2.0])
    for _ in range(MAX_DRAWS):
        flat = np.zeros(n_cells, dtype=bool)
        flat[rng.choice(n_cells, size=n_obstacles, replace=False)] = True
        grid = flat.reshape(height, width)
        free_idx = np.flatnonzero(~flat)
        if placement == "uniform":
            chosen = rng.choice(free_idx, size=needed, replace=False)
            robots_idx, targets_idx = chosen[:n_robots], chosen[n_robots:]
            cells = np.stack([rows[chosen], cols[chosen]], axis=1)
            comp = _component_of(grid, cells[0])
            if not comp[cells[:, 0], cells[:, 1]].all():
                continue
        else:
            # largest free component, then the 5R cells nearest the centre
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
        f"{n_targets} targets in one connected component in {MAX_DRAWS} tries"
    )


def _largest_component(grid: np.ndarray) -> np.ndarray:
    """Mask of the largest 4-connected free component (first found on ties)."""
    unseen = ~grid.copy()
    best = np.zeros_like(grid)
    best_size = 0
    while unseen.any():
        r, c = np.argwhere(unseen)[0]
        comp = _component_of(grid, (r, c))
        unseen &= ~comp
        size = int(comp.sum())
        if size > best_size:
            best, best_size = comp, size
    return best
