"""The lane rule of the guided executors, written from its statement (planners/mapf/guides/guidance.py) for the tests."""

from __future__ import annotations


def lane_cost(grid, p, d, weight):
    """A forward move from flat ``p`` in direction ``d``: 1, or 1 + weight against the lane (even rows
    run east, odd rows west, even columns south, odd columns north; one-cell corridors have none)."""
    r, c = divmod(p, grid.shape[1])
    h, w = grid.shape

    def free(rr, cc):
        return 0 <= rr < h and 0 <= cc < w and not grid[rr, cc]

    if d in (0, 2) and not (free(r - 1, c) or free(r + 1, c)):
        return 1  # a one-cell-wide horizontal corridor has no lane
    if d in (1, 3) and not (free(r, c - 1) or free(r, c + 1)):
        return 1
    against = (d == 0 and r % 2 == 1) or (d == 2 and r % 2 == 0) or (d == 1 and c % 2 == 1) or (
        d == 3 and c % 2 == 0)
    return 1 + weight * against
