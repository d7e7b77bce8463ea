"""The fleet search in one compiled call: local search by chip-selected move sets, then the kicks.

Contract: :func:`local_search_loop` improves the routes ``nxt`` / ``prv`` (linked lists,
:mod:`planners.ising.moves.routes`) in place: each round lists the improving granular moves, offers at most
``capacity >> failures`` of them and applies the compatible set the chip selects
(:func:`planners.ising.moves.selection.select_round`) or, with ``chip=False``, the host's greedy set
(:func:`~planners.ising.moves.selection.greedy_selection`, no chip call).  A round whose reads select
nothing valid is re-issued with half the moves; ``max_retries + 1`` such rounds in a row end the
search (the chip gave up).  :func:`iterated_search` runs it, then ``kicks`` times ruins and recreates a
copy of the current routes (:func:`~.recreate.ruin_recreate`: 2..``ruin`` targets around a random one)
and searches again, keeping the result when it costs at most the best times ``1 + slack``
(record-to-record travel); the cheapest routes so far are kept in place in ``best_nxt`` (also when a
machine's error ends the call).  Both count the statistics in place and log, per submission, the calls
and the kernel's seconds for the caller to settle on its machine session.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.ising.fleet.moves import candidate_moves
from planners.ising.moves.kinds import apply_move
from planners.ising.moves.routes import route_cost, walk
from planners.ising.fleet.recreate import ruin_recreate
from planners.ising.moves.selection import ROUND_REFUSED, conflicts, greedy_selection, pick_candidates, select_round

__all__ = ["local_search_loop", "iterated_search", "STAT_FIELDS", "LOCAL_OPTIMUM", "GAVE_UP", "REFUSED"]

#: The statistics array's fields, in order (``kicks_accepted``: :func:`iterated_search` only).
STAT_FIELDS = ("rounds", "offered", "contested_rounds", "moves_applied", "valid_reads", "reads", "local_optima",
               "chip_gave_up", "kicks_accepted")
#: How a search ended: no improving move left; the chip selected nothing valid ``max_retries + 1`` times in
#: a row; a program the quantizer could not map (a non-finite coefficient), nothing annealed for it.
LOCAL_OPTIMUM, GAVE_UP, REFUSED = 0, 1, 2


@numba.njit(cache=True, inline="always")  # one call site in iterated_search: no link level of its own
def local_search_loop(rng, d, nxt, prv, r, neigh, search, program, machine, stats, log):
    """The local search (module docstring); ``search`` = ``(capacity, max_overlap, max_retries, chip)``,
    ``program`` = ``(rules, Lh, Lj, num_reads)``, ``machine`` an anneal record; ``stats`` (as
    :data:`STAT_FIELDS`) counted in place, each submission's calls and kernel seconds appended to ``log``
    = ``(calls, emulation_s, used)`` (grown when full).  Returns ``(status, calls, emulation_s, used)``."""
    capacity, max_overlap, max_retries, chip = search
    calls, emu, subs = log
    failures = 0
    while True:
        owner, pos, length = walk(nxt, r)
        moves, spans, gains = candidate_moves(d, nxt, prv, owner, pos, length, neigh, r)
        if gains.shape[0] == 0:
            stats[6] += 1
            return LOCAL_OPTIMUM, calls, emu, subs
        k = max(1, capacity >> failures)
        if chip:
            st, keep, clashes, taken, valid, _selecting, best, n_calls, seconds = select_round(
                rng, spans, gains, k, max_overlap, program, machine)
            if st == ROUND_REFUSED:
                return REFUSED, calls, emu, subs
            if subs == calls.shape[0]:
                calls = np.concatenate((calls, np.zeros(max(subs, 16), dtype=np.int64)))
                emu = np.concatenate((emu, np.zeros(max(subs, 16))))
            calls[subs] = n_calls
            emu[subs] = seconds
            subs += 1
            stats[5] += n_calls  # one read of one program is one chip call
            stats[4] += valid.sum()
        else:  # the ablation: the host decides (offered moves come by gain)
            keep = pick_candidates(spans, gains, k, max_overlap)
            clashes = conflicts(spans, keep)
            taken = greedy_selection(clashes)
            best = 0
        stats[0] += 1
        stats[1] += keep.shape[0]
        stats[2] += clashes.any()  # a real choice: not every move fits
        if best < 0:
            failures += 1
            if failures > max_retries:
                stats[7] += 1
                return GAVE_UP, calls, emu, subs
            continue
        failures = 0
        for i in keep[taken]:
            apply_move(nxt, prv, moves[i, 0], moves[i, 1], moves[i, 2], moves[i, 3])
        stats[3] += taken.shape[0]


@numba.njit(cache=True)
def iterated_search(rng, d, nxt, prv, r, neigh, order, search, kick, program, machine, best):
    """The iterated local search (module docstring) from ``nxt`` / ``prv``; ``order[t]`` the nodes nearest
    target ``r + t`` (itself first), ``kick`` = ``(kicks, ruin, slack)``; ``best`` = ``(best_nxt, best_cost
    (1,), stats)``, updated in place as the search goes: the cheapest routes so far and the statistics as
    :data:`STAT_FIELDS`.  Returns ``(status, calls, emulation_s)``."""
    kicks, ruin, slack = kick
    best_nxt, best_cost, stats = best
    n = d.shape[0] - r
    calls, emu, subs = np.zeros(0, dtype=np.int64), np.zeros(0), 0
    status = LOCAL_OPTIMUM
    for it in range(kicks + 1):  # the local search from the start, then one per kick
        if it == 0:
            cand_nxt, cand_prv = nxt, prv
        else:
            cand_nxt, cand_prv = nxt.copy(), prv.copy()
            seed_target = r + rng.integers(0, n)
            q = min(rng.integers(2, ruin + 1), n)
            ruin_recreate(d, cand_nxt, cand_prv, r, seed_target, order[seed_target - r, 1:], q, rng.permutation(q))
        status, calls, emu, subs = local_search_loop(rng, d, cand_nxt, cand_prv, r, neigh, search, program, machine,
                                                     stats, (calls, emu, subs))
        if status == REFUSED:
            break
        new = route_cost(d, cand_nxt, r)
        if it == 0 or new <= best_cost[0] * (1.0 + slack) + 1e-9:  # record-to-record travel around the best
            nxt, prv = cand_nxt, cand_prv
            stats[8] += it > 0
            if new < best_cost[0] - 1e-9:
                best_nxt[:] = cand_nxt
                best_cost[0] = new
    return status, calls[:subs], emu[:subs]
