"""Ising tour construction: chip move selection (default) and the clustered construction of paper 5.2.

Contract: ``IsingTour(chip, config).solve(dist, rng) -> TourResult`` orders nodes ``1..n`` of ``dist`` into
an open route from node 0; a search that never decodes valid is a failure result, never a repaired tour
(a chip that cannot answer: ``stats["chip_unavailable"]``, which the pipeline hands to 3-opt).  Backends:
``"chip"`` (:mod:`.selection`), ``"logical"`` (the paper's Algorithm 2, ``PaperIsingTour``) and
``"chip-onehot"``.  Every call is metered.  Choices and measurements: docs/design/ising_tour.md.
"""

from __future__ import annotations

import math

import numpy as np

from ising_backend import ChipUnavailableError, SolverOutputError, mapping_record
from planners.base import TourResult
from planners.compute import ComputeReport
from planners.fallback import unavailable_message
from planners.ising.tour.cluster import Clusters, TourFailure, _Run
from planners.ising.tour.config import TourConfig
from planners.ising.tour.kernels import dist_flags, route_cost
from planners.ising.tour.onehot import OneHotSolver
from planners.ising.tour.selection import MoveSearch

__all__ = ["IsingTour", "PaperIsingTour"]


class IsingTour:
    """Clustered Ising tour construction (see the module docstring), built from components:
    ``moves`` (:class:`~.selection.MoveSearch`, the chip backend), ``onehot``
    (:class:`~.onehot.OneHotSolver`, one-hot and max-cut programs) and ``clusters``
    (:class:`~.cluster.Clusters`, clustering and cluster ordering on them).

    Args:
        chip: an :class:`ising_backend.EmulatedChip` (default: a fresh one); its
            spec gives the spin budget and the accounting numbers, and its ledger
            is shared with the default logical solver (one ledger per pipeline).
        config: a :class:`TourConfig`; keyword ``options`` override its fields.
        solver: a ready logical solver (``solve_many(models, num_reads, seed)``,
            ``ledger``, ``last_call``), replacing the default.
    """

    name = "ising"
    config_class = TourConfig
    defaults: TourConfig | None = None  # None: TourConfig()

    def __init__(self, chip=None, config: TourConfig | None = None, *, solver=None, **options) -> None:
        from ising_backend import as_machine

        self.chip = as_machine(chip)  # the paper's emulated chip for None
        self.spec = self.chip.spec
        cfg = TourConfig.resolve(config, options, self.defaults)
        # sizes not given explicitly shrink to a smaller chip (an explicit config is taken as it is)
        self.config = cfg = cfg if config is not None else cfg.fit_spins(self.spec.n_spins, keep=set(options))
        self.onehot = OneHotSolver(cfg, self.chip, solver)
        self.solver = self.onehot.solver
        self.clusters = Clusters(cfg, self.onehot)
        self.moves = MoveSearch(cfg, self.chip)
        budget = self.onehot.budget
        largest = max(cfg.local_limit, cfg.patch_size, cfg.max_clusters - 1)
        if cfg.backend != "chip" and largest ** 2 > budget + cfg.max_branch_bits:  # one-hot models only
            raise ValueError(
                f"one-hot models of {largest}^2 = {largest ** 2} variables exceed the spin budget {budget} "
                f"+ max_branch_bits {cfg.max_branch_bits} (local_limit={cfg.local_limit}, patch_size="
                f"{cfg.patch_size}, max_clusters={cfg.max_clusters})")

    def __repr__(self) -> str:
        return f"IsingTour({self.config!r})"

    # ------------------------------------------------------------------ public
    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        """Order nodes ``1..n`` of ``dist`` into an open route from node 0."""
        dist = np.asarray(dist, dtype=np.float64)
        if dist.ndim != 2 or dist.shape[0] != dist.shape[1] or dist.shape[0] < 1:
            raise ValueError(f"dist must be a square (n+1, n+1) matrix, got shape {dist.shape}")
        flag, r, c = dist_flags(dist)
        if flag == 1:
            raise ValueError("dist must hold non-negative distances (no NaN)")
        rng = np.random.default_rng() if rng is None else rng
        n = dist.shape[0] - 1
        run = _Run(rng, self._empty_stats(), self)
        if flag == 2:
            return self._result(run, None, dist,
                                f"distance {(int(r), int(c))} is infinite: targets on different components")
        if n == 0:
            return self._result(run, (), dist)
        if self.config.backend == "chip":
            try:
                return self._result(run, self.moves.starts(dist, run), dist)
            except SolverOutputError as exc:
                return self._result(run, None, dist, f"the chip returned malformed samples: {exc}")
            except ChipUnavailableError as exc:
                return self._unavailable(run, dist, exc)
            except TourFailure as exc:
                return self._result(run, None, dist, str(exc))
        best, best_cost, failure = None, math.inf, None
        clusters = None
        starts = 1 if n <= self.config.patch_size else self.config.n_starts
        stale = 0  # consecutive starts that did not improve the best tour
        for _start in range(starts):
            if self.config.start_patience is not None and stale >= self.config.start_patience:
                break
            try:
                if clusters is None or not self.config.share_clusters:
                    clusters = self.clusters.cluster(dist, run)
                ordered = self.clusters.order(dist, clusters, run)
                tour = self._local_tours(dist, ordered, run)
                tour = self._refine(dist, tour, run)
            except SolverOutputError as exc:  # a broken solver: no start can succeed
                return self._result(run, None, dist, f"the solver returned malformed samples: {exc}")
            except ChipUnavailableError as exc:  # no core can answer
                return self._unavailable(run, dist, exc)
            except TourFailure as exc:  # this start gave up; other starts may still succeed
                failure = str(exc)
                run.stats["failed_starts"] += 1
                clusters = None
                continue
            cost = _tour_cost(dist, tour)
            run.stats["start_costs"].append(cost)
            if cost < best_cost - 1e-9:
                best, best_cost = tour, cost
                stale = 0
            else:
                stale += 1
        if best is None:
            return self._result(run, None, dist, failure)
        return self._result(run, tuple(int(t) for t in best), dist)

    def _unavailable(self, run: _Run, dist, exc) -> TourResult:
        run.stats["chip_unavailable"] = 1
        return self._result(run, None, dist, unavailable_message(exc))


    # ------------------------------------------------------------------ 3. local TSPs
    def _local_tours(self, dist: np.ndarray, ordered: list[list[int]], run: _Run) -> list[int]:
        tour: list[int] = []
        prev = 0
        for k, c in enumerate(ordered):
            c = np.asarray(c)
            if len(c) == 1:
                local = [int(c[0])]
            else:
                d = dist[np.ix_(c, c)]
                entry = dist[prev, c]
                if k + 1 < len(ordered):
                    nxt = np.asarray(ordered[k + 1])
                    block = dist[np.ix_(c, nxt)]
                    ex = block.min(axis=1) if self.config.exit_cost == "min" else block.mean(axis=1)
                    ex = self.config.exit_weight * ex
                else:
                    ex = np.zeros(len(c))
                order = self.onehot.solve_path(d, entry, ex, run, "local")
                if order is None:
                    raise TourFailure(f"local TSP of cluster {k} ({len(c)} targets) gave no valid permutation "
                                      f"after {self.config.max_retries + 1} attempts")
                local = [int(c[i]) for i in order]
            tour.extend(local)
            prev = local[-1]
        return tour

    # ------------------------------------------------------------------ 4. patch refinement
    def _refine(self, dist: np.ndarray, tour: list[int], run: _Run) -> list[int]:
        n = len(tour)
        L = min(self.config.patch_size, n)
        if L < 2:
            return tour
        n_windows = n - L + 1
        patience = n_windows + 1 if self.config.patience is None else self.config.patience
        tour = list(tour)
        cost = _tour_cost(dist, tour)
        fails = 0
        queue: list[int] = []
        while fails < patience:
            if not queue:
                queue = [int(a) for a in run.rng.permutation(n_windows)]
            a = queue.pop()
            patch = np.asarray(tour[a:a + L])
            prev = tour[a - 1] if a > 0 else 0
            d = dist[np.ix_(patch, patch)]
            entry = dist[prev, patch]
            ex = dist[patch, tour[a + L]] if a + L < n else np.zeros(L)
            run.stats["patches"] += 1
            order = self.onehot.solve_path(d, entry, ex, run, "patch")
            if order is not None:
                new = tour[:a] + [int(patch[i]) for i in order] + tour[a + L:]
                new_cost = _tour_cost(dist, new)
                if new_cost < cost - 1e-9:
                    tour, cost = new, new_cost
                    fails = 0
                    run.stats["patches_accepted"] += 1
                    continue
                if self.config.accept_equal and new_cost <= cost + 1e-9 and new != tour:
                    tour = new  # sideways move on a cost plateau; still a non-improving attempt
                    run.stats["patches_sideways"] += 1
            fails += 1
        return tour

    # ------------------------------------------------------------------ result
    def _empty_stats(self) -> dict:
        return {
            "backend": self.config.backend,
            "clusters": [],
            "start_costs": [],
            "failed_starts": 0,
            "cluster_splits": 0,  # max-cut splits of the clustered construction (not the sharing's "splits")
            "refinement_splits": 0,
            "ordering_splits": 0,
            "patches": 0,
            "patches_accepted": 0,
            "patches_sideways": 0,
            "retries": 0,
            "moves_applied": 0,
            "move_rounds": 0,
            "unsolved": {"ordering": 0, "local": 0, "patch": 0, "moves": 0},
            "subproblems": 0,  # move-selection rounds or one-hot models sent to the machine
            "valid_subproblems": 0,  # ... with at least one valid read
            "valid_programs": 0,  # programs with at least one valid read
            "mapping": {"tour": mapping_record(self.config.choices)},
        }

    def _result(self, run: _Run, order, dist, failure: str | None = None) -> TourResult:
        compute = ComputeReport.from_ledger(run.charged)
        if failure is not None:
            return TourResult(order=(), cost=math.inf, compute=compute, stats=run.stats, failure=failure)
        return TourResult(order=tuple(order), cost=_tour_cost(dist, list(order)), compute=compute, stats=run.stats)


class PaperIsingTour(IsingTour):
    """:class:`IsingTour` with the paper's configuration (:meth:`TourConfig.paper`)."""

    name = "ising-paper"
    defaults = TourConfig.paper()


def _tour_cost(dist: np.ndarray, tour: list[int]) -> float:
    if not len(tour):
        return 0.0
    return float(route_cost(dist, np.asarray(tour, dtype=np.int64)))
