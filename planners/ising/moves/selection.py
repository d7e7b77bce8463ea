"""The chip's move selection, shared by the tour and the fleet search (compiled).

Contract: :func:`select_round` is one round of either search: offer candidate moves, build the QUBO
``-sum g_m x_m + sum (min(g_m, g_m') + margin) x_m x_m'`` over clashing pairs (moves touching a common
edge; its ground states are the compatible sets of largest gain), map it by every quantization rule,
one submission, score the reads (a read selecting two clashing moves is invalid).
:func:`greedy_selection` is the host rule in the chip's place.  Design notes: docs/design/ising_fleet.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ising_backend import QUANTIZE_RULE_IDS, quantize_rules, submit_packs
from ising_backend.mapping.numeric import ising_of_qubo

__all__ = ["SPAN_FIELDS", "clash", "conflicts", "pick_candidates", "selection_qubo",
           "read_gain", "score_reads", "greedy_selection", "select_round", "program_record", "RoundProgram", "RoundOut",
           "Scored", "ROUND_OK",
           "ROUND_REFUSED", "REFUSED_MESSAGE"]

#: Columns of a spans row.
SPAN_FIELDS = ("route", "lo", "hi", "route2", "lo2", "hi2")
#: :func:`select_round`'s status: the round ran; a program the quantizer could not map (a non-finite
#: coefficient: gains of distances too large to add), nothing annealed.
ROUND_OK, ROUND_REFUSED = 0, 1
#: What a search that met :data:`ROUND_REFUSED` reports.
REFUSED_MESSAGE = ("the chip refused a move-selection program: a coefficient is not finite (distances too large "
                   "to add)")
_EPS = 1e-9


class RoundProgram(NamedTuple):
    """How a round's selection QUBO goes to the chip (:func:`program_record`)."""

    rules: np.ndarray  # the quantization rules' ids, one program each
    Lh: float  # the chip's coefficient limits
    Lj: float
    num_reads: int


class Scored(NamedTuple):
    """:func:`score_reads`' result."""

    valid: np.ndarray  # (programs,) valid reads
    selecting: np.ndarray  # (programs,) those among them that select a move
    best_rule: int  # the first valid read of largest total gain: its program (-1: none above 0)
    best_read: int
    gain: float


class RoundOut(NamedTuple):
    """:func:`select_round`'s result."""

    status: int  # ROUND_OK or ROUND_REFUSED
    keep: np.ndarray  # the offered moves (indices into gains)
    clashes: np.ndarray  # their clash matrix
    taken: np.ndarray  # the best read's moves (indices into keep; empty when no valid read selects one)
    valid: np.ndarray  # per rule: valid reads
    selecting: np.ndarray  # and those selecting a move
    best: int  # the best read's rule (-1: none)
    calls: int  # the submission's chip calls
    emu: float  # and the kernel's seconds


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
    """Reads ``(programs, reads, M)`` of one selection round scored: a :class:`Scored`."""
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
    return Scored(valid, selecting, best_p, best_r, best)


@numba.njit(cache=True)
def greedy_selection(clashes):
    """The host rule: moves in offered order (by gain), each that clashes with none taken."""
    n = clashes.shape[0]
    taken = np.empty(n, dtype=np.int64)
    t = 0
    for i in range(n):
        free = True
        for j in range(t):
            if clashes[i, taken[j]]:
                free = False
                break
        if free:
            taken[t] = i
            t += 1
    return taken[:t].copy()


@numba.njit(cache=True, inline="always")  # inlined into both searches' loops: no link level of its own
def select_round(rng, spans, gains, k, max_overlap, program, machine):
    """One selection round: at most ``k`` moves offered (:func:`pick_candidates`), their QUBO mapped by
    every rule of the :class:`RoundProgram` ``program`` (``keep_sign``, percentile 95), one submission on
    ``machine`` (an :func:`ising_backend.anneal_submit` record) with a seed drawn from ``rng``, the reads
    scored.  Returns a :class:`RoundOut`."""
    rules = program.rules
    R = rules.shape[0]
    keep = pick_candidates(spans, gains, k, max_overlap)
    clashes = conflicts(spans, keep)
    offered = gains[keep]
    none = np.zeros(0, dtype=np.int64)
    q, Q = selection_qubo(offered, clashes, 1.0)
    h, J, _offset = ising_of_qubo(q, Q, 0.0)
    # one program per rule (as pack_qubo_stack packs them at capacity M: each its own pack, in rule order)
    st, hq, Jq = quantize_rules(h, J, rules, program.Lh, program.Lj, True, 95.0)
    for r in range(R):
        if st[r] != 0:
            return RoundOut(ROUND_REFUSED, keep, clashes, none, np.zeros(R, np.int64), np.zeros(R, np.int64), -1, 0, 0.0)
    seed = rng.integers(0, 9223372036854775807)
    spins, calls, emu = submit_packs(hq, Jq, program.num_reads, np.uint64(seed), machine)
    scored = score_reads(spins, clashes, offered)
    best = scored.best_rule
    taken = np.flatnonzero(spins[best, scored.best_read] > 0) if best >= 0 else none
    return RoundOut(ROUND_OK, keep, clashes, taken, scored.valid, scored.selecting, best, calls, emu)


def program_record(chip_rules, spec, num_reads: int) -> RoundProgram:
    """:func:`select_round`'s ``program`` record (the machine's record comes from each call's session)."""
    rules = np.array([QUANTIZE_RULE_IDS[r] for r in chip_rules], dtype=np.int64)
    Lh, Lj = (float(v) for v in spec.coefficient_limits)
    return RoundProgram(rules=rules, Lh=Lh, Lj=Lj, num_reads=int(num_reads))
