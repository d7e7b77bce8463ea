"""Compiled host kernels of Ising pathfinding (paper 5.1): patch ranking and sample scoring.

Contract: :func:`rank_local_targets` gives the patch cells 4-connected to the robot and the local targets
ranked as :class:`IsingPath` ranks them (one call per robot position); :func:`score_patch_samples` decodes
every read of one submission, applies the strict simple-path check of
:func:`~planners.ising.path.decode.decode_paths` and scores the original (unmerged) Ising energy.
Oracles: :mod:`.qubo`, :mod:`.decode` and ``IsingPath``.  Design notes: docs/design/ising_path.md.
"""

from __future__ import annotations

from functools import lru_cache

import numba
import numpy as np

from planners.ising.path.qubo import patch_frame

__all__ = ["rank_local_targets", "score_patch_samples", "extract_path", "neighbour_table", "cut_walk"]


def neighbour_table(frame) -> np.ndarray:
    """``(n, 4)`` int64: the 4-neighbours of every patch cell (``-1`` padded), ascending (read-only)."""
    return _neighbour_table(frame.size)


@lru_cache(maxsize=8)
def _neighbour_table(size: int) -> np.ndarray:
    frame = patch_frame(size)
    tab = np.full((frame.n, 4), -1, dtype=np.int64)
    for i, nb in enumerate(frame.neighbours):
        tab[i, : len(nb)] = nb
    tab.setflags(write=False)
    return tab


