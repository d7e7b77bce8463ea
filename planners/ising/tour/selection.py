"""The tour on the physical chip: move-selection local search (``TourConfig.backend="chip"``).

Contract: each start runs :func:`planners.ising.moves.search.move_search` on the route's 2-opt and or-opt
moves: the chip selects a non-overlapping set (a read selecting overlapping moves is dropped, never
repaired), so applied moves always give a valid route.  Start 0 is the nearest-neighbour route, later
starts random orders or double-bridge kicks (``chip_restart``; ``"auto"`` kicks above :data:`KICK_ABOVE`
targets); the cheapest route wins.  The starts run in one compiled call (:func:`search_starts`); kicks, drawn by
numpy from the best route so far, one call a start.  Design notes and measurements: docs/design/ising_tour.md.
"""

from __future__ import annotations

import math
from functools import cached_property
from typing import NamedTuple

import numba
import numpy as np

from ising_backend import add_counts
from planners.ising.moves.routes import linked, route_of
from planners.ising.moves.search import GAVE_UP, LOCAL_OPTIMUM, REFUSED, SearchLimits, move_search, new_stats, stats_dict
from planners.ising.moves.selection import REFUSED_MESSAGE, RoundProgram, program_record
from planners.ising.tour.cluster import TourFailure

__all__ = ["MoveSearch", "search_starts", "StartsOut", "double_bridge", "settle", "nearest_neighbour_kernel", "KICK_ABOVE", "ProgramRefused"]



class ProgramRefused(TourFailure):
    """A selection program the quantizer cannot map (a non-finite coefficient): the search ends."""


#: ``chip_restart="auto"``: random restarts up to this many targets, kicks of the best route beyond.
KICK_ABOVE = 16
_NO_LOG = (np.zeros(0, dtype=np.int64), np.zeros(0), 0)  # an empty submission log (grown, never written)
_NO_ROUTES = np.zeros((0, 0), dtype=np.int64)  # no given start routes


class StartsOut(NamedTuple):
    """:func:`search_starts`'s result."""

    status: int  # REFUSED when a start's program was refused (the starts end there), else LOCAL_OPTIMUM
    best: np.ndarray  # the cheapest route of the starts that did not fail (empty when all failed)
    cost: float  # its cost
    costs: np.ndarray  # each such start's cost, in order
    failed: int  # starts the chip gave up with no move applied
    gave_up: int  # starts that ended by the chip giving up, with or without moves applied
    calls: np.ndarray  # per submission: its chip calls (the first ``used``)
    emu: np.ndarray  # and emulation seconds
    used: int


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


