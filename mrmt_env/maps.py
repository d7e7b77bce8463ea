"""Map families: seeded obstacle layouts beyond uniform random obstacles.

:func:`build_layout` turns ``(family, rng, height, width, options)`` into a :class:`Layout` (the obstacle grid and
the cells targets may use) for ``warehouse``, ``rooms`` or ``maze`` (options and defaults in
:data:`LAYOUT_OPTIONS`); the free cells are one 4-connected component, and a seed gives the same map everywhere.
Design notes: docs/design/worlds.md#map-families; pictures: docs/maps.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np

__all__ = ["LAYOUTS", "LAYOUT_OPTIONS", "Layout", "build_layout", "check_layout"]

#: Families :func:`~mrmt_env.generation.generate_world` knows; ``uniform`` is the paper's draw.
LAYOUTS = ("uniform", "warehouse", "rooms", "maze")

#: Options of each family and their defaults (``uniform`` has ``obstacle_density`` instead).
LAYOUT_OPTIONS: dict[str, dict[str, float]] = {
    "uniform": {},
    "warehouse": {"shelf_length": 10, "shelf_depth": 2, "aisle_width": 2, "cross_aisle_width": 2, "margin": 2},
    "rooms": {"room_size": 7, "door_width": 1, "extra_doors": 0.5},
    "maze": {"loops": 0.0},
}

#: Bounds of the integer options (inclusive); the float options lie in [0, 1].
_INT_BOUNDS = {"shelf_length": (1, 2048), "shelf_depth": (1, 2048), "aisle_width": (1, 2048),
               "cross_aisle_width": (1, 2048), "margin": (1, 2048), "room_size": (1, 2048), "door_width": (1, 2048)}


@dataclass(frozen=True)
class Layout:
    """An obstacle grid (``True`` = obstacle) and the cells targets may use (``None``: any free cell)."""

    grid: np.ndarray
    target_cells: np.ndarray | None = None


def check_layout(layout, options) -> dict:
    """The family's full options (defaults filled in); ``ValueError`` naming a bad family, key or value."""
    if not isinstance(layout, str) or layout not in LAYOUTS:
        raise ValueError(f"layout must be one of {LAYOUTS}, got {layout!r}")
    if options is None:
        options = {}
    if not isinstance(options, dict):
        raise ValueError(f"layout_options must be a dict or None, got {type(options).__name__}")
    allowed = LAYOUT_OPTIONS[layout]
    unknown = sorted(str(k) for k in options if k not in allowed)
    if unknown:
        raise ValueError(f"unknown layout_options {unknown} for layout {layout!r}; allowed: {sorted(allowed) or 'none'}")
    out = {**allowed, **options}
    for key, value in out.items():
        if key in _INT_BOUNDS:
            lo, hi = _INT_BOUNDS[key]
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
                raise ValueError(f"layout option {key} must be an integer in [{lo}, {hi}], got {value!r}")
            out[key] = int(value)
        else:
            if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)) \
                    or not (np.isfinite(value) and 0.0 <= value <= 1.0):
                raise ValueError(f"layout option {key} must be a number in [0, 1], got {value!r}")
            out[key] = float(value)
    return out


def build_layout(layout: str, rng: np.random.Generator, height: int, width: int, options: dict | None = None) -> Layout:
    """The ``layout`` family's map on an ``height x width`` grid (not ``uniform``: see the module docstring).

    Raises:
        ValueError: an unknown family or option, or a grid too small for the family's parameters.
    """
    opts = check_layout(layout, options)
    if layout == "warehouse":
        return _warehouse(height, width, **opts)
    if layout == "rooms":
        return Layout(_rooms(rng, height, width, **opts))
    if layout == "maze":
        return Layout(_maze(rng, height, width, **opts))
    raise ValueError("the uniform layout is drawn by generate_world itself")


# ------------------------------------------------------------------ warehouse
def _warehouse(height, width, shelf_length, shelf_depth, aisle_width, cross_aisle_width, margin) -> Layout:
    need_h, need_w = 2 * margin + shelf_depth, 2 * margin + shelf_length
    if height < need_h or width < need_w:
        raise ValueError(
            f"a warehouse with margin {margin}, shelf_depth {shelf_depth} and shelf_length {shelf_length} needs "
            f"height >= {need_h} and width >= {need_w}, got {height}x{width}"
        )
    inner_h, inner_w = height - 2 * margin, width - 2 * margin
    n_rows = (inner_h + aisle_width) // (shelf_depth + aisle_width)
    n_cols = (inner_w + cross_aisle_width) // (shelf_length + cross_aisle_width)
    used_h = n_rows * (shelf_depth + aisle_width) - aisle_width
    used_w = n_cols * (shelf_length + cross_aisle_width) - cross_aisle_width
    top, left = margin + (inner_h - used_h) // 2, margin + (inner_w - used_w) // 2
    grid = np.zeros((height, width), dtype=bool)
    for i in range(n_rows):
        r0 = top + i * (shelf_depth + aisle_width)
        for j in range(n_cols):
            c0 = left + j * (shelf_length + cross_aisle_width)
            grid[r0:r0 + shelf_depth, c0:c0 + shelf_length] = True
    beside = np.zeros_like(grid)
    beside[1:] |= grid[:-1]
    beside[:-1] |= grid[1:]
    beside[:, 1:] |= grid[:, :-1]
    beside[:, :-1] |= grid[:, 1:]
    return Layout(grid, np.flatnonzero((beside & ~grid).ravel()))


