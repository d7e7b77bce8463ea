"""The one local search of the tour and the fleet search (compiled): offer, select, apply.

Contract: :func:`move_search` improves the routes ``nxt`` / ``prv`` in place on one neighbourhood (the
tour's :func:`.route_moves.route_moves` or the fleet's :func:`.granular.granular_moves`): per round it
applies the compatible set of offered moves the chip selects (or the host's greedy set with ``chip``
False), halving the offer after a round without a valid read, and ends at :data:`LOCAL_OPTIMUM`,
:data:`GAVE_UP` or :data:`REFUSED`.  Design notes (rounds, retries, compiling): docs/design/ising_fleet.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from planners.ising.moves.granular import granular_moves
from planners.ising.moves.kinds import apply_move
from planners.ising.moves.route_moves import apply_route_moves, route_moves
from planners.ising.moves.routes import route_of, walk
from planners.ising.moves.selection import ROUND_REFUSED, conflicts, greedy_selection, pick_candidates, select_round

__all__ = ["move_search", "new_stats", "stats_dict", "SearchLimits", "SearchOut", "STAT_FIELDS", "SEARCH_STATS",
           "LOCAL_OPTIMUM", "GAVE_UP", "REFUSED", "FLEET_FIELDS"]

#: The search's statistics (``kicks_accepted``: the fleet's kicks, counted by its caller).
STAT_FIELDS = ("rounds", "offered", "contested_rounds", "moves_applied", "valid_reads", "reads", "local_optima",
               "chip_gave_up", "kicks_accepted", "retries", "valid_rounds", "valid_programs")
#: The fields the fleet search reports (the first nine).
FLEET_FIELDS = STAT_FIELDS[:9]
#: The statistics record: a one-row structured array, counted by field name in the compiled search.
SEARCH_STATS = np.dtype([(name, np.int64) for name in STAT_FIELDS])


def new_stats() -> np.ndarray:
    """A zeroed statistics record (:data:`SEARCH_STATS`, one row)."""
    return np.zeros(1, dtype=SEARCH_STATS)


def stats_dict(stats: np.ndarray, fields=STAT_FIELDS) -> dict:
    """``fields`` of the statistics record ``stats`` as Python ints."""
    return {name: int(stats[0][name]) for name in fields}


class SearchLimits(NamedTuple):
    """How far :func:`move_search` goes."""

    capacity: int  # the most moves offered a round
    max_overlap: int  # how many offered moves may touch one node
    max_retries: int  # rounds in a row without a valid read before the chip gives up
    max_rounds: int
    chip: bool  # the chip selects (False: the host's greedy set)


class SearchOut(NamedTuple):
    """:func:`move_search`'s result: how it ended and its submission log."""

    status: int  # LOCAL_OPTIMUM, GAVE_UP or REFUSED
    calls: np.ndarray  # per submission: its chip calls (the first ``used``)
    emu: np.ndarray  # and emulation seconds
    used: int
#: How a search ended: no improving move left (or ``max_rounds`` rounds); the chip selected nothing valid
#: ``max_retries + 1`` times in a row; a program the quantizer could not map.
LOCAL_OPTIMUM, GAVE_UP, REFUSED = 0, 1, 2


@numba.njit(cache=True, inline="always")  # the fleet calls it from its kick loop: no link level of its own
def move_search(rng, d, nxt, prv, r, max_segment, neigh, search, program, machine, stats, per_rule, log):
    """The search (module docstring); ``search`` a :class:`SearchLimits`, ``program`` the rounds'
    :class:`~.selection.RoundProgram`, ``machine`` an anneal record, ``stats`` a :func:`new_stats` record
    (counted in place); ``per_rule = (clean, wins)``: per quantization rule, valid reads that select a move and
    best reads (added in place); ``log = (calls, emulation_s, used)`` (grown when full).  Returns a
    :class:`SearchOut`."""
    max_overlap, chip = search.max_overlap, search.chip
    clean_all, wins = per_rule
    calls, emu, subs = log
    st = stats[0]
    failures = 0
    rounds = 0
    while rounds < search.max_rounds:
        if max_segment is not None:  # the tour's neighbourhood (pruned for the fleet)
            route = route_of(nxt)
            moves, spans, gains = route_moves(d, route, max_segment)
        if neigh is not None:  # the fleet's (pruned for the tour)
            owner, pos, length = walk(nxt, r)
            moves, spans, gains = granular_moves(d, nxt, prv, owner, pos, length, neigh, r)
        if gains.shape[0] == 0:
            st.local_optima += 1
            return SearchOut(LOCAL_OPTIMUM, calls, emu, subs)
        k = max(1, search.capacity >> failures)
        if chip:
            rnd = select_round(rng, spans, gains, k, max_overlap, program, machine)
            if rnd.status == ROUND_REFUSED:
                return SearchOut(REFUSED, calls, emu, subs)
            keep, clashes, taken, best = rnd.keep, rnd.clashes, rnd.taken, rnd.best
            if subs == calls.shape[0]:
                calls = np.concatenate((calls, np.zeros(max(subs, 16), dtype=np.int64)))
                emu = np.concatenate((emu, np.zeros(max(subs, 16))))
            calls[subs] = rnd.calls
            emu[subs] = rnd.emu
            subs += 1
            st.reads += rnd.calls  # one read of one program is one chip call
            st.valid_reads += rnd.valid.sum()
            for q in range(rnd.selecting.shape[0]):
                clean_all[q] += rnd.selecting[q]
                st.valid_programs += rnd.selecting[q] > 0
        else:  # the ablation: the host decides (offered moves come by gain)
            keep = pick_candidates(spans, gains, k, max_overlap)
            clashes = conflicts(spans, keep)
            taken = greedy_selection(clashes)
            best = 0
        rounds += 1
        st.rounds += 1
        st.offered += keep.shape[0]
        st.contested_rounds += clashes.any()  # a real choice: not every move fits
        if best < 0:
            failures += 1
            st.retries += 1
            if failures > search.max_retries:
                st.chip_gave_up += 1
                return SearchOut(GAVE_UP, calls, emu, subs)
            continue
        if chip:
            wins[best] += 1
        st.valid_rounds += 1
        failures = 0
        st.moves_applied += taken.shape[0]
        if max_segment is not None:
            apply_route_moves(nxt, prv, route, moves[keep], taken)
        if neigh is not None:
            for i in keep[taken]:
                apply_move(nxt, prv, moves[i, 0], moves[i, 1], moves[i, 2], moves[i, 3])
    return SearchOut(LOCAL_OPTIMUM, calls, emu, subs)