@numba.njit(cache=True)
def search_starts(rng, dist, given, nearest, n_random, max_segment, limits, program, machine, stats, per_rule, log):
    """Starts of the chip tour in order, each :func:`~planners.ising.moves.search.move_search` on the route's
    2-opt / or-opt moves: the nearest-neighbour route when ``nearest``, then the rows of ``given``, then
    ``n_random`` random orders (``0`` then ``1 + rng.permutation(n)``).  A start the chip gives up without a move
    fails; a refused program ends the starts.  ``stats``, ``per_rule`` and ``log`` as ``move_search``'s, summed
    over the starts.  Returns a :class:`StartsOut`."""
    n = dist.shape[0] - 1
    total = int(nearest) + given.shape[0] + n_random
    costs = np.empty(total)
    nc, failed, gave_up = 0, 0, 0
    best, best_cost = np.zeros(0, dtype=np.int64), np.inf
    calls, emu, used = log
    st = stats[0]
    for s in range(total):
        if nearest and s == 0:
            route = nearest_neighbour_kernel(dist)
        elif s - int(nearest) < given.shape[0]:
            route = given[s - int(nearest)].copy()
        else:
            route = np.empty(n + 1, dtype=np.int64)
            route[0] = 0
            route[1:] = 1 + rng.permutation(n)
        nxt, prv = linked(route)
        before = st.moves_applied
        out = move_search(rng, dist, nxt, prv, 1, max_segment, None, limits, program, machine, stats, per_rule,
                          (calls, emu, used))
        calls, emu, used = out.calls, out.emu, out.used
        if out.status == GAVE_UP:
            gave_up += 1
        if out.status == REFUSED:
            return StartsOut(REFUSED, best, best_cost, costs[:nc], failed, gave_up, calls, emu, used)
        if out.status == GAVE_UP and st.moves_applied == before:
            failed += 1
            continue
        route = route_of(nxt)
        cost = 0.0
        for i in range(n):
            cost += dist[route[i], route[i + 1]]
        costs[nc] = cost
        nc += 1
        if cost < best_cost - 1e-9:
            best, best_cost = route, cost
    return StartsOut(LOCAL_OPTIMUM, best, best_cost, costs[:nc], failed, gave_up, calls, emu, used)


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
        quantizer cannot map ends the search (every later start would meet it too).  Without kicks every start
        runs in one compiled call (:func:`search_starts`); with kicks one call a start, each kick drawn from
        the best route so far."""
        n = dist.shape[0] - 1
        starts = 1 if n <= 3 else self.config.n_starts
        kicks = self.config.chip_restart == "kick" or (self.config.chip_restart == "auto" and n > KICK_ABOVE)
        dist = np.ascontiguousarray(dist, dtype=np.float64)
        best, best_cost = None, math.inf
        charges: list = []
        with self.chip.session(run.charged, decision="tour_moves") as link:  # one session for every start
            try:
                if not kicks or n < 4:
                    best, best_cost = self._run_starts(dist, _NO_ROUTES, True, starts - 1, run, link.args, charges,
                                                       best, best_cost)
                else:
                    for s in range(starts):
                        given = _NO_ROUTES if s == 0 or best is None else double_bridge(best, run.rng)[None]
                        best, best_cost = self._run_starts(dist, given, s == 0, int(s > 0 and best is None), run,
                                                           link.args, charges, best, best_cost)
            finally:  # what ran is charged once, in order, also when a start ends the search
                settle(link, charges)
        if best is None:
            raise TourFailure(self._no_progress)
        return [int(t) for t in best[1:]]

    def select(self, dist: np.ndarray, route: np.ndarray, run, link, charges: list) -> np.ndarray:
        """One start from ``route`` on the session ``link`` (float64 ``dist``): the route improved by chip-selected
        moves (:func:`search_starts` with one given route); its submissions are appended to ``charges`` for
        :func:`settle`.  A chip that never selects a valid improving set for a route that has improving moves
        fails the start (:class:`TourFailure`): the route would be the host's, not the chip's."""
        out = self._search(dist, np.asarray(route, dtype=np.int64)[None], False, 0, run, link.args, charges)
        if out.status == REFUSED:
            raise ProgramRefused(REFUSED_MESSAGE)
        if out.costs.shape[0] == 0:
            raise TourFailure(self._no_progress)
        return out.best

    def _run_starts(self, dist, given, nearest: bool, n_random: int, run, link_args, charges: list, best,
                    best_cost):
        """Starts of :func:`search_starts` (``charges`` as :meth:`select`'s); the cheapest route of ``best`` and
        theirs, with its cost."""
        out = self._search(dist, given, nearest, n_random, run, link_args, charges)
        run.stats["start_costs"].extend(out.costs.tolist())
        run.stats["failed_starts"] += out.failed
        if out.status == REFUSED:
            raise ProgramRefused(REFUSED_MESSAGE)
        if out.costs.shape[0] and out.cost < best_cost - 1e-9:
            return out.best, out.cost
        return best, best_cost

    def _search(self, dist, given, nearest: bool, n_random: int, run, link_args, charges: list) -> StartsOut:
        """One compiled call of :func:`search_starts`: its statistics counted in ``run``, its submissions appended to
        ``charges``; returns its :class:`StartsOut` (the callers raise on a refused program)."""
        k = len(self.config.chip_rules)
        stats = new_stats()
        clean, wins = np.zeros(k, dtype=np.int64), np.zeros(k, dtype=np.int64)
        out = search_starts(run.rng, dist, given, nearest, n_random, self.config.max_segment, self._limits,
                            self._move_args, link_args, stats, (clean, wins), _NO_LOG)
        charges.append((out.calls[:out.used], out.emu[:out.used]))
        self._count_start(run, stats_dict(stats), clean, wins, out.gave_up)
        return out

    @property
    def _no_progress(self) -> str:
        cfg = self.config
        return (f"the chip selected no valid improving move set in {cfg.max_retries + 1} "
                f"submissions of {len(cfg.chip_rules)} programs")

    def _count_start(self, run, st, clean, wins, gave_up: int) -> None:
        """The statistics of one call's starts: ``st`` (the search's, :func:`~planners.ising.moves.search.stats_dict`),
        ``clean`` (valid reads per rule), ``wins`` (best reads per rule), how many starts the chip gave up."""
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
        run.stats["unsolved"]["moves"] += gave_up
