"""Crisscross guidance for the turning executors: one-way preferences on a grid, as move costs.

A forward move costs 1, or ``1 + weight`` against the lane's preferred direction: even rows prefer
east and odd rows west, even columns south and odd columns north (the human-designed "crisscross"
guidance graph of Zhang et al., "Guidance Graph Optimization for Lifelong Multi-Agent Path
Finding", IJCAI 2024); a corridor one cell wide has no lane (both ways cost 1).  Robots then keep to lanes, which breaks the head-on meetings that jam
PIBT on crowded maps.  Goal fields become the least guided cost to the goal (Dijkstra instead of
BFS); a turn or a wait costs 1.  Measurements: ``docs/design/lifelong_turning.md``.
"""

from __future__ import annotations

import numba
import numpy as np


__all__ = ["check_guidance", "crisscross_costs", "corridor_costs", "move_costs", "distance_bound", "cost_rows", "spread",
           "MAX_GUIDANCE"]

#: Largest extra cost of a move against its lane.
MAX_GUIDANCE = 16


def check_guidance(weight, name: str = "guidance") -> int:
    """``weight`` as an int; ``ValueError`` naming it (as ``name``) unless it is an integer in 0..:data:`MAX_GUIDANCE`."""
    if isinstance(weight, bool) or not isinstance(weight, (int, np.integer)) or not 0 <= weight <= MAX_GUIDANCE:
        what = "its lane" if name == "guidance" else "a one-way corridor"
        raise ValueError(f"{name} must be an integer in 0..{MAX_GUIDANCE} (extra cost of a move against "
                         f"{what}), got {weight!r}")
    return int(weight)


def crisscross_costs(nbr: np.ndarray, cell_of: np.ndarray, width: int, weight: int) -> np.ndarray:
    """``(n, 4)`` int64 cost of a forward move from compact cell ``i`` in direction ``d`` (0 east,
    1 south, 2 west, 3 north): 1 along the lane's direction, ``1 + weight`` against it.  A corridor
    one cell wide has no lane: a horizontal move from a cell with neither a free cell above nor below
    costs 1 both ways (and a vertical one likewise); else maps whose corridors share a row parity
    (sortation_large: every corridor on an odd row) would be one-way throughout."""
    weight = check_guidance(weight)
    row, col = cell_of // width, cell_of % width
    cost = np.ones((len(cell_of), 4), dtype=np.int64)
    wide_h = (nbr[:, 1] >= 0) | (nbr[:, 3] >= 0)  # a horizontal lane needs a neighbour lane
    wide_v = (nbr[:, 0] >= 0) | (nbr[:, 2] >= 0)
    east, south = row % 2 == 0, col % 2 == 0
    cost[~east & wide_h, 0] += weight
    cost[east & wide_h, 2] += weight
    cost[~south & wide_v, 1] += weight
    cost[south & wide_v, 3] += weight
    return cost


def corridor_costs(nbr: np.ndarray, cell_of: np.ndarray, width: int, weight: int) -> np.ndarray:
    """``(n, 4)`` int64 extra cost of a move along a corridor one cell wide against its one-way direction.

    A corridor: a run of free cells with no free neighbour across it (vertical: none east or west),
    open at both ends (a dead end keeps both ways).  Corridors whose first cell (north or west end) lies
    on the same line are numbered along it; even ones run south (east), odd ones north (west), so
    neighbouring corridors carry opposite ways, as the aisles between a warehouse's shelves.  A move from
    a corridor cell against its way costs ``weight`` more; 0 everywhere else."""
    weight = check_guidance(weight, "corridors")
    n = len(cell_of)
    extra = np.zeros((n, 4), dtype=np.int64)
    if weight == 0:
        return extra
    for fwd, across in ((1, 0), (0, 1)):  # vertical corridors (moves south / north), then horizontal
        back = fwd + 2
        inner = (nbr[:, across] < 0) & (nbr[:, across + 2] < 0) & ((nbr[:, fwd] >= 0) | (nbr[:, back] >= 0))
        prev = nbr[:, back]
        first = inner & ~((prev >= 0) & inner[np.maximum(prev, 0)])
        runs = []
        for s in np.flatnonzero(first).tolist():
            cells = [s]
            while nbr[cells[-1], fwd] >= 0 and inner[nbr[cells[-1], fwd]]:
                cells.append(int(nbr[cells[-1], fwd]))
            if nbr[s, back] >= 0 and nbr[cells[-1], fwd] >= 0:  # open at both ends
                line, at = divmod(int(cell_of[s]), width) if fwd == 1 else divmod(int(cell_of[s]), width)[::-1]
                runs.append((line, at, cells))
        runs.sort(key=lambda r: (r[0], r[1]))
        rank, last = 0, None
        for line, _, cells in runs:
            rank = rank + 1 if line == last else 0
            last = line
            extra[cells, back if rank % 2 == 0 else fwd] += weight
    return extra


