"""Recursive Ising target sharing: the search of paper 5.3 (Algorithm 3).

Contract: ``IsingSharing(chip, config).assign(dist, n_robots, tour, rng) -> SharingResult``;
a split that never decodes valid, a group the chip cannot take or a refused program is a
failure result (``result.failure``), never an invented split.  The search runs in one compiled
call (:mod:`.compiled_assign`): stages split every group with several robots, then refine
one-robot groups and bundles, a beam of distinct candidates carried to the complete
assignments, which are compared by route cost; each stage's splits x quantization rules go
block-packed into one chip submission (:class:`~.submit.StageSolver` holds the chip side);
groups beyond the chip split on clusters or spin-budget branches.  Then, beyond the paper
(``pair_rounds``, 0 in ``PaperIsingSharing``), the boundaries between neighbouring robots are
re-split on the chip.  Chip calls are metered (:class:`ising_backend.MeteredSolver`); a chip
that cannot answer hands the call to SSA (flagged; :mod:`planners.ising.fallback`).  The Python
search in ``tests/sharing_search_reference.py`` is its oracle.  Choices and measurements:
docs/design/ising_sharing.md.
"""

from __future__ import annotations

import itertools

import numpy as np

from ising_backend import ChipProgramError, ChipUnavailableError, MeteredSolver, SolverOutputError
from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport
from planners.ising.config import ConfigAttributes, resolve_config
from planners.ising.fallback import counted, flag, unavailable_message, wants_fallback
from planners.ising.sharing.bundles import BundlePricer, SharingFailure
from planners.ising.sharing.compiled_assign import ORDER_IDS, PRICERS, assign_kernel
from planners.ising.sharing.kernels import pair_mean
from planners.ising.sharing.compiled_stages import COUNTERS, FAILED_SPLIT, REFUSED_STAGE, UNCOARSENED
from planners.ising.sharing.components import assign_components
from planners.ising.sharing.config import SharingConfig
from planners.ising.sharing.submit import StageSolver, stage_refusal

__all__ = ["IsingSharing", "PaperIsingSharing"]

_PRICING_HANDLES = itertools.count()


