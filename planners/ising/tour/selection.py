"""The tour on the physical chip: move-selection local search (``TourConfig.backend="chip"``).

Not the paper's one-hot model (its quantized ground state is invalid in the chip's ``[-7, 7]``): the
chip chooses among improving 2-opt and or-opt moves (:mod:`.moves`), coefficients are of the size of
the gains, a read is valid when the moves it selects do not overlap, and applied they always give a
valid route.  Per round the host offers the chip up to ``max_moves`` improving moves (by gain, each
overlapping at most ``max_overlap`` better ones; at most the chip's spins; halved on every re-issue of
the round); the selection QUBO goes through the mapping portfolio (``chip_rules``, one program per
rule, one ``anneal_batch``) and the valid read of largest total gain is applied.  A read selecting
overlapping moves is invalid and dropped, never repaired.  A round whose reads select nothing valid
is re-issued up to ``max_retries`` times; a route without an improving move ends the start.  Start 0
is the nearest-neighbour route; later starts are random orders (``chip_restart="random"``) or
double-bridge kicks of the best route so far (``"kick"``); ``"auto"`` kicks above :data:`KICK_ABOVE`
targets.  The cheapest route wins.  Design notes and measurements: docs/design/ising_tour.md.
"""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from planners.ising.moves.selection import REFUSED_MESSAGE, program_record
from planners.ising.tour.cluster import TourFailure
from planners.ising.tour.move_engine import (
    NO_PROGRESS, REFUSED, STALLED, nearest_neighbour_kernel, select_moves_loop,
)

__all__ = ["MoveSearch", "double_bridge", "settle", "KICK_ABOVE", "ProgramRefused"]



class ProgramRefused(TourFailure):
    """A selection program the quantizer cannot map (a non-finite coefficient): the search ends."""


#: ``chip_restart="auto"``: random restarts up to this many targets, kicks of the best route beyond.
KICK_ABOVE = 16


def settle(link, charges: list) -> None:
    """Charge the starts' submissions ``charges`` (``(calls, emulation_s)`` per start, in order) on ``link``."""
    if charges:
        link.settle(np.concatenate([c for c, _ in charges]), np.concatenate([e for _, e in charges]))


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
    def _move_args(self) -> tuple:
        """The compiled loop's ``program`` record (:func:`~planners.ising.moves.selection.program_record`)."""
        return program_record(self.config.chip_rules, self.spec, self.config.num_reads)

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
        one compiled call (:func:`.move_engine.select_moves_loop`); its submissions' calls and emulation
        seconds are appended to ``charges`` for :func:`settle`.  A chip that never selects a valid improving
        set for a route that has improving moves fails the start (:class:`TourFailure`): the route would be
        the host's, not the chip's."""
        cfg = self.config
        new, status, st, clean, wins, calls, emu = select_moves_loop(
            run.rng, dist, route, cfg.max_segment, self._capacity, cfg.max_overlap, cfg.max_retries, cfg.max_rounds,
            self._move_args, link.args)
        charges.append((calls, emu))
        self._count_start(run, st, clean, wins, status)
        if status == REFUSED:
            raise ProgramRefused(REFUSED_MESSAGE)
        if status == NO_PROGRESS:
            raise TourFailure(self._no_progress)
        return new

    @property
    def _no_progress(self) -> str:
        cfg = self.config
        return (f"the chip selected no valid improving move set in {cfg.max_retries + 1} "
                f"submissions of {len(cfg.chip_rules)} programs")

    def _count_start(self, run, st, clean, wins, status) -> None:
        """The statistics of one start: ``st`` (rounds, retries, moves applied, rounds and programs with a
        valid read), ``clean`` (valid reads per rule), ``wins`` (best reads per rule), its status."""
        cfg = self.config
        rounds, retries, applied, valid_rounds, valid_programs = st.tolist()
        k = len(cfg.chip_rules)
        m = run.stats["mapping"]["tour"]
        m["reads"] += rounds * k * cfg.num_reads
        m["valid_reads"] += sum(clean.tolist())
        m["valid"] += valid_programs
        m["valid_physical"] += valid_programs
        m["programs"] += rounds * k
        m["physical_programs"] += rounds * k
        m["subproblems"] += rounds
        m["valid_subproblems"] += valid_rounds
        if wins.any():
            won = m.setdefault("wins", {})
            for rule, w in zip(cfg.chip_rules, wins.tolist()):
                if w:
                    won[rule] = won.get(rule, 0) + w
        run.stats["retries"] += retries
        run.stats["moves_applied"] += applied
        run.stats["move_rounds"] += rounds
        if status in (STALLED, NO_PROGRESS):
            run.stats["unsolved"]["moves"] += 1
