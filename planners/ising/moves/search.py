"""The one local search of the tour and the fleet search (compiled): offer, select, apply.

Contract: :func:`move_search` improves the routes ``nxt`` / ``prv`` in place on one neighbourhood (the
tour's :func:`.route_moves.route_moves` or the fleet's :func:`.granular.granular_moves`): per round it
applies the compatible set of offered moves the chip selects (or the host's greedy set with ``chip``
False), halving the offer after a round without a valid read, and ends at :data:`LOCAL_OPTIMUM`,
:data:`GAVE_UP` or :data:`REFUSED`.  Design notes (rounds, retries, compiling): docs/design/ising_fleet.md.
"""

from __future__ import annotations

import numba
import numpy as np

from planners.ising.moves.granular import granular_moves
from planners.ising.moves.kinds import apply_move
from planners.ising.moves.route_moves import apply_route_moves, route_moves
from planners.ising.moves.routes import route_of, walk
from planners.ising.moves.selection import ROUND_REFUSED, conflicts, greedy_selection, pick_candidates, select_round

__all__ = ["move_search", "STAT_FIELDS", "LOCAL_OPTIMUM", "GAVE_UP", "REFUSED", "FLEET_FIELDS"]

#: The statistics array's fields, in order (``kicks_accepted``: the fleet's kicks, counted by its caller).
STAT_FIELDS = ("rounds", "offered", "contested_rounds", "moves_applied", "valid_reads", "reads", "local_optima",
               "chip_gave_up", "kicks_accepted", "retries", "valid_rounds", "valid_programs")
#: The fields the fleet search reports (the first nine).
FLEET_FIELDS = STAT_FIELDS[:9]
_ROUNDS, _OFFERED, _CONTESTED, _APPLIED, _VALID_READS, _READS, _OPTIMA, _GAVE_UP = range(8)
_RETRIES, _VALID_ROUNDS, _VALID_PROGRAMS = 9, 10, 11
#: How a search ended: no improving move left (or ``max_rounds`` rounds); the chip selected nothing valid
#: ``max_retries + 1`` times in a row; a program the quantizer could not map.
LOCAL_OPTIMUM, GAVE_UP, REFUSED = 0, 1, 2


@numba.njit(cache=True, inline="always")  # the fleet calls it from its kick loop: no link level of its own
def move_search(rng, d, nxt, prv, r, max_segment, neigh, search, program, machine, stats, per_rule, log):
    """The search (module docstring); ``search = (capacity, max_overlap, max_retries, max_rounds, chip)``,
    ``program = (rules, Lh, Lj, num_reads)``, ``machine`` an anneal record; ``per_rule = (clean, wins)``:
    per quantization rule, valid reads that select a move and best reads (added in place); ``log = (calls,
    emulation_s, used)`` (grown when full).  Returns ``(status, calls, emulation_s, used)``."""
    capacity, max_overlap, max_retries, max_rounds, chip = search
    clean_all, wins = per_rule
    calls, emu, subs = log
    failures = 0
    rounds = 0
    while rounds < max_rounds:
        if max_segment is not None:  # the tour's neighbourhood (pruned for the fleet)
            route = route_of(nxt)
            moves, spans, gains = route_moves(d, route, max_segment)
        if neigh is not None:  # the fleet's (pruned for the tour)
            owner, pos, length = walk(nxt, r)
            moves, spans, gains = granular_moves(d, nxt, prv, owner, pos, length, neigh, r)
        if gains.shape[0] == 0:
            stats[_OPTIMA] += 1
            return LOCAL_OPTIMUM, calls, emu, subs
        k = max(1, capacity >> failures)
        if chip:
            st, keep, clashes, taken, valid, clean, best, n_calls, seconds = select_round(
                rng, spans, gains, k, max_overlap, program, machine)
            if st == ROUND_REFUSED:
                return REFUSED, calls, emu, subs
            if subs == calls.shape[0]:
                calls = np.concatenate((calls, np.zeros(max(subs, 16), dtype=np.int64)))
                emu = np.concatenate((emu, np.zeros(max(subs, 16))))
            calls[subs] = n_calls
            emu[subs] = seconds
            subs += 1
            stats[_READS] += n_calls  # one read of one program is one chip call
            stats[_VALID_READS] += valid.sum()
            for q in range(clean.shape[0]):
                clean_all[q] += clean[q]
                stats[_VALID_PROGRAMS] += clean[q] > 0
        else:  # the ablation: the host decides (offered moves come by gain)
            keep = pick_candidates(spans, gains, k, max_overlap)
            clashes = conflicts(spans, keep)
            taken = greedy_selection(clashes)
            best = 0
        rounds += 1
        stats[_ROUNDS] += 1
        stats[_OFFERED] += keep.shape[0]
        stats[_CONTESTED] += clashes.any()  # a real choice: not every move fits
        if best < 0:
            failures += 1
            stats[_RETRIES] += 1
            if failures > max_retries:
                stats[_GAVE_UP] += 1
                return GAVE_UP, calls, emu, subs
            continue
        if chip:
            wins[best] += 1
        stats[_VALID_ROUNDS] += 1
        failures = 0
        stats[_APPLIED] += taken.shape[0]
        if max_segment is not None:
            apply_route_moves(nxt, prv, route, moves[keep], taken)
        if neigh is not None:
            for i in keep[taken]:
                apply_move(nxt, prv, moves[i, 0], moves[i, 1], moves[i, 2], moves[i, 3])
    return LOCAL_OPTIMUM, calls, emu, subs
