"""Compiled move-selection search of the chip tour: one start in one call.

Contract: :func:`select_moves_loop` runs one start of the chip tour's move selection (the one
implementation; ``tests/tour_reference.py`` is its oracle) -- candidate moves, then per round
:func:`planners.ising.moves.selection.select_round` (the pick, the selection QUBO mapped by every
rule of the portfolio, a chip seed drawn from the construction's ``numpy.random.Generator``, the
machine's anneal, the reads scored) and the applied moves -- and returns the statistics and, per submission, the calls and measured
emulation seconds (a monotonic clock around the kernel) for the caller to charge to the chip
as ``anneal_batch`` would.  A program the quantizer cannot map (a non-finite coefficient: gains
of distances too large to add) ends the start with :data:`REFUSED`, nothing annealed for it.
"""

from __future__ import annotations


import numba
import numpy as np

from planners.ising.moves.routes import linked, route_of
from planners.ising.moves.selection import ROUND_REFUSED, select_round
from planners.ising.tour.moves import apply_moves, candidate_moves

__all__ = ["select_moves_loop", "nearest_neighbour_kernel", "LOCAL_OPTIMUM", "STALLED", "NO_PROGRESS",
           "REFUSED"]

LOCAL_OPTIMUM = 0  # no improving move left (or max_rounds reached)
STALLED = 1  # the chip selected nothing valid max_retries + 1 times in a row, after some progress
NO_PROGRESS = 2  # ... before any move was applied: the start fails
REFUSED = 3  # a program the quantizer could not map (a non-finite coefficient): the start fails


@numba.njit(cache=True)
def select_moves_loop(rng, dist, route, max_segment, capacity, max_overlap, max_retries, max_rounds, program, machine):
    """One start of the move-selection search (module docstring); ``program`` = ``(rules, Lh, Lj,
    num_reads)``: the quantization rules' ids, the coefficient limits and the reads per program.

    Returns ``(route, status, stats (5,), clean (k,), wins (k,), calls (S,), emulation_s (S,))`` with
    stats = rounds, retries, moves applied, rounds with a valid read, programs with a valid read;
    ``clean`` / ``wins`` per rule: valid reads that select a move, best reads.
    """
    nxt, prv = linked(route)  # the route form of every move search (planners.ising.moves.routes)
    k = program[0].shape[0]  # the quantization rules
    stats = np.zeros(5, dtype=np.int64)
    clean_all = np.zeros(k, dtype=np.int64)
    wins = np.zeros(k, dtype=np.int64)
    calls = np.zeros(max_rounds, dtype=np.int64)
    emu = np.zeros(max_rounds)
    failures = 0
    applied = 0
    rounds = 0
    status = LOCAL_OPTIMUM
    while rounds < max_rounds:
        route = route_of(nxt)
        moves, spans, gains = candidate_moves(dist, route, max_segment)
        if gains.shape[0] == 0:
            break
        st, keep, _clashes, taken, _valid, clean, best, n_calls, seconds = select_round(
            rng, spans, gains, max(1, capacity >> failures), max_overlap, program, machine)
        if st == ROUND_REFUSED:
            stats[0] = rounds
            stats[2] = applied
            return route_of(nxt), REFUSED, stats, clean_all, wins, calls[:rounds], emu[:rounds]
        emu[rounds] = seconds
        calls[rounds] = n_calls
        rounds += 1
        for r in range(k):
            clean_all[r] += clean[r]
            stats[4] += clean[r] > 0
        if best < 0:
            failures += 1
            stats[1] += 1
            if failures > max_retries:
                status = STALLED if applied else NO_PROGRESS
                break
            continue
        wins[best] += 1
        stats[3] += 1
        failures = 0
        applied += taken.shape[0]
        apply_moves(nxt, prv, route, moves[keep], taken)
    stats[0] = rounds
    stats[2] = applied
    return route_of(nxt), status, stats, clean_all, wins, calls[:rounds], emu[:rounds]


@numba.njit(cache=True)
def nearest_neighbour_kernel(dist):
    """The nearest-neighbour route: from node 0 always to the nearest unvisited node (ties: the
    lowest index)."""
    n = dist.shape[0] - 1
    route = np.zeros(n + 1, dtype=np.int64)
    seen = np.zeros(n + 1, dtype=np.bool_)
    seen[0] = True
    for t in range(1, n + 1):
        last = route[t - 1]
        best = -1
        for v in range(1, n + 1):
            if not seen[v] and (best < 0 or dist[last, v] < dist[last, best]):
                best = v
        route[t] = best
        seen[best] = True
    return route
