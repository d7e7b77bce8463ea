"""The tour on the physical chip: move-selection local search (``TourConfig.backend="chip"``).

Contract: each start runs :func:`planners.ising.moves.search.move_search` on the route's 2-opt and or-opt
moves: the chip selects a non-overlapping set (a read selecting overlapping moves is dropped, never
repaired), so applied moves always give a valid route.  Start 0 is the nearest-neighbour route, later
starts random orders or double-bridge kicks (``chip_restart``; ``"auto"`` kicks above :data:`KICK_ABOVE`
targets); the cheapest route wins.  Design notes and measurements: docs/design/ising_tour.md.
"""

from __future__ import annotations

import math
from functools import cached_property

import numba
import numpy as np

from ising_backend import add_counts
from planners.ising.moves.routes import linked, route_of
from planners.ising.moves.search import GAVE_UP, REFUSED, SearchLimits, move_search, new_stats, stats_dict
from planners.ising.moves.selection import REFUSED_MESSAGE, RoundProgram, program_record
from planners.ising.tour.cluster import TourFailure

__all__ = ["MoveSearch", "double_bridge", "settle", "nearest_neighbour_kernel", "KICK_ABOVE", "ProgramRefused"]



class ProgramRefused(TourFailure):
    """A selection program the quantizer cannot map (a non-finite coefficient): the search ends."""


#: ``chip_restart="auto"``: random restarts up to this many targets, kicks of the best route beyond.
KICK_ABOVE = 16
_NO_LOG = (np.zeros(0, dtype=np.int64), np.zeros(0), 0)  # an empty submission log (grown, never written)


def settle(link, charges: list) -> None:
    """Charge the starts' submissions ``charges`` (``(calls, emulation_s)`` per start, in order) on ``link``."""
    if charges:
        link.settle(np.concatenate([c for c, _ in charges]), np.concatenate([e for _, e in charges]))


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


