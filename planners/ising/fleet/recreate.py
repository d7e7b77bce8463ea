"""The kick of the fleet search's iterated local search: ruin and recreate (host, compiled).

``q`` targets -- a seed target and its nearest targets -- leave their routes, then each, in
the given order, is inserted at its cheapest place over every route (after any node; open
routes, so appending costs one edge).  A classical perturbation: the chip's decisions are the
moves of the local search that follows.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.ising.moves.routes import insert_after, unlink

__all__ = ["ruin_recreate"]


@numba.njit(cache=True)
def ruin_recreate(d, nxt, prv, r, seed, near, q, order):
    """Ruin ``seed`` and the ``q - 1`` first targets of ``near`` (nodes nearest ``seed`` first),
    recreate in ``order`` (a permutation of ``0..q-1``); ``nxt`` / ``prv`` changed in place."""
    m = nxt.shape[0]
    out = np.empty(q, dtype=np.int64)
    out[0] = seed
    c = 1
    for x in near:
        if c == q:
            break
        if x >= r and x != seed:
            out[c] = x
            c += 1
    q = c
    placed = np.ones(m, dtype=np.bool_)
    for i in range(q):  # take them out
        u = out[i]
        unlink(nxt, prv, u, u)
        nxt[u] = -1
        prv[u] = -1
        placed[u] = False
    for i in range(order.shape[0]):
        if order[i] >= q:
            continue
        u = out[order[i]]
        best, best_x = np.inf, -1
        for x in range(m):
            if not placed[x]:
                continue
            w = nxt[x]
            g = d[x, u] + (d[u, w] - d[x, w] if w >= 0 else 0.0)
            if g < best:
                best, best_x = g, x
        insert_after(nxt, prv, u, u, best_x)
        placed[u] = True
