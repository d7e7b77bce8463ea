"""Move-selection formulation of the chip tour (beyond paper 5.2) -- pure functions.

A route is ``r = [0, t_1, ..., t_n]`` (node 0 the robot, open end).  A *move* rewrites the
route inside its span of edges ``[lo, hi]`` (edge ``e`` joins positions ``e`` and ``e + 1``):

* 2-opt ``(i, j)``: reverse positions ``i+1..j`` (span ``[i, j]``);
* or-opt ``(a, b, c)``: move the segment at positions ``a..b`` (1-3 targets), reversed or not,
  to between positions ``c`` and ``c + 1`` (span ``[c, b]`` or ``[a-1, c]``).

Moves whose spans are disjoint touch disjoint edges and positions, so their gains add.  The
selection QUBO over the candidate moves is ``-sum g_m x_m + sum P_mm' x_m x_m'`` over
overlapping pairs with ``P_mm' = min(g_m, g_m') + margin``: its ground states are the
compatible sets of largest total gain and every coefficient is of the size of a gain (no
one-hot penalty dwarfs the costs).  A read selecting overlapping moves is invalid.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["candidate_moves", "pick_candidates", "selection_qubo", "selection_gain", "score_reads", "apply_moves", "MOVE_FIELDS"]

#: Columns of a move row: kind (0 = 2-opt, 1 = or-opt, 2 = or-opt reversed), i/a, j/b, c, lo, hi.
MOVE_FIELDS = ("kind", "p", "q", "c", "lo", "hi")


@numba.njit(cache=True, inline="always")  # called per candidate: no call (and no array reference counting)
def _edge(d, r, p, n):
    return d[r[p], r[p + 1]] if p < n else 0.0


@numba.njit(cache=True)
def candidate_moves(d, r, max_segment):
    """Every improving 2-opt and or-opt move of route ``r`` under ``d``.

    Returns ``(moves (M, 6) int64, gains (M,))``, gains > 0, unsorted.
    """
    n = r.shape[0] - 1
    cap = n * n + 2 * max(max_segment, 1) * n * (n + 1) + 1  # 2-opt moves + or-opt moves, at most
    moves = np.empty((cap, 6), dtype=np.int64)
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
                moves[m, 4] = i
                moves[m, 5] = j
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
                        moves[m, 4] = c if c < a else a - 1
                        moves[m, 5] = b if c < a else c
                        gains[m] = g
                        m += 1
    return moves[:m].copy(), gains[:m].copy()


@numba.njit(cache=True)
def pick_candidates(moves, gains, k, max_overlap):
    """Indices of at most ``k`` moves for one selection program: by gain (ties: index), each
    overlapping at most ``max_overlap`` moves picked before it (a sparse conflict graph keeps the
    penalties -- and so the quantized fields -- small)."""
    order = np.argsort(-gains, kind="mergesort")
    picked = np.empty(min(k, order.shape[0]), dtype=np.int64)
    n = 0
    for m in order:
        if n == picked.shape[0]:
            break
        hits = 0
        for t in range(n):
            o = picked[t]
            if moves[m, 4] <= moves[o, 5] and moves[o, 4] <= moves[m, 5]:
                hits += 1
                if hits > max_overlap:
                    break
        if hits <= max_overlap:
            picked[n] = m
            n += 1
    return picked[:n].copy()


def selection_qubo(moves: np.ndarray, gains: np.ndarray, margin: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(q, Q)`` of the selection QUBO (module docstring); ``Q`` strictly upper triangular."""
    lo, hi = moves[:, 4], moves[:, 5]
    overlap = (lo[:, None] <= hi[None, :]) & (lo[None, :] <= hi[:, None])
    P = np.minimum(gains[:, None], gains[None, :]) + float(margin)
    Q = np.triu(np.where(overlap, P, 0.0), k=1)
    return -np.asarray(gains, dtype=np.float64), Q


@numba.njit(cache=True)
def selection_gain(chosen, moves, gains):
    """``(taken, total gain)`` of one read (``chosen`` bool per move), or ``(None, 0.0)`` when two
    chosen moves overlap (an invalid read)."""
    idx = np.flatnonzero(chosen)
    total = 0.0
    for a in range(idx.shape[0]):
        m = idx[a]
        total += gains[m]
        for b in range(a):
            o = idx[b]
            if moves[m, 4] <= moves[o, 5] and moves[o, 4] <= moves[m, 5]:
                return None, 0.0
    return idx, total


@numba.njit(cache=True)
def score_reads(spins, moves, gains):
    """Every read of one round (``spins (k, reads, M)``, one program per rule) through
    :func:`selection_gain`.  Returns ``(clean (k,), rule, read, gain)``: per rule the valid reads
    that select a move, and the first read of largest total gain (``rule = -1``: none above 0)."""
    k, reads, M = spins.shape
    clean = np.zeros(k, dtype=np.int64)
    best_k, best_r, best = -1, -1, 0.0
    for a in range(k):
        for r in range(reads):
            taken, total = selection_gain(spins[a, r] > 0, moves, gains)
            if taken is None:
                continue
            if taken.shape[0] > 0:
                clean[a] += 1
            if total > best + 1e-9:
                best_k, best_r, best = a, r, total
    return clean, best_k, best_r, best


def apply_moves(r, moves: np.ndarray, taken) -> np.ndarray:
    """Route ``r`` with the (pairwise disjoint) moves ``taken`` applied."""
    r = np.array(r, dtype=np.int64)
    for m in taken:
        kind, p, q, c = (int(v) for v in moves[m, :4])
        if kind == 0:
            r[p + 1:q + 1] = r[p + 1:q + 1][::-1].copy()
            continue
        seg = r[p:q + 1].copy()
        if kind == 2:
            seg = seg[::-1]
        if c < p:
            rest = r[c + 1:p].copy()
            r[c + 1:c + 1 + len(seg)] = seg
            r[c + 1 + len(seg):q + 1] = rest
        else:
            rest = r[q + 1:c + 1].copy()
            r[p:p + len(rest)] = rest
            r[p + len(rest):c + 1] = seg
    return r
