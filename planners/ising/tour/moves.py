"""Move-selection formulation of the chip tour (beyond paper 5.2): the candidate moves of one route.

A route is ``r = [0, t_1, ..., t_n]`` (node 0 the robot, open end).  A *move* rewrites the
route inside its span of edges ``[lo, hi]`` (edge ``e`` joins positions ``e`` and ``e + 1``):

* 2-opt ``(i, j)``: reverse positions ``i+1..j`` (span ``[i, j]``);
* or-opt ``(a, b, c)``: move the segment at positions ``a..b`` (1-3 targets), reversed or not,
  to between positions ``c`` and ``c + 1`` (span ``[c, b]`` or ``[a-1, c]``).

Moves whose spans are disjoint touch disjoint edges and positions, so their gains add; the
chip selects among them as in the fleet search (:mod:`planners.ising.moves.selection`, spans on
route 0).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["candidate_moves", "apply_moves", "MOVE_FIELDS"]

#: Columns of a move row: kind (0 = 2-opt, 1 = or-opt, 2 = or-opt reversed), i/a, j/b, c.
MOVE_FIELDS = ("kind", "p", "q", "c")


@numba.njit(cache=True, inline="always")  # called per candidate: no call (and no array reference counting)
def _edge(d, r, p, n):
    return d[r[p], r[p + 1]] if p < n else 0.0


@numba.njit(cache=True)
def candidate_moves(d, r, max_segment):
    """Every improving 2-opt and or-opt move of route ``r`` under ``d``.

    Returns ``(moves (M, 4) int64, spans (M, 6) int64, gains (M,))``, gains > 0, unsorted; a
    move's spans row is ``0, lo, hi, -1, 0, 0`` (:data:`planners.ising.moves.selection.SPAN_FIELDS`).
    """
    n = r.shape[0] - 1
    cap = n * n + 2 * max(max_segment, 1) * n * (n + 1) + 1  # 2-opt moves + or-opt moves, at most
    moves = np.empty((cap, 4), dtype=np.int64)
    spans = np.zeros((cap, 6), dtype=np.int64)
    spans[:, 3] = -1
    gains = np.empty(cap)
    m = 0
    for i in range(n - 1):  # 2-opt: reverse i+1..j
        for j in range(i + 2, n + 1):
            g = d[r[i], r[i + 1]] - d[r[i], r[j]]
            if j < n:
                g += d[r[j], r[j + 1]] - d[r[i + 1], r[j + 1]]
            if g > 1e-9:
                moves[m, 0] = 0
                moves[m, 1] = i
                moves[m, 2] = j
                moves[m, 3] = -1
                spans[m, 1] = i
                spans[m, 2] = j
                gains[m] = g
                m += 1
    for a in range(1, n + 1):  # or-opt: segment a..b to between c and c + 1
        for b in range(a, min(n, a + max_segment - 1) + 1):
            out = d[r[a - 1], r[a]] + _edge(d, r, b, n)
            close = d[r[a - 1], r[b + 1]] if b < n else 0.0
            for rev in range(2 if b > a else 1):
                first = r[b] if rev else r[a]
                last = r[a] if rev else r[b]
                for c in range(n + 1):
                    if a - 1 <= c <= b:
                        continue
                    g = out + _edge(d, r, c, n) - close - d[r[c], first]
                    if c < n:
                        g -= d[last, r[c + 1]]
                    if g > 1e-9:
                        moves[m, 0] = 1 + rev
                        moves[m, 1] = a
                        moves[m, 2] = b
                        moves[m, 3] = c
                        spans[m, 1] = c if c < a else a - 1
                        spans[m, 2] = b if c < a else c
                        gains[m] = g
                        m += 1
    return moves[:m].copy(), spans[:m].copy(), gains[:m].copy()


@numba.njit(cache=True)
def apply_moves(route, moves, taken):
    """Route ``route`` with the (pairwise disjoint) moves ``taken`` applied, in place."""
    for m in taken:
        kind, p, q, c = moves[m, 0], moves[m, 1], moves[m, 2], moves[m, 3]
        if kind == 0:
            route[p + 1:q + 1] = route[p + 1:q + 1][::-1].copy()
            continue
        seg = route[p:q + 1].copy()
        if kind == 2:
            seg = seg[::-1].copy()
        L = seg.shape[0]
        if c < p:
            rest = route[c + 1:p].copy()
            route[c + 1:c + 1 + L] = seg
            route[c + 1 + L:q + 1] = rest
        else:
            rest = route[q + 1:c + 1].copy()
            route[p:p + rest.shape[0]] = rest
            route[p + rest.shape[0]:c + 1] = seg
