"""Fleet routing with chip-selected moves between robots: an iterated local search.

Contract: :class:`IsingFleetSharing` builds SSA's insertion routes on the host, then runs one compiled
call (:func:`.local_search.iterated_search`) on one machine session: a local search in which the chip
selects a compatible set of improving granular moves per round (a read selecting clashing moves is
dropped, never repaired), and ruin-and-recreate kicks.  Deterministic under the seed; every chip call is
charged to the layer's report.  Design notes and measurements: docs/design/ising_fleet.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ising_backend import QUANTIZE_RULES, CallLedger, ChipUnavailableError, as_machine, mapping_record
from planners.base import SharingResult
from planners.compute import ComputeReport
from planners.fallback import FALLBACK_MODES, flagged, unavailable_message
from planners.ising.fleet.local_search import FleetBest, iterated_search
from planners.ising.moves.routes import route_cost
from planners.ising.moves.search import FLEET_FIELDS, REFUSED, SearchLimits, new_stats, stats_dict
from planners.ising.moves.selection import REFUSED_MESSAGE, program_record
from planners.options import Options, option
from planners.sharing_classical import SSASharing

__all__ = ["FleetConfig", "IsingFleetSharing"]


@dataclass(frozen=True)
class FleetConfig(Options):
    """Options of :class:`IsingFleetSharing` (module docstring; :meth:`~planners.options.Options.describe` lists
    them)."""

    neighbours: int = option(10, int, 1, meaning="nearest nodes per target whose moves are listed (granular "
                                                 "neighbourhood)")
    max_moves: int = option(16, int, 1, meaning="most candidate moves per selection program (capped by the chip's "
                                                "spins)")
    max_overlap: int = option(4, int, 0, meaning="a candidate clashes with at most this many better-gain candidates "
                                                 "of its program")
    chip_rules: tuple = option(("linear", "rank"), tuple, words=QUANTIZE_RULES,
                               meaning="quantization rules, one selection program each per round (distinct)")
    num_reads: int = option(1, int, 1, meaning="reads per program")
    max_retries: int = option(2, int, 0, meaning="rounds in a row without a valid read before a local search ends")
    kicks: int | None = option(None, int, 0, none=True,
                               meaning="ruin-and-recreate steps of the iterated local search (0: local search only; "
                                       "None: kicks_per_target x N, at least min_kicks, at most three times that)")
    kicks_per_target: int = option(5, int, 0, meaning="kicks per target when kicks is None")
    min_kicks: int = option(1500, int, 0, meaning="the floor of that budget (measured in docs/design/ising_fleet.md)")
    ruin: int | None = option(None, int, 2, none=True,
                              meaning="most targets removed per kick, drawn in 2..ruin (None: two routes' worth, "
                                      "max(5, 2 N // R))")
    slack: float = option(0.005, float, 0, meaning="a kicked solution replaces the current one when it costs at most "
                                                   "the best one times 1 + slack (record-to-record travel)")
    fallback: str = option("unavailable", str, words=FALLBACK_MODES,
                           meaning="a chip that cannot answer: 'never' fails the call; otherwise the routes found so "
                                   "far are kept, flagged; with 'failure' a refused search also goes to SSA")
    selection: str = option("chip", str, words=("chip", "greedy"),
                            meaning="who picks the compatible set among the offered moves: 'chip' (the method) or "
                                    "'greedy' (the host, by gain; no chip call: the ablation)")

    def __post_init__(self) -> None:
        super().__post_init__()
        if len(set(self.chip_rules)) != len(self.chip_rules):  # each rule is one program: named twice, counts merge
            raise ValueError(f"chip_rules = {self.chip_rules} names a rule twice (each rule is one program of every "
                             "round)")


class IsingFleetSharing:
    """Sharing layer ``ising-fleet``: SSA routes improved by chip-selected moves between robots."""

    name = "ising-fleet"
    orders_routes = True
    config_class = FleetConfig

    def __init__(self, chip=None, config: FleetConfig | None = None, **options) -> None:
        self.config = FleetConfig.resolve(config, options)
        self.chip = as_machine(chip)  # the paper's emulated chip for None

    def assign(self, dist, n_robots: int, tour=None, rng=None) -> SharingResult:
        rng = rng if rng is not None else np.random.default_rng()
        base = SSASharing().assign(dist, n_robots)
        d = np.ascontiguousarray(np.asarray(dist, dtype=np.float64))
        r = int(n_robots)
        m = d.shape[0]
        n = m - r
        if n <= 1 or base.failure:
            return base
        nxt = np.full(m, -1, dtype=np.int64)
        prv = np.full(m, -1, dtype=np.int64)
        for k, group in enumerate(base.assignment):
            x = k
            for t in group:
                nxt[x], prv[r + t] = r + t, x
                x = r + t
        k = min(self.config.neighbours, m - 1)
        order = np.argsort(d[r:], axis=1, kind="stable")  # nearest nodes of each target (itself first)
        neigh = np.ascontiguousarray(order[:, 1:k + 1])
        neigh = np.vstack([np.full((r, neigh.shape[1]), -1, dtype=np.int64), neigh])
        cfg = self.config
        ruin = max(2, cfg.ruin or max(5, 2 * n // r))
        per_target = cfg.kicks_per_target * n
        kicks = max(per_target, min(cfg.min_kicks, 3 * per_target)) if cfg.kicks is None else cfg.kicks
        search = SearchLimits(capacity=min(int(self.chip.usable_spins), cfg.max_moves), max_overlap=cfg.max_overlap,
                              max_retries=cfg.max_retries, max_rounds=0, chip=cfg.selection == "chip")
        charged = CallLedger()
        best_nxt, best_cost = nxt.copy(), np.array([route_cost(d, nxt, r)])  # the cheapest routes so far
        stats: dict = {}
        failure = kept = None
        counts = new_stats()  # as the search goes, also up to a machine's error
        clean, wins = np.zeros(len(cfg.chip_rules), dtype=np.int64), np.zeros(len(cfg.chip_rules), dtype=np.int64)
        try:
            with self.chip.session(charged, decision="fleet_moves") as link:
                program = program_record(cfg.chip_rules, self.chip.spec, cfg.num_reads)
                status, calls, emu = iterated_search(
                    rng, d, nxt, prv, r, neigh, order, search, (int(kicks), int(ruin), float(cfg.slack)), program,
                    link.args, FleetBest(best_nxt, best_cost, counts, (clean, wins)))
                link.settle(calls, emu)
            if status == REFUSED:
                failure = REFUSED_MESSAGE
        except ChipUnavailableError as exc:  # the routes so far stand: SSA's, with the moves the chip made
            stats["chip_unavailable"] = 1
            if cfg.fallback == "never":
                failure = unavailable_message(exc)
            else:
                kept = unavailable_message(exc) + "; the routes found before are kept"
        groups = []
        for k_ in range(r):
            g, x = [], best_nxt[k_]
            while x >= 0:
                g.append(int(x) - r)
                x = best_nxt[x]
            groups.append(tuple(g))
        fleet = stats_dict(counts, FLEET_FIELDS)
        programs = fleet["rounds"] if cfg.selection == "chip" else 0  # each chip round: one program per rule
        stats["mapping"] = {"fleet": mapping_record(cfg.chip_rules, [
            (programs, programs * cfg.num_reads, valid, won, 0) for valid, won in zip(clean.tolist(), wins.tolist())])}
        stats["fleet"] = {**fleet,
                          "ssa_cost": float(route_cost_of(d, base.assignment, r)), "cost": float(best_cost[0])}
        compute = ComputeReport.from_ledger(charged)
        if failure:
            return SharingResult(assignment=tuple(() for _ in range(r)), compute=compute, stats=stats, failure=failure)
        result = SharingResult(assignment=tuple(groups), compute=compute, stats=stats)
        return result if kept is None else flagged("sharing", result, kept)

    def __repr__(self) -> str:
        return f"IsingFleetSharing(config={self.config!r})"


def route_cost_of(d, groups, r) -> float:
    total = 0.0
    for k, g in enumerate(groups):
        nodes = [k] + [r + t for t in g]
        total += sum(d[a, b] for a, b in zip(nodes[:-1], nodes[1:]))
    return total
