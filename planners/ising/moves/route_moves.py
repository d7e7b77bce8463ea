"""The tour's neighbourhood (beyond paper 5.2): every improving 2-opt and or-opt move of one route.

Contract: :func:`route_moves` lists every improving 2-opt and or-opt (1-3 targets, reversed or not) of the
route read off the tour's linked list, each with its exact gain and its span of edges;
:func:`apply_route_moves` applies them by node (:mod:`.kinds`).  Moves with disjoint spans have additive
gains; the chip selects among them (:mod:`.selection`, spans on route 0).
Design notes (the spans): docs/design/ising_tour.md.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.ising.moves import or_opt, two_opt
from planners.ising.moves.kinds import OR_OPT, TWO_OPT, apply_move

__all__ = ["route_moves", "apply_route_moves", "MOVE_FIELDS"]

#: Columns of a move row: kind (:data:`~planners.ising.moves.kinds.MOVE_KINDS`: 2-opt, or-opt, or-opt
#: reversed), positions i/a, j/b, c.
MOVE_FIELDS = ("kind", "p", "q", "c")


@numba.njit(cache=True, inline="always")  # called per candidate: no call (and no array reference counting)
def _at(r, p, n):
    """The node at position ``p``, -1 past the open end."""
    return r[p] if p <= n else -1


@numba.njit(cache=True)
def route_moves(d, r, max_segment):
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
            g = two_opt.gain(d, r[i], r[i + 1], r[j], _at(r, j + 1, n))
            if g > 1e-9:
                moves[m, 0] = TWO_OPT
                moves[m, 1] = i
                moves[m, 2] = j
                moves[m, 3] = -1
                spans[m, 1] = i
                spans[m, 2] = j
                gains[m] = g
                m += 1
    for a in range(1, n + 1):  # or-opt: segment a..b to between c and c + 1
        for b in range(a, min(n, a + max_segment - 1) + 1):
            for rev in range(2 if b > a else 1):
                for c in range(n + 1):
                    if a - 1 <= c <= b:
                        continue
                    g = or_opt.gain(d, r[a - 1], r[a], r[b], _at(r, b + 1, n), r[c], _at(r, c + 1, n), rev == 1)
                    if g > 1e-9:
                        moves[m, 0] = OR_OPT + rev
                        moves[m, 1] = a
                        moves[m, 2] = b
                        moves[m, 3] = c
                        spans[m, 1] = c if c < a else a - 1
                        spans[m, 2] = b if c < a else c
                        gains[m] = g
                        m += 1
    return moves[:m].copy(), spans[:m].copy(), gains[:m].copy()


@numba.njit(cache=True)
def apply_route_moves(nxt, prv, r, moves, taken):
    """The (pairwise disjoint) moves ``taken`` of ``moves`` (rows on route ``r``'s positions) applied to
    its linked list ``nxt`` / ``prv`` by node, in place."""
    for m in taken:
        kind, p, q, c = moves[m, 0], moves[m, 1], moves[m, 2], moves[m, 3]
        apply_move(nxt, prv, kind, r[p], r[q], r[c] if kind != TWO_OPT else -1)