# ---------------------------------------------------------------------- rooms
def _splits(length: int, size: int) -> list[tuple[int, int]]:
    """``[start, stop)`` of each room along one axis: ``k`` rooms of >= ``size`` cells, one-cell walls between."""
    k = max(1, (length + 1) // (size + 1))
    walls = [(i * (length + 1)) // k - 1 for i in range(1, k)]
    starts = [0] + [p + 1 for p in walls]
    stops = walls + [length]
    return list(zip(starts, stops))


class _Wall(NamedTuple):
    """The wall between two neighbouring rooms, where a door may go."""

    a: int  # the rooms
    b: int
    is_row: bool  # the wall is a grid row (else a column)
    index: int  # that row or column
    start: int  # the span the rooms share along it
    stop: int


def _rooms(rng, height, width, room_size, door_width, extra_doors) -> np.ndarray:
    rows, cols = _splits(height, room_size), _splits(width, room_size)
    grid = np.zeros((height, width), dtype=bool)
    for _, stop in rows[:-1]:
        grid[stop, :] = True
    for _, stop in cols[:-1]:
        grid[:, stop] = True
    nr, nc = len(rows), len(cols)
    edges = []
    for i in range(nr):
        for j in range(nc):
            if i + 1 < nr:
                edges.append(_Wall(i * nc + j, (i + 1) * nc + j, True, rows[i][1], *cols[j]))
            if j + 1 < nc:
                edges.append(_Wall(i * nc + j, i * nc + j + 1, False, cols[j][1], *rows[i]))
    if not edges:
        return grid
    order = rng.permutation(len(edges))
    extra = rng.random(len(edges)) < extra_doors
    spans = np.array([e.stop - e.start for e in edges], dtype=np.int64)
    widths = np.minimum(spans, door_width)
    offsets = rng.integers(0, spans - widths + 1)
    parent = list(range(nr * nc))

    def root(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    door = extra.copy()
    for e in order.tolist():
        ra, rb = root(edges[e].a), root(edges[e].b)
        if ra != rb:
            parent[ra] = rb
            door[e] = True
    for e in np.flatnonzero(door).tolist():
        wall = edges[e]
        lo = wall.start + int(offsets[e])
        if wall.is_row:
            grid[wall.index, lo:lo + int(widths[e])] = False
        else:
            grid[lo:lo + int(widths[e]), wall.index] = False
    return grid


# ----------------------------------------------------------------------- maze
@numba.njit(cache=True, nogil=True)
def _carve(n_r, n_c, keys, start, grid):  # pragma: no cover - compiled
    """Recursive backtracker on the ``n_r x n_c`` lattice (grid cell ``(2i, 2j)``): at the top of the stack,
    go to the unvisited neighbour with the largest key; pop when there is none."""
    visited = np.zeros(n_r * n_c, dtype=np.bool_)
    stack = np.empty(n_r * n_c, dtype=np.int64)
    di = (-1, 1, 0, 0)
    dj = (0, 0, -1, 1)
    visited[start] = True
    stack[0] = start
    top = 1
    while top > 0:
        cur = stack[top - 1]
        i, j = cur // n_c, cur % n_c
        best, best_key = -1, -1.0
        for m in range(4):
            ni, nj = i + di[m], j + dj[m]
            if 0 <= ni < n_r and 0 <= nj < n_c and not visited[ni * n_c + nj] and keys[cur, m] > best_key:
                best, best_key = m, keys[cur, m]
        if best < 0:
            top -= 1
            continue
        ni, nj = i + di[best], j + dj[best]
        grid[2 * i + di[best], 2 * j + dj[best]] = False
        nxt = ni * n_c + nj
        visited[nxt] = True
        stack[top] = nxt
        top += 1


def _maze(rng, height, width, loops) -> np.ndarray:
    n_r, n_c = (height + 1) // 2, (width + 1) // 2
    grid = np.ones((height, width), dtype=bool)
    grid[0:2 * n_r:2, 0:2 * n_c:2] = False
    keys = rng.random((n_r * n_c, 4))
    start = int(rng.integers(n_r * n_c))
    _carve(n_r, n_c, keys, start, grid)
    if loops > 0.0:
        # inner walls still standing between two lattice cells, row-major
        walls = np.zeros_like(grid)
        walls[0:2 * n_r:2, 1:2 * n_c - 1:2] = True
        walls[1:2 * n_r - 1:2, 0:2 * n_c:2] = True
        closed = np.flatnonzero((walls & grid).ravel())
        k = int(round(loops * len(closed)))
        if k:
            grid.reshape(-1)[closed[rng.choice(len(closed), size=k, replace=False)]] = False
    return grid
