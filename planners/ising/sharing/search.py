"""Recursive Ising target sharing: the search of paper 5.3 (Algorithm 3).

Contract: ``IsingSharing(chip, config).assign(dist, n_robots, tour, rng) -> SharingResult``; a split that
never decodes valid, a group the chip cannot take or a refused program is a failure result, never an
invented split (a chip that cannot answer: ``stats["chip_unavailable"]``, which the pipeline hands to
SSA).  The search is Python over compiled steps (:mod:`.stages`, :mod:`.placement`, :mod:`.refine`); chip
calls are metered.  Oracle: ``tests/sharing_search_reference.py``; design: docs/design/ising_sharing.md.
"""

from __future__ import annotations

import itertools

import numpy as np

from ising_backend import ChipProgramError, ChipUnavailableError, MeteredSolver, SolverOutputError, mapping_record, record_of_reads
from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport
from planners.fallback import unavailable_message
from planners.ising.sharing.bundles import BundlePricer, SharingFailure
from planners.ising.sharing.components import assign_components
from planners.ising.sharing.config import SharingConfig
from planners.ising.sharing.split_problem import pair_mean
from planners.ising.sharing.node_sets import new_pool
from planners.ising.sharing.placement import ORDER_IDS, PRICERS, flat_sets, new_memo, place_states
from planners.ising.sharing.refine import refine_boundaries
from planners.ising.sharing.stage_steps import COUNTERS
from planners.ising.sharing.stages import CandidateStore, SharingStop, SplitStages
from planners.ising.sharing.submission import StageSolver

__all__ = ["IsingSharing", "PaperIsingSharing"]

_PRICING_HANDLES = itertools.count()


def failed(exc, compute, R, stats) -> SharingResult:
    """The failure result of a sharing call that stopped with ``exc`` (a :class:`SharingFailure` or
    :class:`ising_backend.ChipUnavailableError`) after spending ``compute``."""
    if isinstance(exc, ChipUnavailableError):
        stats["chip_unavailable"] = 1
        reason = unavailable_message(exc)
    else:
        reason = str(exc)
    return SharingResult(assignment=tuple(() for _ in range(R)), compute=compute, stats=stats, failure=reason)