def move_costs(nbr: np.ndarray, cell_of: np.ndarray, width: int, lanes: int, corridors: int) -> np.ndarray | None:
    """Forward-move costs of crisscross ``lanes`` (:func:`crisscross_costs`) plus one-way ``corridors``
    (:func:`corridor_costs`); ``None`` when both weights are 0 (every move costs 1)."""
    lanes, corridors = check_guidance(lanes), check_guidance(corridors, "corridors")
    if not lanes and not corridors:
        return None
    return crisscross_costs(nbr, cell_of, width, lanes) + corridor_costs(nbr, cell_of, width, corridors)


def distance_bound(nbr: np.ndarray, cost: np.ndarray, per_cell: int) -> int:
    """An upper bound on any finite guided distance: twice the largest BFS eccentricity of one cell
    per connected component (a bound on every component's diameter in moves) times the costliest
    move (plus two turns a move over (cell, orientation))."""
    n = nbr.shape[0]
    field = np.empty((1, n), dtype=np.uint32)
    far = np.iinfo(np.uint32).max
    seen = np.zeros(n, dtype=bool)
    ecc = 0
    for start in range(n):
        if seen[start]:
            continue
        _reach(nbr, start, field[0], far)
        reached = field[0] != far
        seen |= reached
        ecc = max(ecc, int(field[0][reached].max()))
    step = int(cost.max()) + (2 if per_cell == 4 else 0)
    return (2 * ecc + 1) * step + 2


@numba.njit(cache=True, nogil=True)
def _reach(nbr, start, f, far):
    """BFS moves from compact ``start`` into ``f`` (``far`` where not reached)."""
    f[:] = far
    f[start] = 0
    queue = np.empty(nbr.shape[0], dtype=np.int64)
    queue[0] = start
    spread(nbr, f, far, queue, 1)


@numba.njit(cache=True, nogil=True)
def spread(nbr, f, far, queue, tail, step=1):
    """Breadth-first from the seeds ``queue[:tail]`` (their ``f`` set, every other cell ``far``): a cell
    reached gets its parent's value + ``step`` (1: its depth; 0: its nearest seed's value), the seeds' order
    deciding among parents of equal depth."""
    head = 0
    while head < tail:
        p = queue[head]
        head += 1
        for d in range(4):
            q = nbr[p, d]
            if q >= 0 and f[q] == far:
                f[q] = f[p] + step
                queue[tail] = q
                tail += 1


@numba.njit(cache=True, nogil=True)
def _push(node, d, ent_node, ent_next, head, m):
    """Queue entry ``m`` of ``node`` into bucket ``d`` (a bucket: a linked list through the entries)."""
    ent_node[m] = node
    ent_next[m] = head[d]
    head[d] = m


@numba.njit(cache=True, nogil=True)
def cost_rows(nbr, cost, goals, rows, fields, far):
    """``fields[rows[i], v]`` = least cost from compact ``v`` to ``goals[i]`` under the move costs
    ``cost[v, d]`` (Dijkstra backwards with a bucket per cost modulo the largest move cost + 1, as
    costs are small integers; ``far`` where unreachable)."""
    n = nbr.shape[0]
    span = cost.max() + 1
    dist = np.empty(n, dtype=np.int64)
    ent_node, ent_next = np.empty(4 * n + 1, dtype=np.int64), np.empty(4 * n + 1, dtype=np.int64)
    head = np.empty(span, dtype=np.int64)
    for i in range(goals.shape[0]):
        dist[:] = far
        head[:] = -1
        dist[goals[i]] = 0
        _push(goals[i], 0, ent_node, ent_next, head, 0)
        m, pending, d = 1, 1, 0
        while pending > 0:
            e = head[d % span]
            head[d % span] = -1
            while e != -1:
                p, e = ent_node[e], ent_next[e]
                pending -= 1
                if dist[p] != d:
                    continue
                for k in range(4):
                    q = nbr[p, k]  # q -> p is a move in direction k + 2
                    if q >= 0:
                        nd = d + cost[q, (k + 2) & 3]
                        if nd < dist[q]:
                            dist[q] = nd
                            _push(q, nd % span, ent_node, ent_next, head, m)
                            m += 1
                            pending += 1
            d += 1
        f = fields[rows[i]]
        for v in range(n):
            f[v] = min(dist[v], far)