@numba.njit(cache=True)
def rank_local_targets(padded, pr, pc, gr, gc, size, nbr, ring, excluded, interior, merged, field):
    """Component of the robot cell and its ranked local targets.

    Args:
        padded: ``(H + 2r, W + 2r)`` bool obstacles, padded with ``True`` by ``r = size // 2``.
        pr, pc / gr, gc: robot / goal cell (grid coordinates).
        nbr: :func:`neighbour_table`; ring: ``(n,)`` bool patch-boundary cells.
        excluded: ``(H + 2r, W + 2r)`` bool: cells that may not be a local target
            (the robot's walk, targets that failed from this position).
        interior: interior cells are targets after the boundary; merged: rank boundary and
            interior cells together (``target_order="merged"``).
        field: ``(H + 2r, W + 2r)`` int64 distance to the goal per cell (``target_key="bfs"``),
            or an empty ``(0, 0)`` array for the Manhattan distance (the paper's rule).

    Returns ``(comp (n,) bool, ranked (m,) int64 patch-cell indices)``.
    """
    n = size * size
    rad = size // 2
    centre = n // 2
    comp = np.zeros(n, dtype=np.bool_)
    stack = np.empty(n, dtype=np.int64)
    if not padded[pr + rad, pc + rad]:
        comp[centre] = True
        stack[0] = centre
        top = 1
        while top > 0:
            top -= 1
            i = stack[top]
            for k in range(4):
                j = nbr[i, k]
                if j < 0:
                    break
                if not comp[j] and not padded[pr + j // size, pc + j % size]:
                    comp[j] = True
                    stack[top] = j
                    top += 1
    keys = np.empty(n, dtype=np.int64)
    cand = np.empty(n, dtype=np.int64)
    m = 0
    for i in range(n):
        if not comp[i] or i == centre:
            continue
        dr = i // size - rad
        dc = i % size - rad
        if excluded[pr + rad + dr, pc + rad + dc]:
            continue
        r = pr + dr
        c = pc + dc
        if r == gr and c == gc:
            cls = 0
        elif ring[i]:
            cls = 1
        else:
            cls = 2
        if cls == 2 and not interior:
            continue
        if field.shape[0] > 0:
            to_goal = np.int64(field[r + rad, c + rad])
        else:
            to_goal = np.int64(abs(r - gr) + abs(c - gc))
        from_pos = abs(dr) + abs(dc)
        if merged:  # lexsort((idx, from_pos, cls, to_goal, cls != 0))
            key = (((np.int64(cls != 0) * 4294967296 + to_goal) * 4 + cls) * 1024 + from_pos) * 4096 + i
        else:  # lexsort((idx, from_pos, to_goal, cls))
            key = ((np.int64(cls) * 4294967296 + to_goal) * 1024 + from_pos) * 4096 + i
        keys[m] = key
        cand[m] = i
        m += 1
    order = np.argsort(keys[:m])
    return comp, cand[:m][order]


@numba.njit(cache=True)
def score_patch_samples(spins, ptr, idx, n_logical, cells, start, goal, nbr, h, J, offset):
    """Decode, check and score every read of the programs of one patch problem.

    Args:
        spins: ``(P, R, W)`` int8 physical spins of ``P`` programs (merge styles) x ``R`` reads.
        ptr, idx: ``(P, n + 1)`` / ``(P, >= N)`` copy layouts of the programs (majority decode,
            a tie to the original copy).
        n_logical: number of patch variables ``n``; cells: ``(n,)`` their patch-cell indices.
        start, goal: the pinned endpoints (patch-cell indices); nbr: :func:`neighbour_table`.
        h, J, offset: the logical Ising model of the patch QUBO (the original objective).

    Returns ``(n_valid (P,) int64, best (P,) int64, energy (P,) float64, logical (P, R, n) int8)``:
    a read is valid when its selected cells plus the endpoints form one simple, induced
    4-connected path from start to goal; per program the number of valid reads, the first
    valid read of lowest original energy (``-1``: none) and that energy (``inf``: none).
    """
    P = spins.shape[0]
    R = spins.shape[1]
    n = n_logical
    nc = nbr.shape[0]
    n_valid = np.zeros(P, dtype=np.int64)
    best = np.full(P, -1, dtype=np.int64)
    energy = np.full(P, np.inf)
    logical = np.zeros((P, R, n), dtype=np.int8)
    sel = np.zeros(nc, dtype=np.bool_)
    buf = np.empty(nc, dtype=np.int64)
    for p in range(P):
        for r in range(R):
            s = spins[p, r]
            x = logical[p, r]
            for i in range(n):
                c0 = ptr[p, i]
                c1 = ptr[p, i + 1]
                v = s[i]
                if c1 - c0 > 1:
                    tot = 0
                    for c in range(c0, c1):
                        tot += np.int64(s[idx[p, c]])
                    v = 1 if tot > 0 else (-1 if tot < 0 else s[idx[p, c0]])
                x[i] = v
            sel[:] = False
            total = 2
            for i in range(n):
                if x[i] > 0:
                    sel[cells[i]] = True
                    total += 1
            sel[start] = True
            sel[goal] = True
            if not _walk(sel, start, goal, nbr, total, buf):
                continue
            n_valid[p] += 1
            e = offset
            for i in range(n):
                e += h[i] * x[i]
                for j in range(i + 1, n):
                    e += J[i, j] * x[i] * x[j]
            if e < energy[p]:
                energy[p] = e
                best[p] = r
    return n_valid, best, energy, logical


@numba.njit(cache=True)
def extract_path(x, cells, start, goal, nbr):
    """The ordered patch cells from ``start`` to ``goal`` selected by 0/1 ``x`` (one per entry of
    ``cells``, endpoints pinned), or an empty array unless they form one simple, induced
    4-connected path (the rule of :func:`score_patch_samples`)."""
    nc = nbr.shape[0]
    sel = np.zeros(nc, dtype=np.bool_)
    total = 2
    for i in range(x.shape[0]):
        if x[i]:
            sel[cells[i]] = True
            total += 1
    sel[start] = True
    sel[goal] = True
    path = np.empty(total, dtype=np.int64)
    if _walk(sel, start, goal, nbr, total, path):
        return path
    return np.zeros(0, dtype=np.int64)


@numba.njit(cache=True)
def _walk(sel, start, goal, nbr, total, out):
    """Whether the ``total`` selected cells form one simple, induced 4-connected path from
    ``start`` to ``goal`` (every selected cell has two selected neighbours, each endpoint one, and
    the walk from ``start`` covers them all); the path's cells go into ``out``."""
    nc = nbr.shape[0]
    for i in range(nc):
        if sel[i]:
            deg = 0
            for k in range(4):
                j = nbr[i, k]
                if j < 0:
                    break
                deg += sel[j]
            if deg != (1 if (i == start or i == goal) else 2):
                return False
    out[0] = start
    prev = -1
    cur = start
    steps = 1
    while cur != goal:
        nxt = -1
        for k in range(4):
            j = nbr[cur, k]
            if j < 0:
                break
            if sel[j] and j != prev:
                nxt = j
                break
        if nxt < 0 or steps >= total:
            return False
        prev = cur
        cur = nxt
        out[steps] = cur
        steps += 1
    return steps == total


@numba.njit(cache=True)
def cut_walk(walk, grid, sr, sc, gr, gc, cut):
    """The walk ``(L, 2)`` with its loops cut (when ``cut``: a revisit of a cell drops the cells
    since its first visit, so every step is a step of the walk) and ``ok`` -- whether it is a 4-neighbour path from
    ``(sr, sc)`` to ``(gr, gc)`` over free cells.  Returns ``(ok, path (L', 2))``."""
    H, W = grid.shape
    n = walk.shape[0]
    out = np.empty((n, 2), dtype=np.int64)
    m = 0
    if cut:
        where = np.full(H * W, -1, dtype=np.int64)
        for t in range(n):
            r, c = walk[t, 0], walk[t, 1]
            inside = 0 <= r < H and 0 <= c < W
            k = where[r * W + c] if inside else -1
            if k >= 0:  # a revisit: drop the loop since the first visit
                for u in range(k + 1, m):
                    where[out[u, 0] * W + out[u, 1]] = -1
                m = k + 1
            else:
                if inside:
                    where[r * W + c] = m
                out[m, 0], out[m, 1] = r, c
                m += 1
    else:
        out[:, :] = walk
        m = n
    if m == 0:
        return False, out[:0]
    ok = out[0, 0] == sr and out[0, 1] == sc and out[m - 1, 0] == gr and out[m - 1, 1] == gc
    for t in range(m):
        r, c = out[t, 0], out[t, 1]
        if not (0 <= r < H and 0 <= c < W) or grid[r, c]:
            ok = False
        if t and abs(r - out[t - 1, 0]) + abs(c - out[t - 1, 1]) != 1:
            ok = False
    return ok, out[:m]
