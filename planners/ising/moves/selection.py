"""The chip's move selection, shared by the tour and the fleet search (compiled).

A candidate move rewrites the edges of at most two routes: its *spans* row is ``route, lo, hi,
route2, lo2, hi2`` (edges ``lo..hi`` of ``route``; ``route2 = -1`` when it touches one route).
Two moves *clash* when they touch a common edge; moves that clash with none of the others touch
disjoint edges, so their gains add.  The selection QUBO over ``M`` offered moves is
``-sum g_m x_m + sum P_mm' x_m x_m'`` over clashing pairs with ``P_mm' = min(g_m, g_m') + margin``:
its ground states are the compatible sets of largest total gain and every coefficient is of the
size of a gain (no one-hot penalty dwarfs the costs).  A read selecting two clashing moves is
invalid.  The host rule in the chip's place takes the offered moves by gain, each that clashes
with none taken (:func:`greedy_selection`).
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend.numeric import ising_of_qubo

__all__ = ["SPAN_FIELDS", "clash", "conflicts", "pick_candidates", "selection_qubo", "selection_ising",
           "read_gain", "score_reads", "greedy_selection"]

#: Columns of a spans row.
SPAN_FIELDS = ("route", "lo", "hi", "route2", "lo2", "hi2")
_EPS = 1e-9


@numba.njit(cache=True, inline="always")
def clash(spans, i, j):
    """Whether moves ``i`` and ``j`` touch a common edge."""
    for x in range(2):
        ri = spans[i, 3 * x]
        if ri < 0:
            continue
        for y in range(2):
            if spans[j, 3 * y] == ri and spans[i, 3 * x + 1] <= spans[j, 3 * y + 2] \
                    and spans[j, 3 * y + 1] <= spans[i, 3 * x + 2]:
                return True
    return False


@numba.njit(cache=True)
def conflicts(spans, idx):
    """``(K, K)`` bool: which of the moves ``idx`` clash."""
    n = idx.shape[0]
    out = np.zeros((n, n), dtype=np.bool_)
    for a in range(n):
        for b in range(a):
            if clash(spans, idx[a], idx[b]):
                out[a, b] = True
                out[b, a] = True
    return out


@numba.njit(cache=True)
def pick_candidates(spans, gains, k, max_overlap):
    """Indices of at most ``k`` moves for one selection program: by gain (ties: index), each
    clashing with at most ``max_overlap`` moves picked before it (a sparse conflict graph keeps the
    penalties -- and so the quantized fields -- small)."""
    order = np.argsort(-gains, kind="mergesort")
    picked = np.empty(min(k, order.shape[0]), dtype=np.int64)
    n = 0
    for m in order:
        if n == picked.shape[0]:
            break
        hits = 0
        for t in range(n):
            if clash(spans, m, picked[t]):
                hits += 1
                if hits > max_overlap:
                    break
        if hits <= max_overlap:
            picked[n] = m
            n += 1
    return picked[:n].copy()


@numba.njit(cache=True)
def selection_qubo(gains, clashes, margin):
    """``(q, Q)`` of the selection QUBO (module docstring) over the moves of ``gains`` with the
    clash matrix ``clashes``; ``Q`` strictly upper triangular."""
    M = gains.shape[0]
    Q = np.zeros((M, M))
    for i in range(M):
        for j in range(i + 1, M):
            if clashes[i, j]:
                Q[i, j] = min(gains[i], gains[j]) + margin
    return -gains, Q


@numba.njit(cache=True)
def selection_ising(gains, clashes, margin):
    """The selection QUBO in Ising form: ``(h (M,), J (M, M))``."""
    q, Q = selection_qubo(gains, clashes, margin)
    h, J, _offset = ising_of_qubo(q, Q, 0.0)
    return h, J


@numba.njit(cache=True)
def read_gain(chosen, clashes, gains):
    """``(taken, total gain)`` of one read (``chosen`` bool per move), or ``(None, 0.0)`` when two
    chosen moves clash (an invalid read)."""
    idx = np.flatnonzero(chosen)
    total = 0.0
    for a in range(idx.shape[0]):
        m = idx[a]
        total += gains[m]
        for b in range(a):
            if clashes[m, idx[b]]:
                return None, 0.0
    return idx, total


@numba.njit(cache=True)
def score_reads(spins, clashes, gains):
    """Reads ``(programs, reads, M)`` of one selection round.  Returns ``(valid (programs,), selecting
    (programs,), program, read, gain)``: per program its valid reads and those among them that
    select a move, and the first valid read of largest total gain (program -1: none above 0)."""
    p_n, reads, _m = spins.shape
    valid = np.zeros(p_n, dtype=np.int64)
    selecting = np.zeros(p_n, dtype=np.int64)
    best_p, best_r, best = -1, -1, 0.0
    for p in range(p_n):
        for rd in range(reads):
            taken, total = read_gain(spins[p, rd] > 0, clashes, gains)
            if taken is None:
                continue
            valid[p] += 1
            if taken.shape[0] > 0:
                selecting[p] += 1
            if total > best + _EPS:
                best_p, best_r, best = p, rd, total
    return valid, selecting, best_p, best_r, best


def greedy_selection(clashes: np.ndarray) -> np.ndarray:
    """The host rule: moves in offered order (by gain), each that clashes with none taken."""
    taken: list[int] = []
    for i in range(clashes.shape[0]):
        if not any(clashes[i, j] for j in taken):
            taken.append(i)
    return np.array(taken, dtype=np.int64)
