"""What an entry sees of an instance at preprocessing (:class:`Shape`): its team, the map's cells, robots per free
cell, and two measures of the map's shape.

Contract: :func:`shape_of` ``(instance) -> Shape``; :func:`corridor_share` and :func:`narrow_share`
``(grid) -> float`` in [0, 1] (``grid`` an ``(H, W)`` bool array, True = blocked).
Design notes (the measures, measured shares): docs/design/lorr_simulator.md#what-an-entry-sees-shape.
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
