"""The Python search of Ising target sharing (paper 5.3): the oracle of the package's sharing.

``reference_assign(sharing, dist, R, tour, rng)`` makes, step by step in plain Python and numpy, the
decisions :meth:`planners.ising.sharing.IsingSharing.assign` makes over compiled steps on node-set
ids (``stages``, ``stage_steps``, ``clusters``, ``placement``, ``refine``): the anchored split QUBO, the
split stages with their memo and beam, coarse splits of groups beyond the chip, spin-budget
branches, bundle placement, the choice of state and the boundary refinement, with the same chip
submissions (``stage_steps.submit_stage``), charges and rng draws.  Test code only: the package never
imports it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ising_backend import ChipProgramError, ChipUnavailableError, MeteredSolver, SolverOutputError
from planners.base import SharingResult
from planners.compute import ComputeReport
from planners.ising.sharing.bundles import BundlePricer, SharingFailure
from planners.ising.sharing.search import failed
from planners.ising.sharing.split_problem import SplitProblems, branch_problems, split_model
from ising_backend import STACK_OK
from planners.ising.sharing.stage_steps import submit_stage
from planners.ising.sharing.submission import StageSolver, stage_refusal

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


def farthest_point_clusters(w: np.ndarray, k: int) -> np.ndarray:
    """Labels ``0..k-1`` of the ``n`` points of the symmetric weight (distance-like) matrix ``w``."""
    n = w.shape[0]
    if k >= n:
        return np.arange(n, dtype=np.int64)
    centres = [int(np.argmax(w.sum(axis=1)))]
    nearest = w[centres[0]].copy()
    for _ in range(1, k):
        nxt = int(np.argmax(nearest))
        centres.append(nxt)
        nearest = np.minimum(nearest, w[nxt])
    return np.argmin(w[np.ix_(np.arange(n), centres)], axis=1).astype(np.int64)


def _clusters(w: np.ndarray, nodes: np.ndarray, k: int) -> list[np.ndarray]:
    sub = np.asarray(w, dtype=float)[np.ix_(nodes, nodes)]
    if len(nodes) > 1:
        low = sub[~np.eye(len(nodes), dtype=bool)].min()
        if low < 0:  # shifted split weights: back to a distance-like matrix (same order), zero diagonal
            sub = sub - low
            np.fill_diagonal(sub, 0.0)
    labels = farthest_point_clusters(sub, k)
    return [np.sort(nodes[labels == c]) for c in range(int(labels.max()) + 1) if (labels == c).any()]


def coarsen(w: np.ndarray, group: np.ndarray, n_robots: int, n_clusters: int, robot_clusters: int | None = None):
    """``(members, wc)``: the coarse nodes of ``group`` (robots first -- one each, or
    ``robot_clusters`` clusters of neighbouring robots --, then target clusters; arrays of global
    node indices) and their summed weight matrix (zero diagonal)."""
    group = np.asarray(group, dtype=np.int64)
    robots = group[group < n_robots]
    targets = group[group >= n_robots]
    if robot_clusters is None:
        members = [np.array([r], dtype=np.int64) for r in robots]
    else:
        members = _clusters(w, robots, robot_clusters)
    members += _clusters(w, targets, n_clusters)
    w = np.asarray(w, dtype=float)
    wc = np.zeros((len(members), len(members)))
    for a, ma in enumerate(members):
        for b, mb in enumerate(members):
            if a != b:
                wc[a, b] = w[np.ix_(ma, mb)].sum()
    return members, wc


def expand_sides(members, side0, side1) -> tuple[np.ndarray, np.ndarray]:
    """Coarse sides (coarse node indices) -> the fine sides (sorted global node indices)."""
    def grow(side):
        parts = [members[int(i)] for i in side]
        return np.sort(np.concatenate(parts)) if parts else np.zeros(0, dtype=np.int64)
    return grow(side0), grow(side1)


@dataclass
class CoarseSplit:
    """A split solved on target clusters: its group and its expanded candidates, best cut first."""

    nodes: np.ndarray
    cands: list = field(default_factory=list)




def coarse_split(splits, w, R, g, kind, rng, stats) -> CoarseSplit:
    """The split of a group too large for the chip, solved on target clusters by ``splits`` (a
    :class:`~.splits.SplitSearch`): as many clusters as fit the chip without branching."""
    g = np.asarray(g, dtype=np.int64)
    n_spins = int(splits.chip.spec.n_spins)
    robots = int((g < R).sum())
    robot_clusters = None
    if n_spins + 2 - robots < max(1, n_spins // 2):
        # more robots than leave half the chip to target clusters: neighbouring robots are
        # clustered too (each side of the coarse split keeps whole robot clusters; the fine
        # groups below split them on the chip as usual)
        robot_clusters = max(2, (n_spins + 2) // 2)
        if robots < 2 or n_spins + 2 - robot_clusters < 1:
            raise SharingFailure(
                f"a group of {robots} robots and {len(g) - robots} targets cannot be coarsened onto the "
                f"chip: its split needs at least {robot_clusters - 1} free spins, the chip has {n_spins}")
    n_coarse_robots = robots if robot_clusters is None else min(robots, robot_clusters)
    n_clusters = n_spins + 2 - n_coarse_robots
    members, wc = coarsen(w, g, R, n_clusters, robot_clusters)
    robots = sum(1 for m in members if m[0] < R)  # coarse robot nodes (robot clusters keep robots only)
    outer, splits.memo = splits.memo, {}  # coarse node indices must not meet the fine memo
    try:
        (problem,) = splits.stage(wc, robots, [np.arange(len(members), dtype=np.int64)], kind, rng, stats)
    finally:
        splits.memo = outer
    cands = []
    for _cut, side0, side1, _ in problem.cands:
        f0, f1 = expand_sides(members, side0, side1)
        cands.append((cut_value(w, f0, f1), f0, f1, None))
    cands.sort(key=lambda c: -c[0])
    stats["coarse_splits"] = stats.get("coarse_splits", 0) + 1
    return CoarseSplit(nodes=g, cands=cands)


class SplitSearch:
    """The split stages on one chip (module docstring)."""

    def __init__(self, config, chip, stages):
        self.config = config
        self.chip = chip
        self.stages = stages
        self.memo: dict = {}

    def problem(self, dist, R, nodes, kind) -> SplitProblem:
        nodes = np.asarray(nodes, dtype=np.int64)
        balance = self.config.balance if kind == "robots" else 0.0
        if len(nodes) < 2 or balance:
            a, b = choose_anchors(dist, nodes, R)  # the reference (and its errors), and the balance term
            free = np.array([n for n in nodes if n != a and n != b], dtype=np.int64)
            q, Q, offset = None, None, None
        else:
            a, b, free, q, Q, offset = split_model(dist, nodes, R)
            a, b = int(a), int(b)
        limit = int(self.chip.spec.n_spins) + self.config.max_frozen
        if len(free) > limit:
            raise SharingFailure(
                f"a group of {len(nodes)} nodes needs {len(free)} free spins after anchor substitution; "
                f"the chip has {self.chip.spec.n_spins} spins and spin-budget branching freezes at most "
                f"max_frozen = {self.config.max_frozen} (at most {limit + 2} robots + targets per group)"
            )
        if q is None:
            q, Q, offset = build_split_qubo(dist, free, a, b, R, balance)
        return SplitProblem(nodes=nodes, a=a, b=b, free=free, q=q, Q=Q, offset=float(offset), kind=kind)

    def split_all(self, w, R, rng, stats) -> list[list[np.ndarray]]:
        """All candidate partial solutions (lists of groups) after the split stages.

        Robot (refinement) stages keep up to ``beam`` (``refine_beam``)
        distinct valid chip candidates per split (best unquantized cuts
        first) and expand every state by them (at most ``max_states``
        states, ranked by the sum of their chosen cuts).  Every stage is one
        chip submission for the splits of all states.
        """
        states: list[tuple[float, list[np.ndarray]]] = [(0.0, [np.arange(w.shape[0])])]
        while True:  # robot stages: split every group holding more than one robot
            # groups are sorted node arrays: robots (nodes < R) come first
            todo = [(si, gi) for si, (_, st) in enumerate(states) for gi, g in enumerate(st) if g.searchsorted(R) >= 2]
            if not todo:
                break
            problems = self.stage(w, R, [states[si][1][gi] for si, gi in todo], "robots", rng, stats)
            states = self.expand(states, todo, problems, self.config.beam)
        for _ in range(self.config.refine_stages):
            base_max, above = self.config.resolved_base_max, self.config.refine_above
            todo = []
            for si, (_, st) in enumerate(states):
                for gi, g in enumerate(st):
                    nr = g.searchsorted(R)
                    if len(g) - nr > (base_max if nr else above):
                        todo.append((si, gi))
            if not todo:
                break
            problems = self.stage(w, R, [states[si][1][gi] for si, gi in todo], "refine", rng, stats)
            states = self.expand(states, todo, problems, self.config.refine_beam)
        stats["states"] += len(states)
        return [st for _, st in states]

    def expand(self, states, todo, problems, width: int):
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
                combos = [combos[i] for i in order[: self.config.max_states]]
            for sc, combo in combos:  # sc: the combo's cuts summed left to right
                chosen = dict(zip(keys, combo))
                groups: list[np.ndarray] = []
                for gi, g in enumerate(st):
                    if gi in chosen:
                        groups.extend([chosen[gi][1], chosen[gi][2]])
                    else:
                        groups.append(g)
                expanded.append((score + sc, groups))
        order = sorted(range(len(expanded)), key=lambda i: (-expanded[i][0], i))
        return [expanded[i] for i in order[: self.config.max_states]]

    def stage(self, w, R, groups, kind, rng, stats) -> list[SplitProblem]:
        """Solve the splits of ``groups`` (one chip submission, plus retries); each problem's
        ``cands`` lists its distinct valid candidates, best unquantized cut first.

        The same group met again (in another partial solution, or an earlier
        stage) reuses its solved split from ``self.memo`` instead of a new chip call.
        """
        memo = self.memo
        keys = [(kind, tuple(int(v) for v in np.sort(g))) for g in groups]
        fresh: dict = {}
        for key, g in zip(keys, groups):
            if key not in memo and key not in fresh:
                too_big = len(g) - 2 > int(self.chip.spec.n_spins) + self.config.max_frozen
                fresh[key] = coarse_split(self, w, R, g, kind, rng, stats) if too_big else self.problem(w, R, g, kind)
        stats["stages"] += 1
        stats["splits"] += len(fresh)
        pending = []
        for p in fresh.values():
            if isinstance(p, CoarseSplit):  # solved on its clusters already
                continue
            if len(p.free) == 0:  # one partition only: nothing to solve
                stats["trivial_splits"] += 1
                side0, side1 = decode_split(p, np.zeros(0, dtype=np.int8))
                p.cands = [(cut_value(w, side0, side1), side0, side1, None)]
            else:
                pending.append(p)
        self.stages.solve_all(w, R, pending, rng, stats)
        memo.update(fresh)
        return [memo[key] for key in keys]


def neighbour_pairs(dist: np.ndarray, sets, R: int, per_robot: int) -> list[tuple[int, int]]:
    """Pairs ``(k, l)``, ``k < l``: each robot with its ``per_robot`` nearest robots, the distance
    between two robots being the least distance between their nodes (robot and targets)."""
    if R < 2:
        return []
    if per_robot >= R - 1:
        return [(k, l) for k in range(R) for l in range(k + 1, R)]
    nodes = [np.array([k] + list(s), dtype=np.int64) for k, s in enumerate(sets)]
    gap = np.full((R, R), np.inf)
    for k in range(R):
        block = dist[nodes[k]]
        for l in range(k + 1, R):
            gap[k, l] = gap[l, k] = float(block[:, nodes[l]].min())
    pairs = set()
    for k in range(R):
        for l in np.argsort(gap[k], kind="stable")[:per_robot].tolist():
            if l != k and np.isfinite(gap[k, l]):
                pairs.add((min(k, l), max(k, l)))
    return sorted(pairs)


def refine_boundaries(splits, weights_of, dist, R, sets, cost, rng, stats) -> list[list[int]]:
    """``sets`` (global target nodes per robot) after up to ``pair_rounds`` rounds of pair re-splits,
    solved by ``splits`` (a :class:`~.splits.SplitSearch`) on the split weights ``weights_of(shift)``."""
    cfg = splits.config
    sets = [sorted(s) for s in sets]
    weights = [weights_of(s) for s in cfg.pair_shifts]
    limit = int(splits.chip.spec.n_spins) + cfg.max_frozen
    tried: set = set()
    for _ in range(cfg.pair_rounds):
        pairs = []
        for k, l in neighbour_pairs(dist, sets, R, cfg.pair_neighbours):
            key = (k, l, tuple(sets[k]), tuple(sets[l]))
            if (sets[k] or sets[l]) and key not in tried:  # a pair seen unchanged has nothing new
                tried.add(key)
                pairs.append((k, l))
        if not pairs:
            break
        groups = [np.array(sorted([k, l] + sets[k] + sets[l]), dtype=np.int64) for k, l in pairs]
        problems = []  # (pair index, problem)
        for j, g in enumerate(groups):
            for w in weights:
                if len(g) - 2 > limit:
                    problems.append((j, coarse_split(splits, w, R, g, "pair", rng, stats)))
                elif len(g) > 2:
                    problems.append((j, splits.problem(w, R, g, "pair")))
        pending = [p for _, p in problems if not isinstance(p, CoarseSplit)]
        if pending:  # one submission; candidates ordered by the first shift's cut (the route cost decides)
            stats["splits"] += len(pending)
            splits.stages.solve_all(weights[0], R, pending, rng, stats)
        stats["pair_resplits"] = stats.get("pair_resplits", 0) + len(pairs)
        gains = []
        for j, (k, l) in enumerate(pairs):
            old = cost(k, sets[k]) + cost(l, sets[l])
            best = None
            seen: set = set()
            for i, p in problems:
                if i != j:
                    continue
                for _cut, side0, side1, _ in p.cands:
                    key = side1.tobytes()
                    if key in seen:  # several shifts often propose the same partition
                        continue
                    seen.add(key)
                    # each side holds one of the two robots, its smallest node (robots come first)
                    mine, theirs = (side0, side1) if side0[0] == k else (side1, side0)
                    tk = mine[1:].tolist()
                    tl = theirs[1:].tolist()
                    new = cost(k, tk) + cost(l, tl)
                    if new < old - 1e-9 and (best is None or new < best[0] - 1e-9):
                        best = (new, tk, tl)
            if best is not None:
                gains.append((old - best[0], k, l, best[1], best[2]))
        if not gains:
            break
        gains.sort(key=lambda g: (-g[0], g[1], g[2]))
        moved: set[int] = set()
        for _gain, k, l, tk, tl in gains:
            if k not in moved and l not in moved:
                sets[k], sets[l] = sorted(tk), sorted(tl)
                moved.update((k, l))
                stats["pair_accepted"] = stats.get("pair_accepted", 0) + 1
    return sets


def assign_bundles(dist, R: int, groups, cost, bundle_order: str, stats: dict) -> list[list[int]]:
    """Robot base sets plus every bundle placed on the robot whose route cost
    (``cost(k, targets)``, the downstream tour) grows least.  Global node indices.

    ``cost`` is a :class:`BundlePricer` (its cache keyed by bit masks kept here as sets grow) or
    any callable ``cost(k, targets)``."""
    base: list[list[int]] = [[] for _ in range(R)]
    bundles: list[list[int]] = []
    for g in groups:
        nodes = g.tolist()
        robots = [v for v in nodes if v < R]
        targets = [v for v in nodes if v >= R]
        if len(robots) == 1:
            base[robots[0]].extend(targets)
        elif len(robots) == 0:
            if targets:
                bundles.append(targets)
        else:  # cannot happen: robot stages run until <= 1 robot per group
            raise SharingFailure(f"group {nodes} still holds {len(robots)} robots")
    stats["bundles"] += len(bundles)
    if not bundles:
        return base
    if bundle_order in ("far_first", "near_first"):
        robots = np.arange(R)
        near = [float(dist[np.ix_(robots, b)].min()) for b in bundles]
    if bundle_order == "far_first":
        order = sorted(range(len(bundles)), key=lambda i: (-near[i], i))
    elif bundle_order == "near_first":
        order = sorted(range(len(bundles)), key=lambda i: (near[i], i))
    elif bundle_order == "largest_first":
        order = sorted(range(len(bundles)), key=lambda i: (-len(bundles[i]), i))
    else:
        order = list(range(len(bundles)))
    current = [list(b) for b in base]
    if isinstance(cost, BundlePricer):
        price = cost.cost_mask
        masks = [sum(1 << t for t in c) for c in current]
        for i in order:
            b = bundles[i]
            bm = sum(1 << t for t in b)
            inc = [price(k, masks[k] | bm, current[k] + b) - price(k, masks[k], current[k]) for k in range(R)]
            k = inc.index(min(inc))  # the first robot of least increase (np.argmin's tie rule)
            current[k].extend(b)
            masks[k] |= bm
        return current
    for i in order:
        b = bundles[i]
        inc = [cost(k, current[k] + b) - cost(k, current[k]) for k in range(R)]
        k = inc.index(min(inc))
        current[k].extend(b)
    return current


def problem_arrays(config, problems) -> tuple:
    """``(q (P, f), Q (P, f, f), free (P, f), sizes, anchors (P, 2), reject (P,))`` of split problems,
    zero-padded to the largest: a stage submission's input."""
    P = len(problems)
    f = max(len(p.free) for p in problems)
    q = np.zeros((P, f))
    Q = np.zeros((P, f, f))
    free = np.zeros((P, f), dtype=np.int64)
    sizes = np.empty(P, dtype=np.int64)
    for k, p in enumerate(problems):
        n = len(p.free)
        sizes[k] = n
        q[k, :n] = p.q
        Q[k, :n, :n] = p.Q
        free[k, :n] = p.free
    anchors = np.array([(p.a, p.b) for p in problems], dtype=np.int64)
    reject = np.array([config.reject_empty_robot_side and p.kind == "robots" for p in problems])
    return q, Q, free, sizes, anchors, reject


