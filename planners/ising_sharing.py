"""Recursive Ising target sharing (paper section 5.3, Algorithm 3).

Robots and targets are the nodes of a complete graph whose edge weights are
the obstacle-aware BFS distances (``world.distance_matrix``).  Starting from
one group holding every node, groups are split in two by maximising the
distance-weighted cut of eq. (8),

    cut(x) = sum_{i<j} w_ij (x_i + x_j - 2 x_i x_j),

i.e. the chip minimises the QUBO ``E(x) = -cut(x)``.  Groups with more than
one robot are split first (one *stage* per round: every group that needs a
split in that round is split at once), until every group holds at most one
robot.  Then *refinement* stages split groups further; the robot's side of a
refined one-robot group stays that robot's base set and every robotless side
becomes a *bundle*.  Finally each bundle goes to the robot whose route cost
grows least -- classically, as in the paper -- priced by ``pricing_tour``
(default: exact Held-Karp on the host for sets of up to 13 targets, the
downstream ``tour`` handed to :meth:`IsingSharing.assign` beyond; the paper's
literal "downstream tour solver" is ``pricing_tour="downstream"``).  No auction, no local search:
the host only decomposes, decodes, scores and prices whole bundles.

Per split (the paper's anchored split):

* **anchors** -- two nodes fixed to opposite sides: the farthest robot pair
  (group with several robots), that robot and the target farthest from it
  (one robot), the farthest target pair (no robot).  Ties go to the lowest
  node indices.  The anchors are *substituted* into the QUBO (not
  penalised): anchor ``a`` is fixed to side 0 (x=0) and ``b`` to side 1
  (x=1), so a group of ``m`` nodes has ``m - 2`` free spins and every spin
  assignment is a partition with the anchors on different sides.  A split
  with no free spin (a group of two nodes) has one partition and needs no
  chip call.
* **mapping** -- the reduced QUBO is converted exactly to Ising form
  (``x = (1 + s) / 2``) and quantized to the chip's integer range by each of
  the four rules of :data:`ising_backend.QUANTIZE_RULES` (linear, clip95,
  rank, sqrt): one mapped program per (split, rule).
* **batching** -- the mapped programs of one stage are independent, so
  :func:`ising_backend.run_portfolio_batch` (``pack=True``) places them on
  disjoint blocks of as few 45-spin chip programs as first-fit decreasing
  packing finds (zero cross-block couplings, :func:`ising_backend.plan_packs`)
  and sends the whole stage to the emulated physical chip in ONE
  ``anneal_batch`` submission.  Unlike the paper (one program per rule, 4
  calls per stage) the rules of a split share programs too, so 3 robots x 10
  targets need about one program per stage (x ``reads`` calls; median 12
  calls in 4 batches per instance with the defaults, the paper 20 / 5).  A
  stage whose blocks exceed 45 spins simply uses several programs.
* **decode, validate, score** -- each returned spin block is decoded into a
  partition, checked, and scored on the *unquantized* eq. (8) cut (with the
  weights below); the best valid candidate over all rules and reads wins.
  Win counts per rule: ties between rules (several rules finding the same
  best cut) are broken uniformly at random with the ``rng`` of
  :meth:`~IsingSharing.assign`, so integer counts stay unbiased.

Candidate beam (our addition; ``beam=1`` is the paper's greedy recursion).
The portfolio returns several distinct valid partitions per split (the four
rules x ``reads`` quantize the cut differently; about 2-3 distinct ones per
robot split).  The robot stages keep the ``beam`` best of them by
unquantized cut (refinement stages the ``refine_beam`` best) and expand
every partial solution by them (at most ``max_states`` partial solutions,
ranked by the sum of their chosen cuts); in each complete candidate the
bundles are placed, and the one
with the lowest total route cost (priced as above) -- the sharing layer's
original objective -- is returned.  This is candidate
*selection* (decode-filter-score one level up), not repair: every group
boundary still comes from a chip split.  The refinement stages of all
partial solutions share their chip submissions.

Choices the paper leaves open (each a constructor parameter), tuned on
centre-placement worlds (3 robots x 10 targets, exact tours); figures are
mean total route cost over worlds 0..999 (SSA 28.65, exact optimum 27.97,
median 28 for SSA, exact and these defaults; defaults 28.31-28.32 depending on the annealer build):

``beam`` (3), ``refine_beam`` (2), ``max_states`` (9), ``reads`` (2)
    ``beam`` / ``refine_beam`` candidates are kept per robot / refinement
    split.  Beam 1 / reads 1: 29.11 (the paper's recursion with our
    weights); beam 3 / reads 1: 28.50; beam 3 / reads 2: 28.38; + refine
    beam 2: 28.32 (the defaults: median 12 chip calls in 4 batches and ~43
    pricing tour solves per instance); beam 4 / reads 4 / 16 states: 28.28
    (~36 calls).  A group met again (in another partial solution) reuses its
    solved split.
``weight_shift`` (default 0.5)
    the split weights are ``w_ij = d_ij ** weight_power - weight_shift *
    mean``, ``mean`` the mean pairwise ``d ** weight_power`` of the whole
    instance.  Pure distances (shift 0, the paper's literal eq. 8) make
    max-cut favour equal-size sides, while min-sum routes favour uneven
    ones (one robot often serves a long chain); subtracting a constant
    charges every cut edge, so unbalanced splits of clustered targets win.
    Measured (beam 1, worlds 0..99): mean 29.6 with 0, 29.1 with 0.5;
    with the default beam 0.25 / 0.5 / 0.75 give 28.43 / 28.37 / 28.39.
``weight_power`` (1.0), ``robot_weight`` (1.0: factor on robot-target edges)
    other weight shapes tried, no better than the defaults.
``balance`` (0.0)
    weight of an optional balance term added to multi-robot splits:
    ``balance * mean_w * (R*T1 - N*R1)^2 / R^2`` (``T1``/``R1`` targets and
    robots on side 1 of a group with ``N`` targets and ``R`` robots) --
    targets in proportion to robots.  It is still an Ising term (the chip
    finds the balanced split).  Off by default: min-sum routes do not want
    balance.
``base_max`` (default 0), ``refine_above`` (default 3), ``refine_stages`` (8)
    refinement rule: a one-robot group is split while it holds more than
    ``base_max`` targets, a robotless bundle while it holds more than
    ``refine_above``; at most ``refine_stages`` stages (a cap; refinement
    stops as soon as nothing qualifies).  ``base_max=0`` peels every target
    off the robots, so each robot's final set is built only from chip-made
    bundles (robot-anchored splits peel the far side off first); bundles of
    at most 3 targets keep the chip's clusters intact (bundles of 1 would
    turn the last step into plain greedy insertion).  With these defaults
    3 x 10 takes a median of 5 stages (2 robot + 3 refinement; the paper's 5
    batches).  ``refine_stages=0`` gives the unrefined recursive split.
``bundle_order`` (default ``"creation"``)
    order in which bundles are placed, each on the robot whose tour cost
    grows least given the bundles already placed: ``"creation"`` (the order
    of the split tree, side 0 before side 1), ``"far_first"`` (bundle whose
    nearest robot is farthest first), ``"near_first"``, ``"largest_first"``.
    ``far_first`` measured 28.74 against ``creation``'s 28.37 (beam 3).
``rules`` (default all four quantization rules).
``pricing_tour`` (default ``"auto"``)
    what prices bundles (and complete candidates).  The paper says "the
    downstream tour solver"; its end-to-end figures count only 20 sharing
    chip calls, so its pricing was not charged to the accelerator.  Priced
    by the clustered Ising tour downstream, 3 x 10 costs a median of ~240
    projected logical calls and ~0.2 s of host time per instance -- 4x the
    accelerator energy of the whole rest of the Ising pipeline -- for the
    same allocation quality as exact pricing.  So ``"auto"`` prices exactly
    (Held-Karp, :class:`~planners.tours_classical.BruteTour`, on the host,
    its time counted in the layer's ``cpu_s``) when the robot's set has at
    most 13 targets, and with the downstream tour otherwise;
    ``"downstream"`` is the paper's literal rule.  Pricing never reorders
    the downstream tours: the tour layer still builds every route.

Validity rule.  A candidate is *invalid* (counted in
``stats["mapping"]["sharing"][rule]["candidates"]`` but not in ``valid``)
if its spin block is not a vector of +-1 of the right length (a broken or
garbage chip), or -- only with ``reject_empty_robot_side=True`` (default
False) -- if in a multi-robot split a side gets robots but no target.  The
default accepts that side because a min-sum optimum may leave a robot idle.
Both sides are never empty (the anchors are substituted).  If every
candidate of a split is invalid the stage's failed splits are re-submitted
up to ``retries`` times (counted); after that :meth:`assign` returns a
failure result (``stats["failure"]`` says which split; ``assignment`` all
empty) instead of inventing a split.

Size limit.  A split has ``group size - 2`` free spins.  A split with more
free spins than the chip has uses the backend's spin-budget branching
(:class:`ising_backend.BranchMapping`, as the paper does for tours): the
``k`` excess spins are frozen and all ``2^k`` reduced programs of every rule
are solved, the best decoded candidate winning as usual.  ``k`` is capped by
``max_frozen`` (default 4: the paper's 49-variable / 16-branch case); a
larger group is refused with a failure result naming the size and the limit
(default chip: at most 51 robots + targets in the root group).

Accounting.  ``compute`` carries the chip ledger of the sharing calls plus
the compute reports of every tour solve used for bundle pricing (e.g.
projected logical calls of an Ising tour solver with ``"downstream"``), so
nothing is hidden; the chip is charged around this planner's own submissions only, so
a chip shared with other layers is not double counted.  A chip that refuses
a mapped program (``ChipProgramError``) ends in a failure result.
``stats`` holds ``"mapping"`` (per rule: candidates, valid, wins),
``"stages"``, ``"splits"``, ``"trivial_splits"`` (no free spin, no chip
call), ``"states"`` (complete candidates compared), ``"bundles"`` (summed
over those candidates) and ``"tour_solves"``.  A failure is reported in both
``failure`` and ``stats["failure"]``.
One robot, or no target, needs no split and no chip call.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ising_backend import (
    QUANTIZE_RULES,
    BranchMapping,
    ChipProgramError,
    ChipSpec,
    EmulatedChip,
    QuantizeMapping,
    QuboModel,
    run_portfolio_batch,
)
from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport
from planners.tours_classical import MAX_BRUTE_TARGETS, BruteTour

__all__ = [
    "IsingSharing",
    "SplitProblem",
    "build_split_qubo",
    "choose_anchors",
    "cut_value",
    "decode_split",
    "BUNDLE_ORDERS",
]

BUNDLE_ORDERS = ("creation", "far_first", "near_first", "largest_first")


# --------------------------------------------------------------------------
# Pure formulation: anchors, QUBO, decode, score
# --------------------------------------------------------------------------


def choose_anchors(dist: np.ndarray, nodes, n_robots: int) -> tuple[int, int]:
    """The two anchors of a split of ``nodes`` (global indices; robots are
    ``0..n_robots-1``): farthest robot pair / robot + farthest target /
    farthest target pair.  Ties go to the lexicographically smallest pair.
    Returns ``(a, b)`` with ``a`` fixed to side 0 and ``b`` to side 1."""
    nodes = np.asarray(nodes, dtype=int)
    robots = nodes[nodes < n_robots]
    targets = nodes[nodes >= n_robots]
    if len(nodes) < 2:
        raise ValueError(f"a split needs at least 2 nodes, got {len(nodes)}")
    if len(robots) >= 2:
        pool_a, pool_b = robots, robots
    elif len(robots) == 1:
        if len(targets) == 0:
            raise ValueError("a one-robot group without targets cannot be split")
        r = int(robots[0])
        d = dist[r, targets]
        return r, int(targets[int(np.argmax(d))])
    else:
        pool_a, pool_b = targets, targets
    sub = dist[np.ix_(pool_a, pool_b)]
    iu = np.triu_indices(len(pool_a), k=1)
    k = int(np.argmax(sub[iu]))
    return int(pool_a[iu[0][k]]), int(pool_b[iu[1][k]])


def _robot_target_weights(nodes: np.ndarray, n_robots: int) -> np.ndarray:
    return nodes < n_robots


def build_split_qubo(
    dist: np.ndarray,
    free,
    a: int,
    b: int,
    n_robots: int,
    balance: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, float]:
    """The reduced QUBO ``E(x) = -cut(x) [+ balance term]`` over the free nodes.

    Anchor ``a`` is substituted as ``x_a = 0`` and ``b`` as ``x_b = 1``.
    Returns ``(q, Q, offset)`` with ``Q`` strictly upper triangular so that
    ``E(x) = offset + q @ x + x @ Q @ x`` for ``x`` in {0,1}^F equals
    ``-cut`` of the full partition (plus the balance term when ``balance``
    is non-zero and the group has several robots).
    """
    free = np.asarray(free, dtype=int)
    f = len(free)
    w = np.asarray(dist, dtype=float)[np.ix_(free, free)]
    np.fill_diagonal(w, 0.0)
    wa = np.asarray(dist, dtype=float)[free, a]
    wb = np.asarray(dist, dtype=float)[free, b]
    # -cut over free pairs: -w_ij (x_i + x_j) + 2 w_ij x_i x_j
    q = -w.sum(axis=1) - wa + wb
    Q = np.triu(2.0 * w, k=1)
    offset = -float(dist[a, b]) - float(wb.sum())
    if balance:
        nodes = np.concatenate([free, [a, b]])
        is_robot = nodes < n_robots
        R = int(is_robot.sum())
        N = len(nodes) - R
        if R >= 2:
            # penalty lam * (R*T1 - N*R1)^2 / R^2 with c_i = R (target) or -N (robot)
            allw = np.asarray(dist, dtype=float)[np.ix_(nodes, nodes)]
            mean_w = float(allw[np.triu_indices(len(nodes), 1)].mean()) if len(nodes) > 1 else 1.0
            lam = balance * mean_w / R**2
            c = np.where(free < n_robots, -float(N), float(R))
            c0 = -float(N) if b < n_robots else float(R)  # x_b = 1 contributes
            # (c0 + c.x)^2 = c0^2 + sum (c_i^2 + 2 c0 c_i) x_i + sum_{i<j} 2 c_i c_j x_i x_j
            q = q + lam * (c**2 + 2.0 * c0 * c)
            Q = Q + lam * np.triu(2.0 * np.outer(c, c), k=1)
            offset += lam * c0**2
    return q, Q, offset


def cut_value(dist: np.ndarray, side0, side1) -> float:
    """The unquantized eq. (8) objective: total weight of edges across the cut."""
    side0 = np.asarray(side0, dtype=int)
    side1 = np.asarray(side1, dtype=int)
    if len(side0) == 0 or len(side1) == 0:
        return 0.0
    return float(np.asarray(dist, dtype=float)[np.ix_(side0, side1)].sum())


@dataclass
class SplitProblem:
    """One anchored split of a group (global node indices)."""

    nodes: np.ndarray
    a: int
    b: int
    free: np.ndarray
    q: np.ndarray
    Q: np.ndarray
    offset: float
    kind: str  # "robots" | "refine"
    cands: list = field(default_factory=list)  # distinct valid (cut, side0, side1, _), best first


def decode_split(problem: SplitProblem, spins) -> tuple[np.ndarray, np.ndarray] | None:
    """Spins (+-1, one per free node) -> ``(side0, side1)`` global node arrays,
    or ``None`` if the spin block is malformed (wrong length, not +-1)."""
    s = np.asarray(spins)
    if s.shape != (len(problem.free),):
        return None
    if not np.all((s == 1) | (s == -1)):
        return None
    x = s > 0
    side1 = np.concatenate([[problem.b], problem.free[x]]).astype(int)
    side0 = np.concatenate([[problem.a], problem.free[~x]]).astype(int)
    return np.sort(side0), np.sort(side1)


# --------------------------------------------------------------------------
# The planner
# --------------------------------------------------------------------------


class SharingFailure(RuntimeError):
    """Internal: a split could not be mapped or solved (becomes a failure result)."""


class IsingSharing:
    """Recursive Ising target sharing on the emulated physical chip (module docstring).

    Args:
        chip: an :class:`ising_backend.EmulatedChip` or anything with its
            ``spec``, ``ledger`` and ``anneal_batch`` (default: a fresh
            ``EmulatedChip(ChipSpec())``).
        rules: quantization rules used as the mapping portfolio (default all four).
        reads: chip reads per program.
        beam: distinct chip candidates kept per robot split (1 = paper's greedy recursion).
        refine_beam: distinct chip candidates kept per refinement split.
        max_states: cap on candidate partial solutions carried along.
        weight_shift, weight_power, robot_weight: split weights (module docstring).
        balance: weight of the optional balance term of multi-robot splits.
        refine_stages: cap on refinement stages after the robot splits (0 = none).
        refine_above: a robotless bundle with more targets than this is split.
        base_max: a one-robot group with more targets than this is split
            (``None``: same as ``refine_above``).
        bundle_order: see :data:`BUNDLE_ORDERS`.
        pricing_tour: what prices bundles and complete candidates: ``"auto"``
            (default: exact Held-Karp on the host up to 13 targets, else the
            downstream tour), ``"downstream"`` (or ``None``: the ``tour`` given
            to :meth:`assign`), a tour registry name or a :class:`TourSolver`.
        reject_empty_robot_side: validity rule variant (module docstring).
        retries: re-submissions of splits whose candidates were all invalid.
        max_frozen: spins a too-large split may freeze (spin-budget branching, 2^k programs).
    """

    name = "ising"

    def __init__(
        self,
        chip=None,
        *,
        rules=None,
        reads: int = 2,
        beam: int = 3,
        refine_beam: int = 2,
        max_states: int = 9,
        weight_shift: float = 0.5,
        weight_power: float = 1.0,
        robot_weight: float = 1.0,
        balance: float = 0.0,
        refine_stages: int = 8,
        refine_above: int = 3,
        base_max: int | None = 0,
        bundle_order: str = "creation",
        pricing_tour="auto",
        reject_empty_robot_side: bool = False,
        retries: int = 2,
        max_frozen: int = 4,
    ) -> None:
        if chip is None:
            chip = EmulatedChip(ChipSpec())
        self.chip = chip
        rules = tuple(QUANTIZE_RULES if rules is None else rules)
        if not rules:
            raise ValueError("rules must name at least one quantization rule")
        for r in rules:
            if r not in QUANTIZE_RULES:
                raise ValueError(f"unknown quantization rule {r!r}; expected one of {QUANTIZE_RULES}")
        self.rules = rules
        if int(reads) < 1:
            raise ValueError(f"reads must be >= 1, got {reads}")
        self.reads = int(reads)
        if int(refine_stages) < 0:
            raise ValueError(f"refine_stages must be >= 0, got {refine_stages}")
        self.refine_stages = int(refine_stages)
        if int(refine_above) < 1:
            raise ValueError(f"refine_above must be >= 1, got {refine_above}")
        self.refine_above = int(refine_above)
        self.base_max = self.refine_above if base_max is None else int(base_max)
        if self.base_max < 0:
            raise ValueError(f"base_max must be >= 0, got {base_max}")
        if not np.isfinite(balance) or balance < 0:
            raise ValueError(f"balance must be a finite number >= 0, got {balance}")
        self.balance = float(balance)
        if bundle_order not in BUNDLE_ORDERS:
            raise ValueError(f"unknown bundle_order {bundle_order!r}; expected one of {BUNDLE_ORDERS}")
        self.bundle_order = bundle_order
        self.reject_empty_robot_side = bool(reject_empty_robot_side)
        if int(retries) < 0:
            raise ValueError(f"retries must be >= 0, got {retries}")
        self.retries = int(retries)
        if int(beam) < 1:
            raise ValueError(f"beam must be >= 1, got {beam}")
        self.beam = int(beam)
        if int(refine_beam) < 1:
            raise ValueError(f"refine_beam must be >= 1, got {refine_beam}")
        self.refine_beam = int(refine_beam)
        if int(max_states) < 1:
            raise ValueError(f"max_states must be >= 1, got {max_states}")
        self.max_states = int(max_states)
        if not 0 <= int(max_frozen) <= 10:
            raise ValueError(f"max_frozen must be in 0..10 (2^max_frozen branches), got {max_frozen}")
        self.max_frozen = int(max_frozen)
        if pricing_tour is None:
            pricing_tour = "downstream"
        if isinstance(pricing_tour, str) and pricing_tour not in ("auto", "downstream"):
            from planners import registry

            pricing_tour = registry.create("tour", pricing_tour)
        if not isinstance(pricing_tour, str) and not callable(getattr(pricing_tour, "solve", None)):
            raise ValueError(
                f"pricing_tour must be 'auto', 'downstream', a tour name or a TourSolver, got {pricing_tour!r}"
            )
        self.pricing_tour = pricing_tour
        for name, v in (("weight_power", weight_power), ("robot_weight", robot_weight)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a finite number > 0, got {v}")
        self.weight_power = float(weight_power)
        self.robot_weight = float(robot_weight)
        if not np.isfinite(weight_shift):
            raise ValueError(f"weight_shift must be finite, got {weight_shift}")
        self.weight_shift = float(weight_shift)

    def __repr__(self) -> str:
        return (
            f"IsingSharing(rules={self.rules}, reads={self.reads}, beam={self.beam}, "
            f"refine_beam={self.refine_beam}, max_states={self.max_states}, weight_shift={self.weight_shift}, "
            f"refine_stages={self.refine_stages}, refine_above={self.refine_above}, base_max={self.base_max}, "
            f"bundle_order={self.bundle_order!r}, pricing_tour={self.pricing_tour!r})"
        )

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
        mapping = {r: {"candidates": 0, "valid": 0, "wins": 0} for r in self.rules}
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
            i, j = np.argwhere(~np.isfinite(dist))[0]
            msg = f"node {i} cannot reach node {j} (distance {dist[i, j]}); sharing needs one connected component"
            stats["failure"] = msg
            return SharingResult(assignment=empty, compute=ComputeReport(), stats=stats, failure=msg)
        if N == 0:
            return SharingResult(assignment=empty, compute=ComputeReport(), stats=stats)
        if R == 1:
            return SharingResult(assignment=(tuple(range(N)),), compute=ComputeReport(), stats=stats)

        self._chip_compute = ComputeReport()  # charged around our own submissions only
        tour_compute = [ComputeReport()]
        cache: dict = {}
        if self.pricing_tour == "auto":
            exact = BruteTour()
            pricer = lambda n: exact if n <= MAX_BRUTE_TARGETS else tour  # noqa: E731
        elif self.pricing_tour == "downstream":
            pricer = lambda n: tour  # noqa: E731
        else:
            pricer = lambda n: self.pricing_tour  # noqa: E731

        def cost(k: int, targets) -> float:
            """Route cost of robot ``k`` over global target nodes ``targets`` (pricing tour, cached)."""
            key = (k, frozenset(targets))
            if key not in cache:
                if not targets:
                    cache[key] = 0.0
                else:
                    nodes = [k] + sorted(targets)
                    res = pricer(len(targets)).solve(dist[np.ix_(nodes, nodes)], rng)
                    tour_compute[0] = tour_compute[0] + res.compute
                    stats["tour_solves"] += 1
                    if getattr(res, "failure", None):
                        raise SharingFailure(f"tour solver failed while pricing a bundle: {res.failure}")
                    cache[key] = float(res.cost)
            return cache[key]

        self._memo: dict = {}
        try:
            states = self._split_all(self.split_weights(dist, R), R, rng, stats)
            best = None
            for groups in states:
                sets = self._assign_bundles(dist, R, groups, cost, stats)
                if len(states) == 1:
                    best = (0.0, sets)
                    break
                total = sum(cost(k, sets[k]) for k in range(R))
                if best is None or total < best[0] - 1e-9:  # ties: the state with the larger cuts
                    best = (total, sets)
            assignment = tuple(tuple(sorted(t - R for t in ts)) for ts in best[1])
            self._memo = {}
        except SharingFailure as exc:
            self._memo = {}
            stats["failure"] = str(exc)
            return SharingResult(
                assignment=empty, compute=self._chip_compute + tour_compute[0], stats=stats, failure=str(exc)
            )
        return SharingResult(assignment=assignment, compute=self._chip_compute + tour_compute[0], stats=stats)

    def split_weights(self, dist: np.ndarray, R: int) -> np.ndarray:
        """Edge weights ``w_ij`` of the split graph: ``dist ** weight_power`` minus
        ``weight_shift`` x its mean over node pairs, robot-target edges then
        multiplied by ``robot_weight`` (zero diagonal)."""
        w = np.asarray(dist, dtype=float) ** self.weight_power
        if self.weight_shift:
            n = w.shape[0]
            mean = float(w[np.triu_indices(n, 1)].mean()) if n > 1 else 0.0
            w = w - self.weight_shift * mean
            np.fill_diagonal(w, 0.0)
        if self.robot_weight != 1.0:
            w = w.copy()
            w[:R, R:] *= self.robot_weight
            w[R:, :R] *= self.robot_weight
        return w

    # -------------------------------------------------------------- helpers

    def _compute(self, snap) -> ComputeReport:
        d = self.chip.ledger.since(snap)
        return ComputeReport.from_ledger(d)

    def _problem(self, dist, R, nodes, kind) -> SplitProblem:
        a, b = choose_anchors(dist, nodes, R)
        free = np.array([n for n in nodes if n != a and n != b], dtype=int)
        limit = int(self.chip.spec.n_spins) + self.max_frozen
        if len(free) > limit:
            raise SharingFailure(
                f"a group of {len(nodes)} nodes needs {len(free)} free spins after anchor substitution; "
                f"the chip has {self.chip.spec.n_spins} spins and spin-budget branching freezes at most "
                f"max_frozen = {self.max_frozen} (at most {limit + 2} robots + targets per group)"
            )
        q, Q, offset = build_split_qubo(dist, free, a, b, R, self.balance if kind == "robots" else 0.0)
        return SplitProblem(nodes=np.asarray(nodes, dtype=int), a=a, b=b, free=free, q=q, Q=Q, offset=offset, kind=kind)

    def _split_all(self, w, R, rng, stats) -> list[list[np.ndarray]]:
        """All candidate partial solutions (lists of groups) after the split stages.

        Robot (refinement) stages keep up to ``beam`` (``refine_beam``)
        distinct valid chip candidates per split (best unquantized cuts
        first) and expand every state by them (at most ``max_states``
        states, ranked by the sum of their chosen cuts).  Every stage is one
        chip submission for the splits of all states.
        """
        states: list[tuple[float, list[np.ndarray]]] = [(0.0, [np.arange(w.shape[0])])]
        while True:  # robot stages: split every group holding more than one robot
            todo = [(si, gi) for si, (_, st) in enumerate(states) for gi, g in enumerate(st) if int((g < R).sum()) >= 2]
            if not todo:
                break
            problems = self._stage(w, R, [states[si][1][gi] for si, gi in todo], "robots", rng, stats)
            states = self._expand(states, todo, problems, self.beam)
        for _ in range(self.refine_stages):
            todo = [
                (si, gi)
                for si, (_, st) in enumerate(states)
                for gi, g in enumerate(st)
                if int((g >= R).sum()) > (self.base_max if (g < R).any() else self.refine_above)
            ]
            if not todo:
                break
            problems = self._stage(w, R, [states[si][1][gi] for si, gi in todo], "refine", rng, stats)
            states = self._expand(states, todo, problems, self.refine_beam)
        stats["states"] += len(states)
        return [st for _, st in states]

    def _expand(self, states, todo, problems, width: int):
        """Replace the split groups of every state by up to ``width`` candidate splits each
        (a beam over the state's splits, then over all states: at most ``max_states``)."""
        expanded: list[tuple[float, list[np.ndarray]]] = []
        for si, (score, st) in enumerate(states):
            mine = {gi: p for (sj, gi), p in zip(todo, problems) if sj == si}
            if not mine:
                expanded.append((score, st))
                continue
            keys = sorted(mine)
            combos: list[tuple[float, tuple]] = [(0.0, ())]
            for gi in keys:
                combos = [(sc + c[0], combo + (c,)) for sc, combo in combos for c in mine[gi].cands[:width]]
                order = sorted(range(len(combos)), key=lambda i: (-combos[i][0], i))
                combos = [combos[i] for i in order[: self.max_states]]
            for _, combo in combos:
                chosen = dict(zip(keys, combo))
                groups: list[np.ndarray] = []
                for gi, g in enumerate(st):
                    if gi in chosen:
                        groups.extend([chosen[gi][1], chosen[gi][2]])
                    else:
                        groups.append(g)
                expanded.append((score + sum(c[0] for c in combo), groups))
        order = sorted(range(len(expanded)), key=lambda i: (-expanded[i][0], i))
        return [expanded[i] for i in order[: self.max_states]]

    def _stage(self, w, R, groups, kind, rng, stats) -> list[SplitProblem]:
        """Solve the splits of ``groups`` (one chip submission, plus retries); each problem's
        ``cands`` lists its distinct valid candidates, best unquantized cut first.

        The same group met again (in another partial solution, or an earlier
        stage) reuses its solved split from ``self._memo`` instead of a new chip call.
        """
        memo = self._memo
        keys = [(kind, tuple(int(v) for v in np.sort(g))) for g in groups]
        fresh: dict = {}
        for key, g in zip(keys, groups):
            if key not in memo and key not in fresh:
                fresh[key] = self._problem(w, R, g, kind)
        stats["stages"] += 1
        stats["splits"] += len(fresh)
        pending = []
        for p in fresh.values():
            if len(p.free) == 0:  # one partition only: nothing to solve
                stats["trivial_splits"] += 1
                side0, side1 = decode_split(p, np.zeros(0, dtype=np.int8))
                p.cands = [(cut_value(w, side0, side1), side0, side1, None)]
            else:
                pending.append(p)
        attempts = 0
        while pending:
            self._solve(w, R, pending, rng, stats)
            failed = [p for p in pending if not p.cands]
            if failed and attempts >= self.retries:
                p = failed[0]
                raise SharingFailure(
                    f"every chip candidate for the split of group {p.nodes.tolist()} was invalid "
                    f"after {attempts + 1} submissions"
                )
            attempts += 1
            pending = failed
        memo.update(fresh)
        return [memo[key] for key in keys]

    def _valid(self, R, side0, side1, kind) -> bool:
        if self.reject_empty_robot_side and kind == "robots":
            for side in (side0, side1):
                if (side < R).any() and not (side >= R).any():
                    return False
        return True

    def _solve(self, dist, R, problems, rng, stats) -> None:
        """One chip submission for every mapped program of ``problems``.

        Each split's reduced QUBO is converted to Ising form and mapped by
        every quantization rule; :func:`ising_backend.run_portfolio_batch`
        block-packs all programs of the stage into as few chip programs as fit
        (first-fit decreasing, ``pack=True``), dispatches them in one
        ``anneal_batch``, decodes, filters and scores each split's candidates
        on the unquantized cut (objective ``-cut``: lower is better).
        """
        models = [QuboModel(p.q, p.Q, p.offset).to_ising() for p in problems]
        if max(len(p.free) for p in problems) > self.chip.spec.n_spins:
            # spin-budget branching: freeze the excess spins, 2^k reduced programs per rule
            mappings = [BranchMapping(None, QuantizeMapping(rule), name=rule) for rule in self.rules]
        else:
            mappings = [QuantizeMapping(rule) for rule in self.rules]

        def decoder(p):
            return lambda spins: decode_split(p, spins)

        found: list[dict] = [{} for _ in problems]  # distinct valid partitions per split

        def validator(k, p):
            def check(cand) -> bool:
                ok = self._valid(R, cand[0], cand[1], p.kind)
                if ok:
                    found[k].setdefault(cand[1].tobytes(), cand)
                return ok

            return check

        def objective(cand):
            return -cut_value(dist, cand[0], cand[1])

        snap = self.chip.ledger.snapshot()
        try:
            results = run_portfolio_batch(
                models,
                mappings,
                self.chip,
                decode=[decoder(p) for p in problems],
                is_valid=[validator(k, p) for k, p in enumerate(problems)],
                objective=objective,
                num_reads=self.reads,
                seed=int(rng.integers(2**63 - 1)),
                pack=True,
            )
        except ChipProgramError as exc:  # a mapped program the chip cannot take: a clear failure
            self._chip_compute = self._chip_compute + self._compute(snap)
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        # only this submission: a chip shared with other layers (or with a tour
        # solver used for pricing, whose own report is added separately) is not double counted
        self._chip_compute = self._chip_compute + self._compute(snap)
        mapping = stats["mapping"]["sharing"]
        for k, (p, res) in enumerate(zip(problems, results)):
            for rule in self.rules:
                out = res.outcomes[rule]
                mapping[rule]["candidates"] += int(out.reads)
                mapping[rule]["valid"] += int(out.valid)
            if res.best is None:
                continue
            winners = [rule for rule in self.rules if res.outcomes[rule].win > 0]
            # ties between rules (common: several rules find the same split) are
            # broken at random so integer win counts stay unbiased
            win = winners[int(rng.integers(len(winners)))] if len(winners) > 1 else winners[0]
            mapping[win]["wins"] += 1
            cands = [(cut_value(dist, c[0], c[1]), c[0], c[1], None) for c in found[k].values()]
            order = sorted(range(len(cands)), key=lambda i: (-cands[i][0], i))
            p.cands = [cands[i] for i in order]

    def _assign_bundles(self, dist, R, groups, cost, stats) -> list[list[int]]:
        """Robot base sets plus every bundle placed on the robot whose route cost
        (``cost(k, targets)``, the downstream tour) grows least.  Global node indices."""
        base: list[list[int]] = [[] for _ in range(R)]
        bundles: list[list[int]] = []
        for g in groups:
            robots = g[g < R]
            targets = [int(t) for t in g[g >= R]]
            if len(robots) == 1:
                base[int(robots[0])].extend(targets)
            elif len(robots) == 0:
                if targets:
                    bundles.append(targets)
            else:  # cannot happen: robot stages run until <= 1 robot per group
                raise SharingFailure(f"group {g.tolist()} still holds {len(robots)} robots")
        stats["bundles"] += len(bundles)
        if not bundles:
            return base
        robots = np.arange(R)
        near = [float(dist[np.ix_(robots, b)].min()) for b in bundles]
        if self.bundle_order == "far_first":
            order = sorted(range(len(bundles)), key=lambda i: (-near[i], i))
        elif self.bundle_order == "near_first":
            order = sorted(range(len(bundles)), key=lambda i: (near[i], i))
        elif self.bundle_order == "largest_first":
            order = sorted(range(len(bundles)), key=lambda i: (-len(bundles[i]), i))
        else:
            order = list(range(len(bundles)))
        current = [list(b) for b in base]
        for i in order:
            b = bundles[i]
            inc = [cost(k, current[k] + b) - cost(k, current[k]) for k in range(R)]
            k = int(np.argmin(inc))
            current[k].extend(b)
        return current
