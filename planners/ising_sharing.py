"""Recursive Ising target sharing (paper section 5.3, Algorithm 3).

Robots and targets are the nodes of a complete graph whose edge weights are
the obstacle-aware BFS distances (``world.distance_matrix``).  Starting from
one group holding every node, groups are split in two by maximising the
distance-weighted cut of eq. (8),

    cut(x) = sum_{i<j} w_ij (x_i + x_j - 2 x_i x_j),

i.e. the chip minimises the QUBO ``E(x) = -cut(x)``.  Groups with more than
one robot are split first (one *stage* per round: every group that needs a
split in that round is split at once), until every group holds at most one
robot.  Then optional *refinement* stages split large groups further; the
robot's side of a refined one-robot group stays that robot's base set and
every robotless side becomes a *bundle*.  Finally each bundle goes to the
robot whose tour cost (by the downstream ``tour`` solver handed to
:meth:`IsingSharing.assign`) grows least -- classically, as in the paper.

Per split (the paper's anchored split):

* **anchors** -- two nodes fixed to opposite sides: the farthest robot pair
  (group with several robots), that robot and the target farthest from it
  (one robot), the farthest target pair (no robot).  Ties go to the lowest
  node index.  The anchors are *substituted* into the QUBO (not penalised):
  anchor ``a`` is fixed to side 0 (x=0) and anchor ``b`` to side 1 (x=1), so
  a group of ``m`` nodes has ``m - 2`` free spins, and every spin assignment
  is a partition with both anchors on different sides.
* **mapping** -- the reduced QUBO is converted exactly to Ising form
  (``x = (1 + s) / 2``) and quantized to the chip's integer range by each of
  the four rules of :data:`ising_backend.QUANTIZE_RULES` (linear, clip95,
  rank, sqrt): one chip program per rule.
* **batching** -- the splits of one stage are independent; for each rule
  they are packed block-diagonally (:func:`ising_backend.pack_blocks`, zero
  cross-block couplings) into as few programs of at most ``chip.spec.n_spins``
  spins as first-fit packing allows, and all programs of the stage (every
  rule) go to the emulated physical chip in ONE ``anneal_batch`` submission.
  With 3 robots x 10 targets every stage fits one 45-spin program per rule,
  so a stage costs 4 chip calls.
* **decode, validate, score** -- each returned spin block is decoded into a
  partition, checked, and scored on the *unquantized* cut; the best valid
  candidate over all rules and reads wins (ties: first rule in
  ``rules`` order).

Choices the paper leaves open (each a constructor parameter):

``balance`` (default 0.0)
    weight of an optional balance term added to the split QUBO of
    multi-robot groups: ``balance * mean_w * (R*T1 - N*R1)^2 / R^2``
    (``T1``/``R1`` targets/robots on side 1 of a group with ``N`` targets
    and ``R`` robots) -- it asks each side for targets in proportion to its
    robots.  0 keeps the paper's pure eq. (8).  It is still an Ising term:
    the chip, not the host, finds the balanced split.
``refine_stages`` (default 3) and ``refine_above`` (default 2)
    number of refinement stages after the robot splits, and the size rule:
    in each refinement stage every group (robot base or bundle) holding more
    than ``refine_above`` targets is split.  The paper reports a median of
    20 chip calls in 5 batches for 3 robots x 10 targets: 2 robot stages +
    3 refinement stages of 4 rule programs each, which these defaults
    reproduce.  ``refine_stages=0`` disables refinement (pure recursive
    split; each one-robot group is then that robot's set).
``bundle_order`` (default ``"far_first"``)
    order in which bundles are assigned (each to the robot whose tour cost
    grows least given the bundles already placed): ``"far_first"`` (bundle
    whose nearest robot is farthest first), ``"near_first"``,
    ``"largest_first"``, ``"creation"`` (order the splits made them).
``reads`` (default 1)
    chip reads per mapped program (each read is one physical call).
``rules`` (default all four quantization rules).

Validity rule.  A candidate is *invalid* (rejected, counted in
``stats["mapping"]["sharing"][rule]["candidates"]`` but not ``valid``) if
its spin block is not a vector of +-1 values of the right length (a broken
or garbage chip), or -- only for ``reject_empty_robot_side=True`` (default
False) -- if in a multi-robot split one side gets robots but no target.  The
default accepts such a side because a min-sum optimum may leave a robot idle.
Because the anchors are substituted, both sides are never empty.  If every
candidate of some split is invalid the split is retried up to ``retries``
times (new chip submission, counted); after that :meth:`assign` returns a
failure result (``stats["failure"]`` names the split; ``assignment`` is all
empty) instead of inventing a split.

Size limit.  The free spins of one split are ``group size - 2``.  A group
with more free spins than the chip has spins cannot be mapped without a
decomposition the paper does not describe, so :meth:`assign` refuses it
with a failure result naming the size and the limit (with the default
45-spin chip: at most 47 robots + targets in the root group).  Splits of
one stage whose total exceeds the chip size are spread over several
programs (first-fit, in group order).

Accounting: ``compute`` carries the chip ledger of the sharing calls plus
the compute reports of every downstream tour solve used for bundle pricing
(e.g. projected logical calls of an Ising tour solver), so nothing is
hidden.  ``stats`` holds ``"mapping"`` (counts per rule: candidates, valid,
wins), ``"stages"``, ``"splits"``, ``"bundles"`` and ``"tour_solves"``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planners.base import SharingResult, TourSolver
from planners.compute import ComputeReport

__all__ = [
    "IsingSharing",
    "SplitProblem",
    "build_split_qubo",
    "choose_anchors",
    "cut_value",
    "decode_split",
    "BUNDLE_ORDERS",
]

BUNDLE_ORDERS = ("far_first", "near_first", "largest_first", "creation")


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
    best: tuple | None = None  # (cut, side0, side1, rule)
    retries: int = 0


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
        chip: an :class:`ising_backend.EmulatedChip` (default: a fresh one
            with the paper's ``ChipSpec()``).
        rules: quantization rules used as the mapping portfolio.
        reads: chip reads per mapped program.
        refine_stages: refinement stages after the robot splits (0 = none).
        refine_above: in a refinement stage, groups with more targets than
            this are split.
        balance: weight of the optional balance term of multi-robot splits.
        bundle_order: see :data:`BUNDLE_ORDERS`.
        reject_empty_robot_side: validity rule variant (module docstring).
        retries: chip re-submissions of a split whose candidates were all invalid.
    """

    name = "ising"

    def __init__(
        self,
        chip=None,
        rules=None,
        reads: int = 1,
        refine_stages: int = 3,
        refine_above: int = 2,
        balance: float = 0.0,
        bundle_order: str = "far_first",
        reject_empty_robot_side: bool = False,
        retries: int = 2,
        weight_power: float = 1.0,
        robot_weight: float = 1.0,
        weight_shift: float = 0.0,
    ) -> None:
        from ising_backend import QUANTIZE_RULES

        if chip is None:
            from ising_backend import ChipSpec, EmulatedChip

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
        for name, v in (("weight_power", weight_power), ("robot_weight", robot_weight)):
            if not np.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a finite number > 0, got {v}")
        self.weight_power = float(weight_power)
        self.robot_weight = float(robot_weight)
        if not np.isfinite(weight_shift):
            raise ValueError(f"weight_shift must be finite, got {weight_shift}")
        self.weight_shift = float(weight_shift)

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
        stats: dict = {"mapping": {"sharing": mapping}, "stages": 0, "splits": 0, "bundles": 0, "tour_solves": 0}
        empty = tuple(() for _ in range(R))
        if not np.all(np.isfinite(dist)):
            i, j = np.argwhere(~np.isfinite(dist))[0]
            stats["failure"] = f"node {i} cannot reach node {j} (distance {dist[i, j]}); sharing needs one connected component"
            return SharingResult(assignment=empty, compute=ComputeReport(), stats=stats)
        if N == 0:
            return SharingResult(assignment=empty, compute=ComputeReport(), stats=stats)
        if R == 1:
            return SharingResult(assignment=(tuple(range(N)),), compute=ComputeReport(), stats=stats)

        snap = self.chip.ledger.snapshot()
        tour_compute = [ComputeReport()]
        try:
            groups = self._split_all(self.split_weights(dist, R), R, rng, stats)
            assignment = self._assign_bundles(dist, R, groups, tour, tour_compute, stats, rng)
        except SharingFailure as exc:
            stats["failure"] = str(exc)
            return SharingResult(assignment=empty, compute=self._compute(snap) + tour_compute[0], stats=stats)
        return SharingResult(assignment=assignment, compute=self._compute(snap) + tour_compute[0], stats=stats)

    def split_weights(self, dist: np.ndarray, R: int) -> np.ndarray:
        """Edge weights ``w_ij`` of the split graph: ``dist ** weight_power``,
        with robot-target edges multiplied by ``robot_weight``."""
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
        return ComputeReport(
            chip_calls=int(d.physical_calls),
            chip_batches=int(d.batches),
            logical_calls=int(d.logical_calls),
            chip_time_s=float(d.chip_time_s),
            chip_time_parallel_s=float(d.chip_time_parallel_s),
            accelerator_energy_j=float(d.energy_j),
        )

    def _problem(self, dist, R, nodes, kind) -> SplitProblem:
        a, b = choose_anchors(dist, nodes, R)
        free = np.array([n for n in nodes if n != a and n != b], dtype=int)
        limit = int(self.chip.spec.n_spins)
        if len(free) > limit:
            raise SharingFailure(
                f"a group of {len(nodes)} nodes needs {len(free)} free spins after anchor substitution; "
                f"the chip has {limit} spins (at most {limit + 2} robots + targets per group)"
            )
        q, Q, offset = build_split_qubo(dist, free, a, b, R, self.balance if kind == "robots" else 0.0)
        return SplitProblem(nodes=np.asarray(nodes, dtype=int), a=a, b=b, free=free, q=q, Q=Q, offset=offset, kind=kind)

    def _split_all(self, dist, R, rng, stats) -> list[np.ndarray]:
        groups: list[np.ndarray] = [np.arange(dist.shape[0])]
        # robot stages: split every group holding more than one robot
        while True:
            todo = [i for i, g in enumerate(groups) if int((g < R).sum()) >= 2]
            if not todo:
                break
            groups = self._stage(dist, R, groups, todo, "robots", rng, stats)
        for _ in range(self.refine_stages):
            todo = [i for i, g in enumerate(groups) if int((g >= R).sum()) > self.refine_above]
            if not todo:
                break
            groups = self._stage(dist, R, groups, todo, "refine", rng, stats)
        return groups

    def _stage(self, dist, R, groups, todo, kind, rng, stats) -> list[np.ndarray]:
        problems = [self._problem(dist, R, groups[i], kind) for i in todo]
        stats["stages"] += 1
        stats["splits"] += len(problems)
        pending = [p for p in problems if len(p.free) > 0]
        for p in problems:
            if len(p.free) == 0:  # one partition only: nothing to solve
                side0, side1 = decode_split(p, np.zeros(0, dtype=np.int8))
                p.best = (cut_value(dist, side0, side1), side0, side1, None)
        attempts = 0
        while pending:
            self._solve(dist, R, pending, rng, stats)
            failed = [p for p in pending if p.best is None]
            if failed and attempts >= self.retries:
                p = failed[0]
                raise SharingFailure(
                    f"every chip candidate for the split of group {p.nodes.tolist()} was invalid "
                    f"after {attempts + 1} submissions"
                )
            attempts += 1
            pending = failed
        new_groups: list[np.ndarray] = []
        by_index = dict(zip(todo, problems))
        for i, g in enumerate(groups):
            if i in by_index:
                _, side0, side1, _ = by_index[i].best
                new_groups.extend([side0, side1])
            else:
                new_groups.append(g)
        return new_groups

    def _valid(self, R, side0, side1, kind) -> bool:
        if self.reject_empty_robot_side and kind == "robots":
            for side in (side0, side1):
                if (side < R).any() and not (side >= R).any():
                    return False
        return True

    def _solve(self, dist, R, problems, rng, stats) -> None:
        """One chip submission for all mapped programs of ``problems``."""
        from ising_backend import QuboModel, pack_blocks, quantize, unpack_blocks

        spec = self.chip.spec
        capacity = int(spec.n_spins)
        # first-fit packing of the splits into programs (same for every rule)
        bins: list[list[int]] = []
        loads: list[int] = []
        for k, p in enumerate(problems):
            size = len(p.free)
            for bi in range(len(bins)):
                if loads[bi] + size <= capacity:
                    bins[bi].append(k)
                    loads[bi] += size
                    break
            else:
                bins.append([k])
                loads.append(size)
        ising = [QuboModel(p.q, p.Q, p.offset).to_ising() for p in problems]
        programs = []  # (rule, bin index, slices)
        hs, Js = [], []
        for rule in self.rules:
            quantized = [quantize(m, rule, spec.h_range, spec.j_range) for m in ising]
            for bi, members in enumerate(bins):
                packed, slices = pack_blocks([quantized[k] for k in members])
                programs.append((rule, bi, slices))
                hs.append(np.asarray(packed.h))
                Js.append(np.asarray(packed.J))
        n = max(len(h) for h in hs)
        H = np.zeros((len(hs), n))
        J = np.zeros((len(hs), n, n))
        for k, (h, j) in enumerate(zip(hs, Js)):
            H[k, : len(h)] = h
            J[k, : len(h), : len(h)] = j
        seed = int(rng.integers(2**31 - 1))
        spins, _ = self.chip.anneal_batch(H, J, num_reads=self.reads, seed=seed)
        spins = np.asarray(spins)
        # candidates per problem: (cut, side0, side1, rule)
        cands: list[list] = [[] for _ in problems]
        mapping = stats["mapping"]["sharing"]
        for k, (rule, bi, slices) in enumerate(programs):
            members = bins[bi]
            size = loads[bi]
            for r in range(spins.shape[1]):
                blocks = unpack_blocks(spins[k, r, :size], slices)
                for pk, block in zip(members, blocks):
                    p = problems[pk]
                    mapping[rule]["candidates"] += 1
                    dec = decode_split(p, block)
                    if dec is None or not self._valid(R, dec[0], dec[1], p.kind):
                        continue
                    mapping[rule]["valid"] += 1
                    cands[pk].append((cut_value(dist, dec[0], dec[1]), dec[0], dec[1], rule))
        for p, cs in zip(problems, cands):
            if not cs:
                continue
            best = max(c[0] for c in cs)
            top = [c for c in cs if c[0] >= best - 1e-9]
            pick = top[int(rng.integers(len(top)))] if len(top) > 1 else top[0]
            p.best = pick
            mapping[pick[3]]["wins"] += 1

    def _assign_bundles(self, dist, R, groups, tour, tour_compute, stats, rng):
        base: list[list[int]] = [[] for _ in range(R)]
        bundles: list[np.ndarray] = []
        for g in groups:
            robots = g[g < R]
            targets = [int(t) for t in g[g >= R]]
            if len(robots) == 1:
                base[int(robots[0])].extend(targets)
            elif len(robots) == 0:
                if targets:
                    bundles.append(np.asarray(targets, dtype=int))
            else:  # cannot happen: robot stages run until <= 1 robot per group
                raise SharingFailure(f"group {g.tolist()} still holds {len(robots)} robots")
        stats["bundles"] = len(bundles)
        cache: dict = {}

        def cost(k: int, targets) -> float:
            key = (k, frozenset(targets))
            if key not in cache:
                if not targets:
                    cache[key] = 0.0
                else:
                    nodes = [k] + sorted(targets)
                    res = tour.solve(dist[np.ix_(nodes, nodes)], rng)
                    tour_compute[0] = tour_compute[0] + res.compute
                    stats["tour_solves"] += 1
                    cache[key] = float(res.cost)
            return cache[key]

        if bundles:
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
                b = [int(t) for t in bundles[i]]
                inc = [cost(k, current[k] + b) - cost(k, current[k]) for k in range(R)]
                k = int(np.argmin(inc))
                current[k].extend(b)
            base = current
        return tuple(tuple(sorted(t - R for t in ts)) for ts in base)