def keep_candidates(problems, rules, best, cands, rng, mapping) -> None:
    """Each split's candidates (``cands[k]``: ``(cut, side0, side1, _)`` in first-read order), best cut
    first, into ``problems[k].cands``; the winning rule (``best[k]``: each rule's best ``-cut``) counted,
    ties between rules broken at random so integer win counts stay unbiased."""
    for k, p in enumerate(problems):
        if not cands[k]:
            continue
        top = min(best[k])
        tol = 1e-9 * max(1.0, abs(top))
        winners = [rule for rule, rb in zip(rules, best[k]) if rb <= top + tol]
        # ties between rules (common: several rules find the same split) are
        # broken at random so integer win counts stay unbiased
        win = winners[int(rng.integers(len(winners)))] if len(winners) > 1 else winners[0]
        mapping[win]["wins"] += 1
        c = cands[k]
        order = sorted(range(len(c)), key=lambda i: (-c[i][0], i))
        p.cands = [c[i] for i in order]


class ReferenceStages(StageSolver):
    """The stage submissions of the Python search: :class:`StageSolver` with its re-submissions and
    the decoding of one compiled stage call into candidates."""

    def solve_all(self, w, R, pending, rng, stats) -> None:
        """Solve ``pending`` split problems on the chip, re-submitting those without a valid
        candidate up to ``retries`` times; still none is a :class:`SharingFailure`."""
        attempts = 0
        while pending:
            self.solve_packed(w, R, pending, rng, stats)
            failed = [p for p in pending if not p.cands]
            if failed and attempts >= self.config.retries:
                p = failed[0]
                raise SharingFailure(
                    f"every chip candidate for the split of group {p.nodes.tolist()} was invalid "
                    f"after {attempts + 1} submissions"
                )
            attempts += 1
            pending = failed

    def solve_packed(self, w, R, problems, rng, stats) -> None:
        """The submission of :meth:`solve` for splits that fit the chip: every split x quantization
        rule mapped, block-packed first-fit decreasing into one submission, every read decoded,
        checked and scored on the unquantized cut -- in one compiled call
        (:func:`.stage_steps.submit_stage`, on any machine); each distinct valid partition becomes a
        candidate."""
        cfg = self.config
        seed = int(rng.integers(2**63 - 1))
        rules = cfg.rules
        P = len(problems)
        q, Q, free, sizes, anchors, reject = problem_arrays(cfg, problems)
        # splits beyond the chip as their spin-budget branches, merged back below
        q, Q, free, sizes, nfix, fixed, parent = branch_problems(q, Q, free, sizes, int(self.chip.spec.n_spins))
        try:
            with self.chip.session(self.meter.charged) as link:
                status, calls, emu, scores, sides = submit_stage(
                    SplitProblems(q, Q, free, sizes, anchors[parent], reject[parent], nfix, fixed), self.program(),
                    np.uint64(seed), link.args, w, R)
                if status == STACK_OK:
                    link.settle([calls], [emu])
        except SolverOutputError as exc:  # a broken machine behind the callback: nothing to decode
            raise SharingFailure(f"the chip returned malformed samples: {exc}") from exc
        except ChipProgramError as exc:
            raise SharingFailure(f"the chip refused a mapped split program: {exc}") from exc
        if status != STACK_OK:
            raise SharingFailure(stage_refusal(status))
        b_valid, b_best, c_split, c_cut, _side = scores
        s0, n0, s1, n1 = sides
        mapping = stats["mapping"]["sharing"]
        cands: list = [[] for _ in problems]
        for m, (k, cut, a, b) in enumerate(zip(parent[c_split].tolist(), c_cut.tolist(), n0.tolist(), n1.tolist())):
            cands[k].append((cut, s0[m, :a], s1[m, :b], None))
        for rule, v in zip(rules, b_valid.sum(axis=0).tolist()):
            mapping[rule]["programs"] += len(parent)
            mapping[rule]["reads"] += cfg.reads * len(parent)
            mapping[rule]["valid"] += v
        best = np.full((P, len(rules)), np.inf)
        np.minimum.at(best, parent, b_best)
        best = best.tolist()
        keep_candidates(problems, rules, best, cands, rng, mapping)


