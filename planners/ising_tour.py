"""Clustered Ising tour construction (paper section 5.2, Algorithm 2) -- ``--tour ising``.

The tour layer orders the targets of one robot into an open route.  The target
set is decomposed into small Ising subproblems whose samples are the only
source of ordering decisions; the host decomposes, decodes, rejects invalid
samples, scores candidates on the original objective and stitches:

1. **Distance-Ising clustering.**  Recursive max-cut splits (eq. 7,
   ``cut = sum_{i<j} w_ij (x_i + x_j - 2 x_i x_j)``, maximised, ``w`` = BFS
   distance) of every cluster larger than ``local_limit`` (7) targets, then
   refinement splits until there are ``max_clusters`` (8) clusters.
2. **Cluster ordering.**  The cluster nearest the robot start is fixed first;
   the other ``K-1`` are ordered by a one-hot position QUBO with ``(K-1)^2``
   variables (49 for ``K = 8``).
3. **Local TSP.**  Each cluster, in that order, is solved as a local open-path
   one-hot QUBO with soft boundary costs: from the previous endpoint into the
   first local target, and from the last local target toward the next cluster.
4. **Ising patch refinement.**  Random contiguous patches of at most
   ``patch_size`` (6; the paper's limit is 7) targets are re-solved as one-hot QUBOs with the fixed
   waypoints before and after the patch; a patch is accepted only if the full
   tour cost strictly decreases; the loop stops after ``patience``
   consecutive non-improving patches.

Models above the spin budget (45) go through spin-budget branching
(:func:`ising_backend.branch`, 49 -> 16 branches).  The default backend is the
logical Ising solver (:class:`ising_backend.LogicalIsingSolver`): the spin
budget is enforced but not the coefficient range, and every program solve is
one projected chip call (``compute.logical_calls``), as in the paper.
``backend="chip"`` runs the very same QUBOs on the emulated physical chip
after :func:`ising_backend.quantize` (rule ``chip_quantize``), to measure the
paper's finding that the chip's ``[-7, 7]`` range cannot hold the one-hot
penalties: ``stats["mapping"]["tour"]`` counts ``programs`` (one-hot programs
solved), ``valid`` (programs with at least one valid permutation among their
reads) and ``valid_physical`` (the same, for programs run on the physical chip).

Choices the paper leaves open (each a constructor parameter where reasonable):

* **Which cluster is refined** (``refine="largest"``): the largest cluster,
  ties by lowest index in the cluster list (children of a split replace their
  parent in place, side ``x=0`` first).  Splitting the largest keeps local
  problems balanced (``"spare_first"`` refines the cluster nearest the robot
  last; measured worse: 2.28 % vs 1.56 % mean gap with one start on 400 worlds).  Refinement runs whenever fewer than ``max_clusters``
  clusters exist and some cluster has two or more targets, **also for small
  ``n``**: with 10 targets the paper's ``(K-1)^2 = 49`` example implies ``K = 8``
  (several singleton clusters).  ``max_clusters=1`` disables refinement.
* **Trivial subproblems are not sent to the solver**: a 2-target split (the
  only non-degenerate cut), a 1-target cluster and a single cluster to order
  have exactly one outcome, so no Ising call is made for them.
* **Cluster-to-cluster distance** (``cluster_distance="min"``): single
  linkage, the smallest BFS distance between a target of one cluster and one
  of the other (the cheapest possible stitch); ``"mean"`` (average linkage)
  and ``"medoid"`` (distance between the clusters' medoids) are offered.
  Measured with the defaults (4 starts) on 500 10-target worlds (seeds
  0..499): mean gap 0.39 % (``min``) vs 0.43 % (``mean``); with a single start
  ``mean`` is slightly better (1.69 % vs 1.79 % on seeds 100..299), so the
  choice is close.  The robot's distance to a cluster (which one is first) is
  the minimum as well.
* **Soft exit cost** of a local TSP (``exit_cost="min"``): for each local
  target, its minimum (``"min"``) or mean (``"mean"``) BFS distance to the
  targets of the next cluster, times ``exit_weight`` (1); zero for the last
  cluster (open route).  The entry cost is the exact distance from the previous
  endpoint.
* **Penalty weight**: route weight ``B = 1``, one-hot penalty ``A =
  penalty_factor * w_max + 1`` (``penalty_factor=1``) with ``w_max`` the
  largest route coefficient of the subproblem (see
  :mod:`planners.ising_tsp_qubo`: ``A > w_max`` makes every ground state a
  valid permutation; a larger ``A`` only steepens the walls the sampler must
  cross).
* **Patch size** (``patch_size=6``, the paper's limit is 7): a patch has
  ``min(patch_size, n)`` targets.  A 6-target patch is 36 spins, one call; a
  7-target patch is 49 variables, 16 branched calls.  Spending those calls on
  independent starts instead (below) buys more quality per call: on 200
  10-target worlds (seeds 100..299, average linkage), 6-target patches x 4
  starts gave mean gap 0.43 % at a median 117 calls, 7-target patches x 2
  starts 0.92 % at 206 calls.
* **Patch choice and patience M**: start positions are drawn without
  replacement from a fresh random permutation of the ``n - L + 1`` windows each
  round, and a patch is accepted only if the full tour cost strictly decreases
  (the paper's rule; ``accept_equal=True`` also takes equal-cost reorders as
  sideways moves, still counted as failures).  ``patience=None`` (default)
  sets ``M`` = number of windows + 1: stopping then means every window was
  re-solved since the last improvement without gain, i.e. the tour is locally
  optimal with respect to every window (as far as the sampler finds each patch
  optimum; measured: every non-optimal final tour was a true window-local
  optimum), plus one retry for the stochastic sampler.
* **Independent starts** (``n_starts=4``): the whole construction (clustering,
  ordering, local TSPs, refinement) is repeated with fresh samples and the
  cheapest final tour is kept (host scoring of Ising-generated candidates, the
  paper's portfolio idea applied to the whole construction).  Nearly all
  remaining gaps are window-local optima where the tour runs the "wrong way"
  from the nearest cluster (fixed first, as in the paper); different max-cut
  samples give different clusterings and so different local optima.  One
  start: mean gap 1.1-1.8 % depending on the seed range; four: 0.34-0.50 %.
  Starts do not share clusterings (``share_clusters=True`` reuses the first
  one: cheaper, measured worse).  ``start_patience=k`` stops after ``k``
  starts in a row that did not improve the best tour (default ``None``: all
  ``n_starts``); measured on seeds 100..499, ``n_starts=6, start_patience=2``
  saves calls (median 89 instead of 117) but loses quality (0.51 % vs 0.38 %).
  With ``n <= patch_size`` the one patch is the whole tour, so only one start
  is made.
* **Sampling**: ``num_reads`` reads per program (each read of a logical program
  is one projected chip call); the candidate with the best original objective
  among the valid decoded samples of all branches wins.  The logical tabu
  solver runs with ``max_tenure=10`` (:data:`DEFAULT_SOLVER_OPTIONS`): its
  general default tenure (up to 20) blocks the four-spin moves between
  permutations on 36-45-spin one-hot models (patch optimum found on 45/60 vs
  150/150 random 6-target patches).
* **No valid candidate** (a non-repairing fallback): the program is re-issued
  with a fresh seed up to ``max_retries`` (3) times.  A refinement patch that
  still has no valid candidate keeps the previous order (a failed attempt).  A
  split, the cluster ordering or a local TSP that never yields a valid
  candidate ends that start; if no start completes, the result is a failure
  (``TourResult.failure``, empty order, infinite cost), never an invalid or
  classically repaired tour.
* **Clusters larger than the spin budget** (more than ``budget +
  max_branch_bits`` targets; never on the paper's 10-target instances): the
  split is solved on ``budget`` members drawn at random and each other member
  joins the side of its nearest drawn member (decomposition by the host; the
  Ising sample decides the cut of the drawn members).
* **More clusters than the ordering limit** (the paper is silent; happens
  only above ~50 targets per robot, since clusters hold at most 7): the
  clusters after the first are ordered hierarchically -- a max-cut split of
  the clusters on the cluster distance, the part nearer to the previous
  cluster first (the nearest-first rule one level up), each part ordered
  recursively, parts of at most ``max_clusters - 1`` clusters by the one-hot
  ordering model.
* **Physical chip** (``backend="chip"``): the one-hot programs (and their
  branches) and the max-cut splits are quantized with ``chip_quantize``
  (``"linear"``) and annealed on the emulated chip (``num_reads`` reads
  each); the mapping statistic counts the one-hot programs.  Measured (20
  worlds each, all four quantization rules): 3 targets (4-variable ordering) decode valid on
  36-100 % of programs; from 5 targets on (16+ variables) on 0 %, so every
  construction fails -- the paper's finding, reproduced.  It is the range,
  not the annealer: the exact ground state of the quantized 16-variable
  ordering model is itself invalid in 20 of 20 cases under every rule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ising_backend import QUANTIZE_RULES, ChipSpec, EmulatedChip, LogicalIsingSolver, QuboModel, branch, quantize
from planners.base import TourResult
from planners.compute import ComputeReport
from planners.ising_tsp_qubo import (
    cut_value,
    decode_onehot_batch,
    maxcut_qubo,
    open_path_qubo,
)

__all__ = ["IsingTour", "TourFailure", "REFINE_RULES", "CLUSTER_DISTANCES", "EXIT_COSTS", "BACKENDS"]

REFINE_RULES = ("largest", "spare_first")
CLUSTER_DISTANCES = ("min", "mean", "medoid")
EXIT_COSTS = ("min", "mean")
BACKENDS = ("logical", "chip")


#: Default options of the logical tabu solver for this layer (see the module docstring).
DEFAULT_SOLVER_OPTIONS = {"max_tenure": 10}


class TourFailure(RuntimeError):
    """Raised internally when a construction subproblem never decodes valid."""


@dataclass
class _Run:
    """Per-solve bookkeeping."""

    rng: np.random.Generator
    stats: dict = field(default_factory=dict)


class IsingTour:
    """Clustered Ising tour construction (see the module docstring).

    Args:
        chip: an :class:`ising_backend.EmulatedChip` (default: a fresh
            ``EmulatedChip(ChipSpec())``); its spec gives the spin budget and
            the accounting numbers; used directly for ``backend="chip"``.
        backend: ``"logical"`` (paper) or ``"chip"`` (quantized physical runs).
        local_limit: largest cluster solved as one local TSP (7).
        max_clusters: ordering limit ``K`` (8).
        refine: which cluster a refinement split takes (``"largest"`` or
            ``"spare_first"``).
        cluster_distance: ``"min"`` (default), ``"mean"`` or ``"medoid"``.
        exit_cost: ``"min"`` or ``"mean"``; ``exit_weight`` scales it.
        patch_size: most targets in a refinement patch (6; at most 7 with
            the default budget and branching).
        patience: consecutive non-improving patches before stopping (``None``:
            number of windows + 1).
        num_reads: reads per program.
        max_retries: re-issues of a program that gave no valid candidate.
        penalty_factor: ``A = penalty_factor * w_max + 1``.
        max_branch_bits: most frozen spins for spin-budget branching (4 -> 16).
        chip_quantize: quantization rule for ``backend="chip"``
            (one of :data:`ising_backend.QUANTIZE_RULES`).
        n_starts: independent constructions, the cheapest final tour kept (4).
        start_patience: stop after this many non-improving starts in a row
            (``None``: run all ``n_starts``).
        accept_equal: also accept equal-cost patch reorders (not the paper's
            rule; default ``False``).
        share_clusters: reuse the first start's clustering in later starts.
        solver_options: keyword options for the default
            :class:`ising_backend.LogicalIsingSolver` (e.g. ``restarts``).
        solver: a ready logical solver (anything with ``solve_many(models,
            num_reads, seed)`` and a ``ledger``), replacing the default.
    """

    name = "ising"

    def __init__(
        self,
        chip=None,
        backend: str = "logical",
        local_limit: int = 7,
        max_clusters: int = 8,
        refine: str = "largest",
        cluster_distance: str = "min",
        exit_cost: str = "min",
        exit_weight: float = 1.0,
        patch_size: int = 6,
        patience: int | None = None,
        num_reads: int = 1,
        max_retries: int = 3,
        penalty_factor: float = 1.0,
        max_branch_bits: int = 4,
        chip_quantize: str = "linear",
        n_starts: int = 4,
        start_patience: int | None = None,
        accept_equal: bool = False,
        share_clusters: bool = False,
        solver_options: dict | None = None,
        solver=None,
    ) -> None:
        if backend not in BACKENDS:
            raise ValueError(f"backend = {backend!r} not in {BACKENDS}")
        if refine not in REFINE_RULES:
            raise ValueError(f"refine = {refine!r} not in {REFINE_RULES}")
        if cluster_distance not in CLUSTER_DISTANCES:
            raise ValueError(f"cluster_distance = {cluster_distance!r} not in {CLUSTER_DISTANCES}")
        if chip_quantize not in QUANTIZE_RULES:
            raise ValueError(f"chip_quantize = {chip_quantize!r} not in {QUANTIZE_RULES}")
        if exit_cost not in EXIT_COSTS:
            raise ValueError(f"exit_cost = {exit_cost!r} not in {EXIT_COSTS}")
        for nm, v, lo in (("local_limit", local_limit, 1), ("max_clusters", max_clusters, 1),
                          ("patch_size", patch_size, 1), ("num_reads", num_reads, 1),
                          ("max_retries", max_retries, 0), ("max_branch_bits", max_branch_bits, 0),
                          ("n_starts", n_starts, 1)):
            if int(v) != v or v < lo:
                raise ValueError(f"{nm} = {v!r} must be an integer >= {lo}")
        if patience is not None and (int(patience) != patience or patience < 0):
            raise ValueError(f"patience = {patience!r} must be None or an integer >= 0")
        if not (penalty_factor >= 1.0 and math.isfinite(penalty_factor)):
            raise ValueError(f"penalty_factor = {penalty_factor!r} must be >= 1 (A > w_max keeps ground states valid)")
        if not (exit_weight >= 0 and math.isfinite(exit_weight)):
            raise ValueError(f"exit_weight = {exit_weight!r} must be >= 0")
        self.backend = backend
        self.local_limit = int(local_limit)
        self.max_clusters = int(max_clusters)
        self.refine = refine
        self.cluster_distance = cluster_distance
        self.exit_cost = exit_cost
        self.exit_weight = float(exit_weight)
        self.patch_size = int(patch_size)
        self.n_starts = int(n_starts)
        self.accept_equal = bool(accept_equal)
        if start_patience is not None and (int(start_patience) != start_patience or start_patience < 1):
            raise ValueError(f"start_patience = {start_patience!r} must be None or an integer >= 1")
        self.start_patience = None if start_patience is None else int(start_patience)
        self.share_clusters = bool(share_clusters)
        self.patience = None if patience is None else int(patience)
        self.num_reads = int(num_reads)
        self.max_retries = int(max_retries)
        self.penalty_factor = float(penalty_factor)
        self.max_branch_bits = int(max_branch_bits)
        self.chip_quantize = chip_quantize
        self.solver_options = {**DEFAULT_SOLVER_OPTIONS, **(solver_options or {})}
        self._chip = chip
        self._init_backend(solver)

    # ------------------------------------------------------------------ backend glue
    def _init_backend(self, solver) -> None:
        if self._chip is None:
            self._chip = EmulatedChip(ChipSpec())
        self.chip = self._chip
        self.spec = self.chip.spec
        self._budget = int(self.spec.n_spins)
        self.solver = solver if solver is not None else LogicalIsingSolver(spec=self.spec, **self.solver_options)
        largest = max(self.local_limit, self.patch_size, self.max_clusters - 1)
        if largest ** 2 > self._budget + self.max_branch_bits:
            raise ValueError(
                f"one-hot models of {largest}^2 = {largest ** 2} variables exceed the spin budget {self._budget} "
                f"+ max_branch_bits {self.max_branch_bits} (local_limit={self.local_limit}, patch_size="
                f"{self.patch_size}, max_clusters={self.max_clusters})")

    def _snapshot(self):
        return self.solver.ledger.snapshot(), self.chip.ledger.snapshot()

    def _since(self, snap):
        return self.solver.ledger.since(snap[0]) + self.chip.ledger.since(snap[1])

    def _sample(self, q, Q, off, run: _Run, onehot: bool) -> np.ndarray:
        """Bits ``(m, n)`` of every read of every branch of one QUBO program issue."""
        model = QuboModel(q, Q, off).to_ising()
        if model.n > self._budget:
            branches = branch(model, self._budget, max_frozen=self.max_branch_bits)
            programs = [b.model for b in branches]
        else:
            branches = None
            programs = [model]
        seed = int(run.rng.integers(0, 2**63 - 1))
        if self.backend == "logical":
            spins = [r.spins for r in self.solver.solve_many(programs, num_reads=self.num_reads, seed=seed)]
            physical = False
        else:
            hr, jr = self.spec.h_range, self.spec.j_range
            progs = [quantize(m, self.chip_quantize, hr, jr) for m in programs]
            spins = [sp for sp, _e in self.chip.anneal_models(progs, num_reads=self.num_reads, seed=seed)]
            physical = True
        if branches is not None:
            spins = [b.decode(sp) for b, sp in zip(branches, spins)]
        per_program = [((np.asarray(sp, dtype=np.int8) + 1) // 2).reshape(-1, model.n) for sp in spins]
        if onehot:
            s = int(round(math.sqrt(model.n)))
            m = run.stats["mapping"]["tour"]
            any_valid = False
            for bits in per_program:
                _o, valid = decode_onehot_batch(bits, s)
                m["programs"] += 1
                m["reads"] += int(valid.size)
                m["valid_reads"] += int(valid.sum())
                if valid.any():
                    m["valid"] += 1
                    any_valid = True
                if physical:
                    m["physical_programs"] += 1
                    m["valid_physical"] += int(valid.any())
            m["subproblems"] += 1
            m["valid_subproblems"] += int(any_valid)
        return np.concatenate(per_program, axis=0)

    # ------------------------------------------------------------------ public
    def solve(self, dist: np.ndarray, rng: np.random.Generator | None = None) -> TourResult:
        """Order nodes ``1..n`` of ``dist`` into an open route from node 0."""
        dist = np.asarray(dist, dtype=np.float64)
        if dist.ndim != 2 or dist.shape[0] != dist.shape[1] or dist.shape[0] < 1:
            raise ValueError(f"dist must be a square (n+1, n+1) matrix, got shape {dist.shape}")
        if np.any(np.isnan(dist)) or np.any(dist < 0):
            raise ValueError("dist must hold non-negative distances (no NaN)")
        rng = np.random.default_rng() if rng is None else rng
        n = dist.shape[0] - 1
        run = _Run(rng=rng, stats=self._empty_stats())
        snap = self._snapshot()
        if not np.all(np.isfinite(dist)):
            bad = np.argwhere(~np.isfinite(dist))[0]
            return self._result(run, snap, None, dist,
                                f"distance {tuple(int(v) for v in bad)} is infinite: targets on different components")
        if n == 0:
            return self._result(run, snap, (), dist)
        best, best_cost, failure = None, math.inf, None
        clusters = None
        starts = 1 if n <= self.patch_size else self.n_starts
        stale = 0  # consecutive starts that did not improve the best tour
        for _start in range(starts):
            if self.start_patience is not None and stale >= self.start_patience:
                break
            try:
                if clusters is None or not self.share_clusters:
                    clusters = self._cluster(dist, run)
                ordered = self._order_clusters(dist, clusters, run)
                tour = self._local_tours(dist, ordered, run)
                tour = self._refine(dist, tour, run)
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
            return self._result(run, snap, None, dist, failure)
        return self._result(run, snap, tuple(int(t) for t in best), dist)

    # ------------------------------------------------------------------ 1. clustering
    def _cluster(self, dist: np.ndarray, run: _Run) -> list[list[int]]:
        n = dist.shape[0] - 1
        clusters: list[list[int]] = [list(range(1, n + 1))]
        # split every cluster above the local limit (largest first, ties by index)
        while True:
            big = [k for k, c in enumerate(clusters) if len(c) > self.local_limit]
            if not big:
                break
            k = max(big, key=lambda j: (len(clusters[j]), -j))
            clusters[k:k + 1] = self._split(dist, clusters[k], run)
        # refinement up to the ordering limit
        while len(clusters) < self.max_clusters:
            sizes = np.array([len(c) for c in clusters])
            if sizes.max() < 2:
                break
            if self.refine == "spare_first" and len(clusters) > 1:
                near = int(np.argmin([dist[0, c].min() for c in clusters]))
                others = sizes.copy()
                others[near] = 0
                k = int(np.argmax(others)) if others.max() >= 2 else near
            else:
                k = int(np.argmax(sizes))  # largest, ties by lowest index
            clusters[k:k + 1] = self._split(dist, clusters[k], run)
            run.stats["refinement_splits"] += 1
        run.stats["clusters"] = [len(c) for c in clusters]
        return clusters

    def _split(self, dist: np.ndarray, members: list[int], run: _Run) -> list[list[int]]:
        """Max-cut split (eq. 7) of ``members`` by the Ising solver."""
        run.stats["splits"] += 1
        s = len(members)
        if s == 2:  # the only non-degenerate cut: no decision to make
            return [[members[0]], [members[1]]]
        limit = self._budget + self.max_branch_bits
        drawn = np.asarray(members)
        if s > limit:
            drawn = np.sort(run.rng.choice(drawn, size=self._budget, replace=False))
        w = dist[np.ix_(drawn, drawn)]
        q, Q, off = maxcut_qubo(w)
        for _attempt in range(self.max_retries + 1):
            bits = self._sample(q, Q, off, run, onehot=False)
            sizes = bits.sum(axis=1)
            ok = (sizes > 0) & (sizes < len(drawn))
            if np.any(ok):
                cand = bits[ok]
                cuts = cut_value(w, cand)
                x = cand[int(np.argmax(cuts))]
                break
        else:
            raise TourFailure(f"max-cut split of {s} targets gave only degenerate samples "
                              f"after {self.max_retries + 1} attempts")
        side = {int(t): int(b) for t, b in zip(drawn, x)}
        if s > limit:  # undrawn members join the side of their nearest drawn member
            for t in members:
                if t not in side:
                    near = drawn[int(np.argmin(dist[t, drawn]))]
                    side[t] = side[int(near)]
        a = [t for t in members if side[t] == 0]
        b = [t for t in members if side[t] == 1]
        return [a, b]

    # ------------------------------------------------------------------ 2. cluster order
    def _cluster_dist(self, dist: np.ndarray, clusters: list[list[int]]) -> np.ndarray:
        K = len(clusters)
        D = np.zeros((K, K))
        if self.cluster_distance == "medoid":
            med = []
            for c in clusters:
                sub = dist[np.ix_(c, c)]
                med.append(c[int(np.argmin(sub.sum(axis=1)))])
        for a in range(K):
            for b in range(K):
                if a == b:
                    continue
                if self.cluster_distance == "medoid":
                    D[a, b] = dist[med[a], med[b]]
                else:
                    block = dist[np.ix_(clusters[a], clusters[b])]
                    D[a, b] = block.min() if self.cluster_distance == "min" else block.mean()
        return D

    def _order_clusters(self, dist: np.ndarray, clusters: list[list[int]], run: _Run) -> list[list[int]]:
        K = len(clusters)
        to_robot = np.array([dist[0, c].min() for c in clusters])
        first = int(np.argmin(to_robot))  # ties by lowest index
        rest = [k for k in range(K) if k != first]
        if len(rest) <= 1:
            return [clusters[first]] + [clusters[k] for k in rest]
        D = self._cluster_dist(dist, clusters)
        order = self._order_items(D, rest, first, run)
        return [clusters[first]] + [clusters[k] for k in order]

    def _order_items(self, D: np.ndarray, items: list[int], prev: int, run: _Run) -> list[int]:
        """Open path over cluster indices ``items`` entered from cluster ``prev``.

        Up to ``max_clusters - 1`` items: one one-hot ordering model.  More
        (only when the clusters of at most ``local_limit`` targets number more
        than ``max_clusters``): hierarchical -- a max-cut split of the items on
        ``D``, the part nearer to ``prev`` first (the paper's nearest-first
        rule one level up), each part ordered recursively.
        """
        if len(items) <= 1:
            return list(items)
        if len(items) <= self.max_clusters - 1:
            d = D[np.ix_(items, items)]
            entry = D[prev, items]
            order = self._solve_path(d, entry, np.zeros(len(items)), run, "ordering")
            if order is None:
                raise TourFailure(f"cluster ordering ({len(items)}^2 = {len(items) ** 2} variables) gave no valid "
                                  f"permutation after {self.max_retries + 1} attempts")
            return [items[i] for i in order]
        run.stats["ordering_splits"] += 1
        a, b = self._split(D, list(items), run)
        if D[prev, b].min() < D[prev, a].min():
            a, b = b, a
        left = self._order_items(D, a, prev, run)
        return left + self._order_items(D, b, left[-1], run)

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
                    ex = block.min(axis=1) if self.exit_cost == "min" else block.mean(axis=1)
                    ex = self.exit_weight * ex
                else:
                    ex = np.zeros(len(c))
                order = self._solve_path(d, entry, ex, run, "local")
                if order is None:
                    raise TourFailure(f"local TSP of cluster {k} ({len(c)} targets) gave no valid permutation "
                                      f"after {self.max_retries + 1} attempts")
                local = [int(c[i]) for i in order]
            tour.extend(local)
            prev = local[-1]
        return tour

    # ------------------------------------------------------------------ 4. patch refinement
    def _refine(self, dist: np.ndarray, tour: list[int], run: _Run) -> list[int]:
        n = len(tour)
        L = min(self.patch_size, n)
        if L < 2:
            return tour
        n_windows = n - L + 1
        patience = n_windows + 1 if self.patience is None else self.patience
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
            order = self._solve_path(d, entry, ex, run, "patch")
            if order is not None:
                new = tour[:a] + [int(patch[i]) for i in order] + tour[a + L:]
                new_cost = _tour_cost(dist, new)
                if new_cost < cost - 1e-9:
                    tour, cost = new, new_cost
                    fails = 0
                    run.stats["patches_accepted"] += 1
                    continue
                if self.accept_equal and new_cost <= cost + 1e-9 and new != tour:
                    tour = new  # sideways move on a cost plateau; still a non-improving attempt
                    run.stats["patches_sideways"] += 1
            fails += 1
        return tour

    # ------------------------------------------------------------------ one-hot programs
    def _solve_path(self, d, entry, ex, run: _Run, kind: str):
        """Best valid order of an open-path one-hot QUBO, or ``None`` after retries."""
        s = d.shape[0]
        q, Q, off, _A = open_path_qubo(d, entry, ex, B=1.0, margin_factor=self.penalty_factor)
        for _attempt in range(self.max_retries + 1):
            bits = self._sample(q, Q, off, run, onehot=True)
            orders, valid = decode_onehot_batch(bits, s)
            if np.any(valid):
                cand = orders[valid]
                costs = entry[cand[:, 0]] + ex[cand[:, -1]] + d[cand[:, :-1], cand[:, 1:]].sum(axis=1)
                return [int(i) for i in cand[int(np.argmin(costs))]]
            run.stats["retries"] += 1
        run.stats["unsolved"][kind] += 1
        return None

    # ------------------------------------------------------------------ result
    def _empty_stats(self) -> dict:
        return {
            "backend": self.backend,
            "clusters": [],
            "start_costs": [],
            "failed_starts": 0,
            "splits": 0,
            "refinement_splits": 0,
            "ordering_splits": 0,
            "patches": 0,
            "patches_accepted": 0,
            "patches_sideways": 0,
            "retries": 0,
            "unsolved": {"ordering": 0, "local": 0, "patch": 0},
            "mapping": {"tour": {"programs": 0, "valid": 0, "physical_programs": 0, "valid_physical": 0,
                                 "reads": 0, "valid_reads": 0, "subproblems": 0, "valid_subproblems": 0}},
        }

    def _result(self, run: _Run, snap, order, dist, failure: str | None = None) -> TourResult:
        led = self._since(snap)
        compute = ComputeReport.from_ledger(led)
        if failure is not None:
            run.stats["failure"] = failure
            return TourResult(order=(), cost=math.inf, compute=compute, stats=run.stats, failure=failure)
        return TourResult(order=tuple(order), cost=_tour_cost(dist, list(order)), compute=compute, stats=run.stats)


def _tour_cost(dist: np.ndarray, tour: list[int]) -> float:
    if not tour:
        return 0.0
    nodes = np.asarray([0] + list(tour))
    return float(dist[nodes[:-1], nodes[1:]].sum())
