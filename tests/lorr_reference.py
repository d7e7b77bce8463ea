"""Test-side oracles for the League of Robot Runners tests: a plain BFS over a bool grid."""

from __future__ import annotations

from collections import deque

import numpy as np


def bfs(grid: np.ndarray, src: int) -> np.ndarray:
    """Moves from flat cell ``src`` to every flat cell of ``grid`` (True = blocked), -1 unreachable."""
    h, w = grid.shape
    d = np.full(grid.size, -1)
    d[src] = 0
    q = deque([src])
    while q:
        p = q.popleft()
        r, c = divmod(p, w)
        for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
            if 0 <= nr < h and 0 <= nc < w and not grid[nr, nc] and d[nr * w + nc] < 0:
                d[nr * w + nc] = d[p] + 1
                q.append(nr * w + nc)
    return d