class IsingSharing(ConfigAttributes):
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

        self.config = resolve_config(SharingConfig, config, options, self.defaults)
        self.chip = as_machine(chip)  # the paper's emulated chip for None
        spec = self.chip.spec
        self._powered_for = None  # (dist, dist ** weight_power, its mean) of the running call
        self.stages = StageSolver(self.config, self.chip)
        cfg = self.config
        # the arguments of the whole sharing in one compiled call (.compiled_assign), after the stage record
        opts = (cfg.beam, cfg.refine_beam, cfg.max_states, cfg.refine_stages, cfg.resolved_base_max,
                cfg.refine_above, int(cfg.reject_empty_robot_side))
        pair_opts = (ORDER_IDS[cfg.bundle_order], cfg.pair_rounds, cfg.pair_neighbours)
        self._compiled = (cfg.retries, int(spec.n_spins) + cfg.max_frozen, opts,
                          (cfg.weight_shift, cfg.robot_weight, float(cfg.balance)), np.array(cfg.pair_shifts),
                          pair_opts)

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
        mapping = {r: {"candidates": 0, "valid": 0, "wins": 0} for r in self.config.rules}
        stats: dict = {
            "mapping": {"sharing": mapping},
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
            if self.config.pricing_tour != "auto":  # priced by the pricing tour (a callback of the compiled call)
                pricer = BundlePricer(dist, tour, self.config.pricing_tour, rng, stats)
            return self._assign_compiled(dist, R, rng, stats, pricer)
        except (SharingFailure, ChipUnavailableError) as exc:
            compute = ComputeReport.from_ledger(meter.charged)
            return self.failed(exc, compute if pricer is None else compute + pricer.compute, dist, R, tour, rng, stats)

    def failed(self, exc, compute, dist, R, tour, rng, stats) -> SharingResult:
        """The result of a sharing call that stopped with ``exc`` (a :class:`SharingFailure` or
        :class:`ising_backend.ChipUnavailableError`) after spending ``compute``: SSA's sharing
        (flagged) where ``fallback`` asks for it, else a failure result naming why."""
        unavailable = isinstance(exc, ChipUnavailableError)
        reason = unavailable_message(exc) if unavailable else str(exc)
        if wants_fallback(self.config.fallback, unavailable):  # SSA, the strong pipeline's sharing
            from planners.sharing_classical import SSASharing

            res = SSASharing().assign(dist, R, tour, rng)
            return SharingResult(assignment=res.assignment, compute=counted(compute, res.compute),
                                 stats=flag(stats, "sharing", reason))
        return SharingResult(assignment=tuple(() for _ in range(R)), compute=compute, stats=stats, failure=reason)

    def _assign_compiled(self, dist, R, rng, stats, pricer) -> SharingResult | None:
        """The sharing in one compiled call (:func:`.compiled_assign.assign_kernel`), charged and
        counted; where it stops (a split without a valid candidate, a refused stage, robots that
        cannot be coarsened onto the chip) a :class:`SharingFailure` naming it."""
        cfg = self.config
        powered, mean = self._powered(dist)
        # room for every submission: each stage (splits down to single robots, refinement, pair rounds) and
        # each coarse split (at most one per group beyond the chip in a state's stage, per pair and shift)
        # submits at most retries + 1 times
        n = dist.shape[0]
        stages = 2 * R + cfg.refine_stages + cfg.pair_rounds * R + 2
        if n - 2 > int(self.chip.spec.n_spins) + cfg.max_frozen:
            stages += cfg.max_states * stages * (n // (int(self.chip.spec.n_spins) + cfg.max_frozen + 3) + 1)
            stages += cfg.pair_rounds * R * max(1, cfg.pair_neighbours) * len(cfg.pair_shifts)
        subs = stages * (cfg.retries + 1)
        book = (np.zeros((len(cfg.rules), 3), dtype=np.int64), np.zeros(len(COUNTERS), dtype=np.int64),
                np.zeros(subs, dtype=np.int64), np.zeros(subs), np.zeros(3, dtype=np.int64))
        stages = self.stages
        handle = -1
        if pricer is not None:  # its handle, found by the price callback while this call runs
            handle = next(_PRICING_HANDLES)
            PRICERS[handle] = pricer
        compiled = (*self._compiled[:-1], (*self._compiled[-1], handle))
        mapping, counters, calls, emu, failure = book
        try:
            with self.chip.session(stages.meter.charged, decision="sharing_split") as link:
                try:
                    ok, flat, sizes, failed = assign_kernel(dist, powered, mean, R, rng, stages.args(link.args),
                                                            *compiled, book)
                except SharingFailure:  # a pricing tour that failed: what the chip ran so far is charged
                    link.settle(calls[:counters[-1]], emu[:counters[-1]])
                    raise
                link.settle(calls[:counters[-1]], emu[:counters[-1]])
        except SolverOutputError as exc:  # a broken machine behind the callback: nothing to decode
            raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
        except ChipProgramError as exc:
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        finally:
            PRICERS.pop(handle, None)
        counts = dict(zip(COUNTERS, counters.tolist()))
        counts.pop("submissions")
        for key in ("pair_resplits", "pair_accepted", "coarse_splits"):  # present once made
            if not counts[key]:
                del counts[key]
        for key, value in counts.items():
            stats[key] = stats.get(key, 0) + value
        for rule, (cands, valid, wins) in zip(cfg.rules, mapping.tolist()):
            stats["mapping"]["sharing"][rule] = {"candidates": cands, "valid": valid, "wins": wins}
        if not ok:
            raise SharingFailure(self._stopped(failed.tolist(), *failure.tolist()))
        ends = np.cumsum(sizes).tolist()
        flat = (flat - R).tolist()
        assignment = tuple(tuple(flat[e - c:e]) for e, c in zip(ends, sizes.tolist()))
        compute = ComputeReport.from_ledger(stages.meter.charged)
        return SharingResult(assignment=assignment, compute=compute if pricer is None else compute + pricer.compute,
                             stats=stats)

    def _stopped(self, nodes: list, code: int, what: int, submissions: int) -> str:
        """Why the compiled sharing stopped (``book[4]`` of :func:`.compiled_assign.assign_kernel`; ``nodes``:
        the group of a failed split)."""
        if code == FAILED_SPLIT:
            return f"every chip candidate for the split of group {nodes} was invalid after {submissions} submissions"
        if code == REFUSED_STAGE:
            return stage_refusal(what)
        if code == UNCOARSENED:
            n_spins = int(self.chip.spec.n_spins)
            return (f"a group of {what} robots and {submissions} targets cannot be coarsened onto the chip: its split "
                    f"needs at least {max(2, (n_spins + 2) // 2) - 1} free spins, the chip has {n_spins}")
        return f"internal error: the compiled sharing met a group outside its contract (check {what})"

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
