"""What an entry sees of an instance at preprocessing (:class:`Shape`): its team, the map's cells, robots per free
cell, and two measures of the map's shape.

Contract: :func:`shape_of` ``(instance) -> Shape``; :func:`corridor_share` and :func:`narrow_share` ``(grid) ->
float`` in [0, 1] (``grid`` an ``(H, W)`` bool array, True = blocked; 0 on a map without free cells; the map's edge
counts as blocked; about 1 ms on a 500x140 map).

* ``corridors``: the share of free cells whose free 4-neighbours are exactly two opposite ones (north and south, or
  east and west): the cells :func:`planners.mapf.guides.guidance.corridor_costs` can make one-way, the aisles between
  a warehouse's shelves or a sortation centre's chutes.
* ``narrow``: the share of free cells with at most two free 4-neighbours (corridors, their bends and dead ends: a
  maze's passages); it tells a maze from a warehouse where ``corridors`` cannot.

Measured (``benchmarks/entry_rules.py shapes``), corridors / narrow: the 2024 main round's CITY 0.001 / 0.054, GAME
0.003 / 0.042, RANDOM 0.088 / 0.221, SORTATION 0.569 / 0.569, WAREHOUSE 0.631 / 0.641; the package's families at
32x32..128x128: uniform 0.05 / 0.19-0.24, rooms 0.02-0.03 / 0.08-0.09, warehouse 0 / 0.00-0.01 (aisles two wide) or
0.24-0.49 / 0.25-0.49 (``aisle_width=1``), maze 0.65-0.67 / 0.949-0.953.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

__all__ = ["Shape", "shape_of", "corridor_share", "narrow_share", "MEASURES"]


class Shape(NamedTuple):
    """An instance as an entry's rules read it."""

    robots: int       # team size
    cells: int        # the map's cells, blocked ones too
    fill: float       # robots per free cell
    corridors: float  # corridor_share of the map
    narrow: float     # narrow_share of the map


#: The measures an entry's rule may bound (``min_<measure>`` / ``max_<measure>``).
MEASURES = Shape._fields


def _free_and_neighbours(grid):
    free = ~np.asarray(grid, dtype=bool)
    if free.ndim != 2:
        raise ValueError(f"a grid is two-dimensional, got shape {free.shape}")
    p = np.pad(free, 1, constant_values=False)
    return free, (p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:])


def corridor_share(grid) -> float:
    """The share of free cells whose free 4-neighbours are exactly two opposite ones (module docstring)."""
    free, (n, s, w, e) = _free_and_neighbours(grid)
    total = int(free.sum())
    corridor = free & ((n & s & ~w & ~e) | (w & e & ~n & ~s))
    return int(corridor.sum()) / total if total else 0.0


def narrow_share(grid) -> float:
    """The share of free cells with at most two free 4-neighbours (module docstring)."""
    free, (n, s, w, e) = _free_and_neighbours(grid)
    total = int(free.sum())
    degree = n.astype(np.int8) + s + w + e
    return int((free & (degree <= 2)).sum()) / total if total else 0.0


def shape_of(instance) -> Shape:
    """The :class:`Shape` of ``instance`` (a :class:`~mrmt_env.lorr.instance.LoRRInstance`)."""
    grid = instance.grid
    return Shape(int(instance.team_size), int(grid.size), instance.team_size / max(int((~grid).sum()), 1),
                 corridor_share(grid), narrow_share(grid))