def reference_assign(sharing, dist, R: int, tour, rng, solve_packed=None) -> SharingResult:
    """``sharing.assign(dist, R, tour, rng)`` by the Python search (``sharing``: an ``IsingSharing``;
    the world finite, ``R >= 2`` robots and at least one target); ``solve_packed(stages, w, R,
    problems, rng, stats)`` replaces the stage submission (``tests/sharing_reference.py``'s)."""
    self = sharing
    dist = np.asarray(dist, dtype=float)
    mapping = {r: {"programs": 0, "reads": 0, "valid": 0, "wins": 0, "map_errors": 0} for r in self.config.rules}
    stats: dict = {"mapping": {"sharing": mapping}, "stages": 0, "splits": 0, "trivial_splits": 0, "bundles": 0,
                   "tour_solves": 0, "states": 0}
    stages = ReferenceStages(self.config, self.chip)
    if solve_packed is not None:
        stages.solve_packed = lambda *a: solve_packed(stages, *a)
    splits = SplitSearch(self.config, self.chip, stages)
    meter = stages.meter = MeteredSolver(self.chip)
    self._powered_for = None
    pricer = None
    try:
        pricer = BundlePricer(dist, tour, self.config.pricing_tour, rng, stats)
        cost = pricer.cost
        states = splits.split_all(self.split_weights(dist, R), R, rng, stats)
        best = None
        for groups in states:
            sets = assign_bundles(dist, R, groups, pricer, self.config.bundle_order, stats)
            if len(states) == 1:
                best = (0.0, sets)
                break
            total = 0.0
            for k in range(R):  # left to right, as the compiled search sums
                total += cost(k, sets[k])
            if best is None or total < best[0] - 1e-9:  # ties: the state with the larger cuts
                best = (total, sets)
        sets = best[1]
        if self.config.pair_rounds:
            sets = refine_boundaries(splits, lambda shift: self.split_weights(dist, R, shift=shift), dist, R,
                                     sets, cost, rng, stats)
        assignment = tuple(tuple(sorted(t - R for t in ts)) for ts in sets)
        splits.memo = {}
    except (SharingFailure, ChipUnavailableError) as exc:
        compute = ComputeReport.from_ledger(meter.charged)
        return failed(exc, compute if pricer is None else compute + pricer.compute, R, stats)
    compute = ComputeReport.from_ledger(meter.charged) + pricer.compute
    return SharingResult(assignment=assignment, compute=compute, stats=stats)
