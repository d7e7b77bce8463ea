"""Moves between and within robots' open routes, for chip move selection at fleet scale (compiled).

The routes live as linked lists over the world's nodes (robots ``0..R-1`` then targets):
``nxt[x]`` / ``prv[x]`` (-1 past the end; a robot has no predecessor), and :func:`walk` gives
each node's robot (``owner``) and position (robot 0, its first target 1, ...).  Edge ``p`` of a
route joins positions ``p`` and ``p + 1`` (the last edge, to the open end, costs 0).

Candidate moves (granular: ``v`` among the ``k`` nearest nodes of target ``u``):

===== ================ =============================================== =====================
kind  move             what changes                                    edges touched (spans)
===== ================ =============================================== =====================
0     relocate u -> v  ``u`` leaves its place, goes right after ``v``  ``[pos u - 1, pos u]`` and ``[pos v]``
1     swap u, v        ``u`` and ``v`` (other robots) trade places     ``[pos u - 1, pos u]``, ``[pos v - 1, pos v]``
2     2-opt* a, b      tails after ``a`` and after ``b`` (other robots) swap   ``[pos a, end]``, ``[pos b, end]``
3     2-opt a, b       the segment ``nxt a .. b`` of one route reversed ``[pos a, pos b]``
===== ================ =============================================== =====================

Two moves whose spans are disjoint in every route touch disjoint edges, so their gains add and
applying them one after another by node (linked-list operations) gives the sum; two spans in the
same route are merged into one (conservative).  Gains are exact for open routes.  The chip
selects among them with :mod:`planners.ising.moves.selection`.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["walk", "candidate_moves", "apply_move", "route_cost",
           "unlink", "insert_after", "MOVE_KINDS"]

MOVE_KINDS = ("relocate", "swap", "2-opt*", "2-opt")
_EPS = 1e-9


@numba.njit(cache=True)
def walk(nxt, r):
    """``(owner, pos, length)``: each node's robot and position, and each route's target count."""
    m = nxt.shape[0]
    owner = np.full(m, -1, dtype=np.int64)
    pos = np.zeros(m, dtype=np.int64)
    length = np.zeros(r, dtype=np.int64)
    for k in range(r):
        x, p = k, 0
        while x >= 0:
            owner[x] = k
            pos[x] = p
            p += 1
            x = nxt[x]
        length[k] = p - 1
    return owner, pos, length


@numba.njit(cache=True, inline="always")
def _e(d, a, b):
    return 0.0 if b < 0 else d[a, b]


@numba.njit(cache=True)
def route_cost(d, nxt, r):
    total = 0.0
    for k in range(r):
        x = k
        while nxt[x] >= 0:
            total += d[x, nxt[x]]
            x = nxt[x]
    return total


@numba.njit(cache=True, inline="always")
def _add(out, m, kind, a, b, g, span1, span2):
    """Move ``m`` into ``out`` = ``(moves, spans, gains)``; ``span1`` / ``span2`` = ``(route, lo, hi)``."""
    moves, spans, gains = out
    r1, lo1, hi1 = span1
    r2, lo2, hi2 = span2
    moves[m, 0] = kind
    moves[m, 1] = a
    moves[m, 2] = b
    if r1 == r2:  # one route: one merged span
        lo1, hi1 = min(lo1, lo2), max(hi1, hi2)
        r2 = -1
    spans[m, 0] = r1
    spans[m, 1] = lo1
    spans[m, 2] = hi1
    spans[m, 3] = r2
    spans[m, 4] = lo2
    spans[m, 5] = hi2
    gains[m] = g


@numba.njit(cache=True)
def candidate_moves(d, nxt, prv, owner, pos, length, neigh, r):
    """Every improving granular move (module docstring).  Returns ``(moves (M, 3): kind, a, b;
    spans (M, 6): route, lo, hi, route, lo, hi (second route -1 when one); gains (M,))``."""
    m_nodes = nxt.shape[0]
    k = neigh.shape[1]
    cap = (m_nodes - r) * k * 5 + 1
    moves = np.empty((cap, 3), dtype=np.int64)
    spans = np.empty((cap, 6), dtype=np.int64)
    gains = np.empty(cap)
    out = (moves, spans, gains)
    m = 0
    for u in range(r, m_nodes):
        pu, nu, ou = prv[u], nxt[u], owner[u]
        out_u = d[pu, u] + _e(d, u, nu) - _e(d, pu, nu)  # saved by taking u out
        for t in range(k):
            v = neigh[u, t]
            if v < 0 or v == u:
                continue
            ov = owner[v]
            for side in range(2):  # 0: relocate after v, 1: before v (after its predecessor)
                w = v if side == 0 else (prv[v] if v >= r else -1)
                if w < 0 or w == pu or w == u:
                    continue
                wn = nxt[w]
                if wn == u:
                    continue
                g = out_u + _e(d, w, wn) - d[w, u] - _e(d, u, wn)
                if g > _EPS and g < np.inf:
                    _add(out, m, 0, u, w, g, (ou, pos[u] - 1, pos[u]), (owner[w], pos[w], pos[w]))
                    m += 1
            if v < r:
                continue
            pv, nv = prv[v], nxt[v]
            if ov != ou:
                old = d[pu, u] + _e(d, u, nu) + d[pv, v] + _e(d, v, nv)
                new = d[pu, v] + _e(d, v, nu) + d[pv, u] + _e(d, u, nv)
                g = old - new
                if g > _EPS and g < np.inf:
                    _add(out, m, 1, u, v, g, (ou, pos[u] - 1, pos[u]), (ov, pos[v] - 1, pos[v]))
                    m += 1
                # 2-opt*: u -> v, prv[v] -> nxt[u]
                b = pv
                g = _e(d, u, nu) + d[b, v] - d[u, v] - _e(d, b, nu)
                if g > _EPS and g < np.inf:
                    _add(out, m, 2, u, b, g, (ou, pos[u], length[ou]), (ov, pos[b], length[ov]))
                    m += 1
            else:
                a, b = (u, v) if pos[u] < pos[v] else (v, u)
                if pos[b] > pos[a] + 1:  # 2-opt: a -> b, nxt[a] -> nxt[b]
                    an, bn = nxt[a], nxt[b]
                    g = d[a, an] + _e(d, b, bn) - d[a, b] - _e(d, an, bn)
                    if g > _EPS and g < np.inf:
                        _add(out, m, 3, a, b, g, (ou, pos[a], pos[b]), (np.int64(-1), np.int64(0), np.int64(0)))
                        m += 1
    return moves[:m].copy(), spans[:m].copy(), gains[:m].copy()


@numba.njit(cache=True, inline="always")
def unlink(nxt, prv, u):
    """Take node ``u`` out of its route (``u``'s own links are left as they were)."""
    p, n = prv[u], nxt[u]
    nxt[p] = n
    if n >= 0:
        prv[n] = p


@numba.njit(cache=True, inline="always")
def insert_after(nxt, prv, u, x):
    """Put node ``u`` right after node ``x``."""
    w = nxt[x]
    nxt[x] = u
    prv[u] = x
    nxt[u] = w
    if w >= 0:
        prv[w] = u


@numba.njit(cache=True)
def apply_move(nxt, prv, kind, a, b):
    """Apply one move by node (linked lists changed in place)."""
    if kind == 0:  # relocate a after b
        unlink(nxt, prv, a)
        insert_after(nxt, prv, a, b)
    elif kind == 1:  # swap a, b (different routes)
        pa, na, pb, nb = prv[a], nxt[a], prv[b], nxt[b]
        nxt[pa] = b
        prv[b] = pa
        nxt[b] = na
        if na >= 0:
            prv[na] = b
        nxt[pb] = a
        prv[a] = pb
        nxt[a] = nb
        if nb >= 0:
            prv[nb] = a
    elif kind == 2:  # tails after a and after b swap
        an, bn = nxt[a], nxt[b]
        nxt[a] = bn
        if bn >= 0:
            prv[bn] = a
        nxt[b] = an
        if an >= 0:
            prv[an] = b
    else:  # reverse nxt[a] .. b
        an, bn = nxt[a], nxt[b]
        x = an
        while True:
            nx = nxt[x]
            nxt[x] = prv[x]
            prv[x] = nx
            if x == b:
                break
            x = nx
        nxt[a] = b
        prv[b] = a
        nxt[an] = bn
        if bn >= 0:
            prv[bn] = an