def double_bridge(route: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """``route`` with its targets cut at three random points and the middle pieces swapped
    (``A B C D -> A C B D``; node 0 stays first): the classic kick of iterated local search."""
    n = len(route) - 1
    i, j, k = np.sort(rng.choice(np.arange(1, n), size=3, replace=False)) if n > 3 else (1, 2, 3)
    return np.concatenate([route[:i], route[j:k], route[i:j], route[k:]]).astype(np.int64)


class MoveSearch:
    """:class:`~planners.ising.tour.IsingTour`'s chip backend, a component: ``MoveSearch(config, chip)``."""

    def __init__(self, config, chip):
        self.config = config
        self.chip = chip
        self.spec = chip.spec

    @cached_property
    def _move_args(self) -> RoundProgram:
        """The compiled loop's ``program`` record (:func:`~planners.ising.moves.selection.program_record`)."""
        return program_record(self.config.chip_rules, self.spec, self.config.num_reads)

    @cached_property
    def _limits(self) -> SearchLimits:
        """How far the search goes."""
        cfg = self.config
        return SearchLimits(capacity=self._capacity, max_overlap=cfg.max_overlap, max_retries=cfg.max_retries,
                            max_rounds=cfg.max_rounds, chip=True)

    @property
    def _capacity(self) -> int:
        """Most moves per program: the spins a program may use (around stuck spins), at most ``max_moves``."""
        return min(int(self.chip.usable_spins), self.config.max_moves)

    def starts(self, dist: np.ndarray, run) -> list[int]:
        """The cheapest route over ``n_starts`` move-selection searches (module docstring); a program the
        quantizer cannot map ends the search (every later start would meet it too)."""
        n = dist.shape[0] - 1
        starts = 1 if n <= 3 else self.config.n_starts
        kicks = self.config.chip_restart == "kick" or (self.config.chip_restart == "auto" and n > KICK_ABOVE)
        dist = np.ascontiguousarray(dist, dtype=np.float64)
        best, best_cost, failure = None, math.inf, None
        charges: list = []
        with self.chip.session(run.charged, decision="tour_moves") as link:  # one session for every start
            try:
                for s in range(starts):
                    if s == 0:
                        route = nearest_neighbour_kernel(dist)
                    elif kicks and best is not None and n >= 4:
                        route = double_bridge(best, run.rng)
                    else:
                        route = np.concatenate([[0], 1 + run.rng.permutation(n)]).astype(np.int64)
                    try:
                        route = self.select(dist, route, run, link, charges)
                    except ProgramRefused:
                        raise
                    except TourFailure as exc:  # this start gave up; other starts may still succeed
                        failure = exc
                        run.stats["failed_starts"] += 1
                        continue
                    cost = float(dist[route[:-1], route[1:]].sum())
                    run.stats["start_costs"].append(cost)
                    if cost < best_cost - 1e-9:
                        best, best_cost = route, cost
            finally:  # what ran is charged once, in order, also when a start ends the search
                settle(link, charges)
        if best is None:
            raise failure
        return [int(t) for t in best[1:]]

    def select(self, dist: np.ndarray, route: np.ndarray, run, link, charges: list) -> np.ndarray:
        """One start on the session ``link``: ``route`` (float64 ``dist``) improved by chip-selected moves
        until no move improves it (or the chip selects nothing valid ``max_retries + 1`` times in a row), in
        one compiled call (:func:`planners.ising.moves.search.move_search` on the route's 2-opt / or-opt
        neighbourhood); its submissions' calls and emulation seconds are appended to ``charges`` for
        :func:`settle`.  A chip that never selects a valid improving set for a route that has improving moves
        fails the start (:class:`TourFailure`): the route would be the host's, not the chip's."""
        k = len(self.config.chip_rules)
        stats = new_stats()
        clean, wins = np.zeros(k, dtype=np.int64), np.zeros(k, dtype=np.int64)
        nxt, prv = linked(route)
        out = move_search(run.rng, dist, nxt, prv, 1, self.config.max_segment, None, self._limits, self._move_args,
                          link.args, stats, (clean, wins), _NO_LOG)
        charges.append((out.calls[:out.used], out.emu[:out.used]))
        st = stats_dict(stats)
        no_progress = out.status == GAVE_UP and not st["moves_applied"]
        self._count_start(run, st, clean, wins, out.status == GAVE_UP)
        if out.status == REFUSED:
            raise ProgramRefused(REFUSED_MESSAGE)
        if no_progress:
            raise TourFailure(self._no_progress)
        return route_of(nxt)

    @property
    def _no_progress(self) -> str:
        cfg = self.config
        return (f"the chip selected no valid improving move set in {cfg.max_retries + 1} "
                f"submissions of {len(cfg.chip_rules)} programs")

    def _count_start(self, run, st, clean, wins, gave_up: bool) -> None:
        """The statistics of one start: ``st`` (the search's, :func:`~planners.ising.moves.search.stats_dict`),
        ``clean`` (valid reads per rule), ``wins`` (best reads per rule), whether the chip gave up."""
        cfg = self.config
        rounds, retries, applied = st["rounds"], st["retries"], st["moves_applied"]
        valid_rounds, valid_programs = st["valid_rounds"], st["valid_programs"]
        m = run.stats["mapping"]["tour"]  # each round sends one program per rule
        for rule, valid, won in zip(cfg.chip_rules, clean.tolist(), wins.tolist()):
            add_counts(m[rule], programs=rounds, reads=rounds * cfg.num_reads, valid=valid, wins=won)
        add_counts(run.stats, valid_programs=valid_programs, subproblems=rounds, valid_subproblems=valid_rounds)
        run.stats["retries"] += retries
        run.stats["moves_applied"] += applied
        run.stats["move_rounds"] += rounds
        if gave_up:
            run.stats["unsolved"]["moves"] += 1
