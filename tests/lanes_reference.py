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


def corridor_cost(grid, p, d, weight):
    """Extra cost of a move from flat ``p`` in direction ``d`` against a one-way corridor, from the statement:
    a corridor is a maximal run of free cells with no free neighbour across (vertical: none east or west, a
    free cell north or south), open at both ends; corridors whose north (west) end lies on the same line are
    counted along it, the even ones running south (east), the odd ones north (west)."""
    h, w = grid.shape

    def free(rr, cc):
        return 0 <= rr < h and 0 <= cc < w and not grid[rr, cc]

    r, c = divmod(p, w)
    vertical = d in (1, 3)

    def inner(rr, cc):
        if not free(rr, cc):
            return False
        if vertical:
            return not free(rr, cc - 1) and not free(rr, cc + 1) and (free(rr - 1, cc) or free(rr + 1, cc))
        return not free(rr - 1, cc) and not free(rr + 1, cc) and (free(rr, cc - 1) or free(rr, cc + 1))

    if not inner(r, c):
        return 0
    step = (1, 0) if vertical else (0, 1)
    r0, c0 = r, c
    while inner(r0 - step[0], c0 - step[1]):
        r0, c0 = r0 - step[0], c0 - step[1]
    r1, c1 = r, c
    while inner(r1 + step[0], c1 + step[1]):
        r1, c1 = r1 + step[0], c1 + step[1]
    if not (free(r0 - step[0], c0 - step[1]) and free(r1 + step[0], c1 + step[1])):
        return 0  # a dead end keeps both ways

    def corridor_start(rr, cc):  # a corridor open at both ends starts here
        if not inner(rr, cc) or inner(rr - step[0], cc - step[1]) or not free(rr - step[0], cc - step[1]):
            return False
        er, ec = rr, cc
        while inner(er + step[0], ec + step[1]):
            er, ec = er + step[0], ec + step[1]
        return free(er + step[0], ec + step[1])

    if vertical:
        rank = sum(corridor_start(r0, cc) for cc in range(c0))
    else:
        rank = sum(corridor_start(rr, c0) for rr in range(r0))
    forward = 1 if vertical else 0  # south / east
    against = (d != forward) if rank % 2 == 0 else (d == forward)
    return weight * against