class IsingSharing:
    """Recursive Ising target sharing on the emulated physical chip (module docstring).

    Args:
        chip: an :class:`ising_backend.EmulatedChip` or anything with its ``spec``,
            ``ledger`` and ``anneal_batch`` (default: a fresh ``EmulatedChip(ChipSpec())``).
        config: a :class:`SharingConfig`; keyword ``options`` override its fields.
    """

    name = "ising"
    config_class = SharingConfig
    defaults: SharingConfig | None = None  # None: SharingConfig()

    def __init__(self, chip=None, config: SharingConfig | None = None, **options) -> None:
        from ising_backend import as_machine

        self.config = SharingConfig.resolve(config, options, self.defaults)
        self.chip = as_machine(chip)  # the paper's emulated chip for None
        self._powered_for = None  # (dist, dist ** weight_power, its mean) of the running call
        self.stages = StageSolver(self.config, self.chip)

    def __repr__(self) -> str:
        return f"IsingSharing({self.config!r})"

    # ------------------------------------------------------------------ api

    def assign(self, dist, n_robots: int, tour: TourSolver, rng: np.random.Generator | None = None) -> SharingResult:
        dist = np.asarray(dist, dtype=float)
        if dist.ndim != 2 or dist.shape[0] != dist.shape[1]:
            raise ValueError(f"dist must be a square (R+N, R+N) matrix, got shape {dist.shape}")
        R = int(n_robots)
        if not 1 <= R <= dist.shape[0]:
            raise ValueError(f"n_robots must be in 1..{dist.shape[0]}, got {n_robots}")
        if rng is None:
            rng = np.random.default_rng()
        N = dist.shape[0] - R
        stats: dict = {
            "mapping": {"sharing": mapping_record(self.config.rules)},
            "stages": 0,
            "splits": 0,
            "trivial_splits": 0,
            "bundles": 0,
            "tour_solves": 0,
            "states": 0,
        }
        empty = tuple(() for _ in range(R))
        if not np.all(np.isfinite(dist)):
            return assign_components(self.assign, dist, R, tour, rng, stats)
        if N == 0:
            return SharingResult(assignment=empty, compute=ComputeReport(), stats=stats)
        if R == 1:
            return SharingResult(assignment=(tuple(range(N)),), compute=ComputeReport(), stats=stats)

        meter = self.stages.meter = MeteredSolver(self.chip)
        self._powered_for = None  # a new call: the split weights' base is recomputed
        pricer = None
        try:
            if self.config.pricing_tour != "auto":  # priced by the pricing tour (a callback of the compiled pricing)
                pricer = BundlePricer(dist, tour, self.config.pricing_tour, rng, stats)
            return self._assign_search(dist, R, rng, stats, pricer)
        except (SharingFailure, ChipUnavailableError) as exc:
            compute = ComputeReport.from_ledger(meter.charged)
            return failed(exc, compute if pricer is None else compute + pricer.compute, R, stats)

    def _assign_search(self, dist, R, rng, stats, pricer) -> SharingResult:
        """The search (module docstring) on one chip session, charged and counted; where it stops (a
        split without a valid candidate, a refused stage, robots that cannot be coarsened onto the
        chip) a :class:`SharingFailure` naming it."""
        cfg = self.config
        n_spins = int(self.chip.spec.n_spins)
        limit = n_spins + cfg.max_frozen
        # distinct candidates per split: rules x reads x the spin-budget branches of a split beyond the chip
        width = len(cfg.rules) * cfg.reads * (1 << max(0, min(limit - n_spins, dist.shape[0] - 2 - n_spins)))
        counters = np.zeros(len(COUNTERS), dtype=np.int64)
        mapping = np.zeros((len(cfg.rules), 3), dtype=np.int64)
        handle = -1
        if pricer is not None:  # its handle, found by the price callback while this call runs
            handle = next(_PRICING_HANDLES)
            PRICERS[handle] = pricer
        stop = None
        try:
            with self.chip.session(self.stages.meter.charged, decision="sharing_split") as link:
                stages = SplitStages(self.stages, link.args, new_pool(R), rng, limit, CandidateStore(width), counters,
                                     mapping)
                try:
                    sets = self._search(stages, dist, R, (new_memo(), handle))
                except SharingStop as exc:
                    stop = exc
                finally:  # what the chip ran is charged, also when a pricing tour failed
                    link.settle(stages.calls, stages.seconds)
        except SolverOutputError as exc:  # a broken machine behind the callback: nothing to decode
            raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
        except ChipProgramError as exc:
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        finally:
            PRICERS.pop(handle, None)
        counts = dict(zip(COUNTERS, counters.tolist()))
        for key in ("pair_resplits", "pair_accepted", "coarse_splits"):  # present once made
            if not counts[key]:
                del counts[key]
        for key, value in counts.items():
            stats[key] = stats.get(key, 0) + value
        stats["mapping"]["sharing"] = record_of_reads(  # none fails to map: a program beyond the chip raises
            cfg.rules, [(reads, valid, wins, 0) for reads, valid, wins in mapping.tolist()], cfg.reads)
        if stop is not None:
            raise SharingFailure(str(stop))
        flat, sizes = flat_sets(sets, stages.pool)
        ends = np.cumsum(sizes).tolist()
        flat = (flat - R).tolist()
        assignment = tuple(tuple(flat[e - c:e]) for e, c in zip(ends, sizes.tolist()))
        compute = ComputeReport.from_ledger(self.stages.meter.charged)
        return SharingResult(assignment=assignment, compute=compute if pricer is None else compute + pricer.compute,
                             stats=stats)

    def _search(self, stages, dist, R, prices) -> np.ndarray:
        """The split stages, bundle placement in every state, the choice of state and the boundary
        refinement: each robot's target set id."""
        cfg = self.config
        memo, pricing = prices
        w = np.ascontiguousarray(self.split_weights(dist, R))  # one layout for the stage steps
        groups, ng = stages.split_all(w, R, cfg)
        # every state's bundles placed; the state of least route cost (ties: larger cuts)
        ok, sets = place_states(dist, R, groups, ng, ORDER_IDS[cfg.bundle_order], memo, stages.counters, pricing,
                                stages.pool)
        if not ok:
            raise SharingStop("internal error: a group of several robots is left after the split stages")
        if cfg.pair_rounds:
            pair_w = np.stack([self.split_weights(dist, R, shift=shift) for shift in cfg.pair_shifts])
            refine_boundaries(stages, dist, pair_w, R, sets, cfg.pair_rounds, cfg.pair_neighbours, prices)
        return sets

    def split_weights(self, dist: np.ndarray, R: int, shift: float | None = None) -> np.ndarray:
        """Edge weights ``w_ij`` of the split graph: ``dist ** weight_power`` minus
        ``shift`` (default ``weight_shift``) x its mean over node pairs, robot-target edges then
        multiplied by ``robot_weight`` (zero diagonal)."""
        w, mean = self._powered(dist)
        shift = self.config.weight_shift if shift is None else shift
        if shift:
            w = w - shift * mean
            np.fill_diagonal(w, 0.0)
        else:
            w = w.copy()  # the caller's own array: the base is cached (and may be ``dist`` itself)
        if self.config.robot_weight != 1.0:
            w[:R, R:] *= self.config.robot_weight
            w[R:, :R] *= self.config.robot_weight
        return w

    def _powered(self, dist: np.ndarray) -> tuple[np.ndarray, float]:
        """``dist ** weight_power`` and its mean over node pairs ``i < j``, kept for the last ``dist``
        (a planning call asks for the weights of several shifts)."""
        cached = self._powered_for
        if cached is not None and cached[0] is dist:
            return cached[1], cached[2]
        power = self.config.weight_power
        w = np.asarray(dist, dtype=float)
        w = w ** power if power != 1.0 else w  # x ** 1.0 is x; the weights are never changed in place
        mean = float(pair_mean(w))  # the mean over pairs i < j, numpy's bits
        self._powered_for = (dist, w, mean)
        return w, mean

    # -------------------------------------------------------------- helpers


class PaperIsingSharing(IsingSharing):
    """:class:`IsingSharing` with the paper's configuration (:meth:`SharingConfig.paper`)."""

    name = "ising-paper"
    defaults = SharingConfig.paper()
