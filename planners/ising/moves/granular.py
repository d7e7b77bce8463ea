"""The fleet search's neighbourhood: the improving granular moves within and between robots' routes.

Contract: :func:`granular_moves` lists, over the routes' linked lists (:mod:`.routes`) and each target's
``k`` nearest nodes, every improving or-opt (relocation), swap, 2-opt* and 2-opt move with its exact gain
(open routes) and its edge spans, each kind priced and applied by its file (:mod:`.kinds`).  Moves whose
spans are disjoint in every route have additive gains; the chip selects among them (:mod:`.selection`).
Design notes (the spans): docs/design/ising_fleet.md.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.ising.moves import or_opt, swap, two_opt, two_opt_star
from planners.ising.moves.kinds import OR_OPT, SWAP, TWO_OPT, TWO_OPT_STAR

__all__ = ["granular_moves"]

_EPS = 1e-9


@numba.njit(cache=True, inline="always")
def _add(out, m, kind, a, b, c, g, span1, span2):
    """Move ``m`` (``kind, a, b, c``) into ``out`` = ``(moves, spans, gains)``; ``span1`` / ``span2`` =
    ``(route, lo, hi)``."""
    moves, spans, gains = out
    r1, lo1, hi1 = span1
    r2, lo2, hi2 = span2
    moves[m, 0] = kind
    moves[m, 1] = a
    moves[m, 2] = b
    moves[m, 3] = c
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
def granular_moves(d, nxt, prv, owner, pos, length, neigh, r):
    """Every improving granular move (module docstring).  Returns ``(moves (M, 4): kind, a, b, c;
    spans (M, 6): route, lo, hi, route, lo, hi (second route -1 when one); gains (M,))``."""
    m_nodes = nxt.shape[0]
    k = neigh.shape[1]
    cap = (m_nodes - r) * k * 5 + 1
    moves = np.empty((cap, 4), dtype=np.int64)
    spans = np.empty((cap, 6), dtype=np.int64)
    gains = np.empty(cap)
    out = (moves, spans, gains)
    none = (np.int64(-1), np.int64(0), np.int64(0))
    m = 0
    for u in range(r, m_nodes):
        pu, nu, ou = prv[u], nxt[u], owner[u]
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
                g = or_opt.gain(d, pu, u, u, nu, w, wn, False)
                if g > _EPS and g < np.inf:
                    _add(out, m, OR_OPT, u, u, w, g, (ou, pos[u] - 1, pos[u]), (owner[w], pos[w], pos[w]))
                    m += 1
            if v < r:
                continue
            pv, nv = prv[v], nxt[v]
            if ov != ou:
                g = swap.gain(d, pu, u, nu, pv, v, nv)
                if g > _EPS and g < np.inf:
                    _add(out, m, SWAP, u, v, -1, g, (ou, pos[u] - 1, pos[u]), (ov, pos[v] - 1, pos[v]))
                    m += 1
                b = pv  # 2-opt*: u -> v, prv[v] -> nxt[u]
                g = two_opt_star.gain(d, u, nu, b, v)
                if g > _EPS and g < np.inf:
                    _add(out, m, TWO_OPT_STAR, u, b, -1, g, (ou, pos[u], length[ou]), (ov, pos[b], length[ov]))
                    m += 1
            else:
                a, b = (u, v) if pos[u] < pos[v] else (v, u)
                if pos[b] > pos[a] + 1:  # 2-opt: a -> b, nxt[a] -> nxt[b]
                    g = two_opt.gain(d, a, nxt[a], b, nxt[b])
                    if g > _EPS and g < np.inf:
                        _add(out, m, TWO_OPT, a, b, -1, g, (ou, pos[a], pos[b]), none)
                        m += 1
    return moves[:m].copy(), spans[:m].copy(), gains[:m].copy()
