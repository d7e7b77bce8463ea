"""A map's shape, as an entry sees it at preprocessing: the share of its free cells in one-cell-wide corridors.

Contract: :func:`corridor_share` ``(grid) -> float`` in [0, 1]; ``grid`` an ``(H, W)`` bool array, True = blocked.
A corridor cell is a free cell whose free 4-neighbours are exactly two opposite ones (north and south, or east and
west; the map's edge counts as blocked): the cells :func:`planners.mapf.guides.guidance.corridor_costs` can make
one-way, as the aisles between a warehouse's shelves or a sortation centre's chutes.  0 on a map without free cells.
Measured (``benchmarks/entry_rules.py shapes``): the 2024 main round's CITY 0.001, GAME 0.003, RANDOM 0.088,
SORTATION 0.569, WAREHOUSE 0.631; the package's families at 32x32..128x128: uniform 0.05, rooms 0.02-0.03,
warehouse 0 (aisles two wide) or 0.24-0.49 (``aisle_width=1``), maze 0.65-0.66.  A 500x140 map: about 1 ms.
"""

from __future__ import annotations

import numpy as np

__all__ = ["corridor_share"]


def corridor_share(grid) -> float:
    """The share of free cells whose free 4-neighbours are exactly two opposite ones (see the module docstring)."""
    free = ~np.asarray(grid, dtype=bool)
    if free.ndim != 2:
        raise ValueError(f"a grid is two-dimensional, got shape {free.shape}")
    total = int(free.sum())
    if total == 0:
        return 0.0
    p = np.pad(free, 1, constant_values=False)
    n, s, w, e = p[:-2, 1:-1], p[2:, 1:-1], p[1:-1, :-2], p[1:-1, 2:]
    corridor = free & ((n & s & ~w & ~e) | (w & e & ~n & ~s))
    return int(corridor.sum()) / total
