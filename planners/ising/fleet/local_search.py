"""The fleet search in one compiled call: the one local search of the move engine, then the kicks.

Contract: :func:`iterated_search` runs :func:`planners.ising.moves.search.move_search` on the granular
neighbourhood (chip-selected move sets, or the host's greedy set with ``chip`` False), then ``kicks``
times ruins and recreates a copy of the routes (:func:`~.recreate.ruin_recreate`) and searches again,
keeping it within ``1 + slack`` of the best; the cheapest routes stay in ``best_nxt`` (also when a
machine's error ends the call).  Design notes: docs/design/ising_fleet.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from planners.ising.fleet.recreate import ruin_recreate
from planners.ising.moves.routes import route_cost
from planners.ising.moves.search import LOCAL_OPTIMUM, REFUSED, SearchLimits, move_search

__all__ = ["iterated_search", "FleetBest"]

_NO_LIMIT = 1 << 62  # the fleet's local search runs to a local optimum


class FleetBest(NamedTuple):
    """What :func:`iterated_search` updates in place as it goes."""

    nxt: np.ndarray  # the cheapest routes so far
    cost: np.ndarray  # (1,) their cost
    stats: np.ndarray  # the search's statistics record (planners.ising.moves.search.new_stats)
    per_rule: tuple  # (clean, wins): per quantization rule its valid reads and best reads


@numba.njit(cache=True)
def iterated_search(rng, d, nxt, prv, r, neigh, order, search, kick, program, machine, best):
    """The iterated local search (module docstring) from ``nxt`` / ``prv``; ``order[t]`` the nodes nearest
    target ``r + t`` (itself first), ``kick`` = ``(kicks, ruin, slack)``; ``best`` a :class:`FleetBest`;
    ``search`` the :class:`~planners.ising.moves.search.SearchLimits` (its ``max_rounds`` unused: each local
    search runs to a local optimum).  Returns ``(status, calls, emulation_s)``."""
    kicks, ruin, slack = kick
    best_nxt, best_cost = best.nxt, best.cost
    n = d.shape[0] - r
    calls, emu, subs = np.zeros(0, dtype=np.int64), np.zeros(0), 0
    limits = SearchLimits(search.capacity, search.max_overlap, search.max_retries, _NO_LIMIT, search.chip)
    status = LOCAL_OPTIMUM
    for it in range(kicks + 1):  # the local search from the start, then one per kick
        if it == 0:
            cand_nxt, cand_prv = nxt, prv
        else:
            cand_nxt, cand_prv = nxt.copy(), prv.copy()
            seed_target = r + rng.integers(0, n)
            q = min(rng.integers(2, ruin + 1), n)
            ruin_recreate(d, cand_nxt, cand_prv, r, seed_target, order[seed_target - r, 1:], q, rng.permutation(q))
        out = move_search(rng, d, cand_nxt, cand_prv, r, None, neigh, limits, program, machine, best.stats,
                          best.per_rule, (calls, emu, subs))
        status, calls, emu, subs = out.status, out.calls, out.emu, out.used
        if status == REFUSED:
            break
        new = route_cost(d, cand_nxt, r)
        if it == 0 or new <= best_cost[0] * (1.0 + slack) + 1e-9:  # record-to-record travel around the best
            nxt, prv = cand_nxt, cand_prv
            best.stats[0].kicks_accepted += it > 0
            if new < best_cost[0] - 1e-9:
                best_nxt[:] = cand_nxt
                best_cost[0] = new
    return status, calls[:subs], emu[:subs]
