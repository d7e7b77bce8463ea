"""The fleet search's local search in one compiled call: chip-selected move sets until no move improves.

Contract: :func:`local_search_loop` improves the routes ``nxt`` / ``prv`` (linked lists,
:mod:`.moves`) in place: each round lists the improving granular moves, offers at most
``capacity >> failures`` of them and applies the compatible set the chip selects
(:func:`planners.ising.moves.selection.select_round`) or, with ``chip=False``, the host's greedy set
(:func:`~planners.ising.moves.selection.greedy_selection`, no chip call).  A round whose reads select
nothing valid is re-issued with half the moves; ``max_retries + 1`` such rounds in a row end the
search (the chip gave up).  Returns the statistics and, per submission, the calls and the kernel's
seconds for the caller to settle on its machine session.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.ising.fleet.moves import apply_move, candidate_moves, walk
from planners.ising.moves.selection import ROUND_REFUSED, conflicts, greedy_selection, pick_candidates, select_round

__all__ = ["local_search_loop", "STAT_FIELDS", "LOCAL_OPTIMUM", "GAVE_UP", "REFUSED"]

#: The statistics array's fields, in order.
STAT_FIELDS = ("rounds", "offered", "contested_rounds", "moves_applied", "valid_reads", "reads", "local_optima",
               "chip_gave_up")
#: How a search ended: no improving move left; the chip selected nothing valid ``max_retries + 1`` times in
#: a row; a program the quantizer could not map (a non-finite coefficient), nothing annealed for it.
LOCAL_OPTIMUM, GAVE_UP, REFUSED = 0, 1, 2


@numba.njit(cache=True)
def local_search_loop(rng, d, nxt, prv, r, neigh, search, program, machine):
    """The local search (module docstring); ``search`` = ``(capacity, max_overlap, max_retries, chip)``,
    ``program`` = ``(rules, Lh, Lj, num_reads)``, ``machine`` an anneal record.  Returns ``(status,
    stats (8,) as STAT_FIELDS, calls (S,), emulation_s (S,))``."""
    capacity, max_overlap, max_retries, chip = search
    R = program[0].shape[0]
    reads = R * program[3]
    stats = np.zeros(8, dtype=np.int64)
    calls = np.zeros(16, dtype=np.int64)
    emu = np.zeros(16)
    subs = 0
    failures = 0
    while True:
        owner, pos, length = walk(nxt, r)
        moves, spans, gains = candidate_moves(d, nxt, prv, owner, pos, length, neigh, r)
        if gains.shape[0] == 0:
            stats[6] += 1
            return LOCAL_OPTIMUM, stats, calls[:subs], emu[:subs]
        k = max(1, capacity >> failures)
        if chip:
            st, keep, clashes, taken, valid, _selecting, best, seconds = select_round(
                rng, spans, gains, k, max_overlap, program, machine)
            if st == ROUND_REFUSED:
                return REFUSED, stats, calls[:subs], emu[:subs]
            if subs == calls.shape[0]:
                calls = np.concatenate((calls, np.zeros(subs, dtype=np.int64)))
                emu = np.concatenate((emu, np.zeros(subs)))
            calls[subs] = reads
            emu[subs] = seconds
            subs += 1
            stats[5] += reads
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
                return GAVE_UP, stats, calls[:subs], emu[:subs]
            continue
        failures = 0
        for i in keep[taken]:
            apply_move(nxt, prv, moves[i, 0], moves[i, 1], moves[i, 2])
        stats[3] += taken.shape[0]
