"""The chip tour's move selection (one start) as a plain Python loop: the oracle of the compiled loop.

``reference_select_moves(tour, dist, route, run)`` makes the decisions the package's compiled
``planners.ising.moves.search.move_search`` must make on the tour's neighbourhood: list and pick the candidate
moves, build the selection QUBO and its Ising form, quantize it by every rule, one
``anneal_batch`` per round, score the reads, apply the best valid read.  The candidate moves, their
gains, the scoring of the reads and the moves themselves are computed here, independently of
``planners.ising.moves.route_moves`` (gains as route cost before minus after: exact, and so the kernel's
bits, on the integer BFS distances the tests use).  Test code only: the package never imports it.
"""

from __future__ import annotations

import numpy as np

from ising_backend import ising_from_qubo, quantize_stack
from planners.ising.tour.cluster import TourFailure

__all__ = ["nearest_neighbour_route", "reference_select_moves", "cluster_dist_reference"]


def nearest_neighbour_route(dist: np.ndarray) -> np.ndarray:
    """``[0, t_1, ..., t_n]``: from node 0 always to the nearest unvisited node (ties: lowest index)."""
    n = dist.shape[0] - 1
    route = [0]
    left = list(range(1, n + 1))
    while left:
        row = dist[route[-1], left]
        route.append(left.pop(int(np.argmin(row))))
    return np.array(route, dtype=np.int64)


def _open_cost(dist, route) -> float:
    """An open route's cost: its legs summed from the first node on (no return)."""
    return sum(float(dist[a, b]) for a, b in zip(route[:-1], route[1:]))


def _moved(route, move) -> list:
    """``route`` (positions 0..n, node 0 the robot) with one move row ``(kind, p, q, c, lo, hi)`` applied:
    kind 0 reverses positions ``p+1..q`` (2-opt); kind 1 / 2 takes the segment at positions ``p..q``
    out and puts it, as it was / reversed, right after the node at position ``c`` (or-opt)."""
    kind, p, q, c = (int(v) for v in move[:4])
    r = [int(x) for x in route]
    if kind == 0:
        return r[:p + 1] + r[p + 1:q + 1][::-1] + r[q + 1:]
    seg = r[p:q + 1] if kind == 1 else r[p:q + 1][::-1]
    rest = r[:p] + r[q + 1:]
    at = rest.index(r[c]) + 1
    return rest[:at] + seg + rest[at:]


def candidate_moves(dist, route, max_segment):
    """Every improving 2-opt and or-opt move of ``route``, as rows ``(kind, p, q, c, lo, hi)`` (``lo..hi``:
    the edges the move rewrites) with their gains, in the kernel's listing order: 2-opt ``(i, j)`` for
    ``i < j - 1``; then or-opt segments ``a..b`` of 1..``max_segment`` targets, forward then reversed
    (a single target only forward), to after every position ``c`` outside ``a-1..b``."""
    n = len(route) - 1
    before = _open_cost(dist, route)
    rows, gains = [], []

    def offer(row):
        gain = before - _open_cost(dist, _moved(route, row))
        if gain > 1e-9:
            rows.append(row)
            gains.append(gain)

    for i in range(n - 1):
        for j in range(i + 2, n + 1):
            offer((0, i, j, -1, i, j))
    for a in range(1, n + 1):
        for b in range(a, min(n, a + max_segment - 1) + 1):
            for kind in ((1, 2) if b > a else (1,)):
                for c in range(n + 1):
                    if a - 1 <= c <= b:
                        continue
                    offer((kind, a, b, c, c, b) if c < a else (kind, a, b, c, a - 1, c))
    return np.array(rows, dtype=np.int64).reshape(-1, 6), np.array(gains, dtype=np.float64)


def _overlap(m, o) -> bool:
    """Two moves rewrite a common edge (their spans ``lo..hi`` meet)."""
    return m[4] <= o[5] and o[4] <= m[5]


def score_reads(spins, moves, gains):
    """``(clean (k,), rule, read, gain)``: per program (one per rule) the valid reads selecting a move (a
    read selecting two overlapping moves is invalid), and the first read of largest total gain above 0
    (``rule = -1``: none)."""
    k, reads, _ = spins.shape
    clean = np.zeros(k, dtype=np.int64)
    best_k, best_r, best = -1, -1, 0.0
    for a in range(k):
        for r in range(reads):
            chosen = [int(m) for m in np.flatnonzero(spins[a, r] > 0)]
            if any(_overlap(moves[m], moves[o]) for i, m in enumerate(chosen) for o in chosen[:i]):
                continue
            clean[a] += bool(chosen)
            total = sum(float(gains[m]) for m in chosen)
            if total > best + 1e-9:
                best_k, best_r, best = a, r, total
    return clean, best_k, best_r, best


def pick_candidates(moves, gains, k, max_overlap) -> np.ndarray:
    """At most ``k`` moves by gain (ties: index), each overlapping at most ``max_overlap`` picked before it."""
    picked: list[int] = []
    for m in sorted(range(len(gains)), key=lambda i: (-gains[i], i)):
        if len(picked) == k:
            break
        if sum(_overlap(moves[m], moves[o]) for o in picked) <= max_overlap:
            picked.append(m)
    return np.array(picked, dtype=np.int64)


def selection_qubo(moves, gains) -> tuple[np.ndarray, np.ndarray]:
    """``(q, Q)``: ``-sum g_m x_m + sum (min(g_m, g_m') + 1) x_m x_m'`` over overlapping pairs, ``Q`` upper."""
    M = len(gains)
    Q = np.zeros((M, M))
    for i in range(M):
        for j in range(i + 1, M):
            if _overlap(moves[i], moves[j]):
                Q[i, j] = min(gains[i], gains[j]) + 1.0
    return -np.asarray(gains, dtype=np.float64), Q


def apply_moves(route, moves, taken) -> np.ndarray:
    """``route`` with the (pairwise non-overlapping) moves ``taken`` applied one after another."""
    r = list(route)
    for m in taken:
        r = _moved(r, moves[m])
    return np.array(r, dtype=np.int64)


def reference_select_moves(tour, dist: np.ndarray, route: np.ndarray, run) -> np.ndarray:
    """``tour.moves.select(dist, route, run, link)`` (one start) through the Python loop."""
    cfg = tour.config
    capacity = min(int(getattr(tour.chip, "usable_spins", tour.spec.n_spins)), cfg.max_moves)
    failures = rounds = applied = 0
    while rounds < cfg.max_rounds:
        moves, gains = candidate_moves(dist, route, cfg.max_segment)
        if len(gains) == 0:
            break
        # a round re-issued after reads that selected nothing valid offers fewer moves
        keep = pick_candidates(moves, gains, max(1, capacity >> failures), cfg.max_overlap)
        moves, gains = moves[keep], gains[keep]
        taken = _chip_round(tour, moves, gains, run)
        rounds += 1
        if taken is None:
            failures += 1
            run.stats["retries"] += 1
            if failures > cfg.max_retries:
                run.stats["unsolved"]["moves"] += 1
                if not applied:
                    run.stats["move_rounds"] += rounds
                    raise TourFailure(f"the chip selected no valid improving move set in {failures} "
                                      f"submissions of {len(cfg.chip_rules)} programs")
                break
            continue
        failures = 0
        applied += len(taken)
        route = apply_moves(route, moves, taken)
        run.stats["moves_applied"] += len(taken)
    run.stats["move_rounds"] += rounds
    return route


def _chip_round(tour, moves, gains, run):
    """One selection program per rule in one chip submission; the taken moves of the best read,
    or ``None`` when no read selects an improving set."""
    cfg = tour.config
    q, Q = selection_qubo(moves, gains)
    h, J = quantize_stack(ising_from_qubo(q, Q), cfg.chip_rules, tour.spec.h_range, tour.spec.j_range)
    seed = int(run.rng.integers(0, 2**63 - 1))
    spins, _ = run.chip.anneal_batch(h, J, num_reads=cfg.num_reads, seed=seed)
    m = run.stats["mapping"]["tour"]
    # overlapping moves make a read invalid: dropped, never repaired
    clean, best_k, best_r, _gain = score_reads(spins, moves, gains)
    best = np.flatnonzero(spins[best_k, best_r] > 0) if best_k >= 0 else None
    for rule, valid in zip(cfg.chip_rules, clean.tolist()):
        m[rule]["programs"] += 1
        m[rule]["reads"] += cfg.num_reads
        m[rule]["valid"] += int(valid)
    run.stats["valid_programs"] += int((clean > 0).sum())
    run.stats["subproblems"] += 1
    run.stats["valid_subproblems"] += best is not None
    if best is not None:
        m[cfg.chip_rules[best_k]]["wins"] += 1
    return best


def cluster_dist_reference(dist: np.ndarray, clusters: list[list[int]], mode: str) -> np.ndarray:
    """Cluster-to-cluster distances in numpy, pair by pair (``mode``: min, mean or medoid)."""
    K = len(clusters)
    D = np.zeros((K, K))
    med = [c[int(np.argmin(dist[np.ix_(c, c)].sum(axis=1)))] for c in clusters]
    for a in range(K):
        for b in range(K):
            if a == b:
                continue
            if mode == "medoid":
                D[a, b] = dist[med[a], med[b]]
            else:
                block = dist[np.ix_(clusters[a], clusters[b])]
                D[a, b] = block.min() if mode == "min" else block.mean()
    return D


def reference_solve_path(tour, d, entry, ex, run, kind: str):
    """``tour.onehot.solve_path(d, entry, ex, run, kind)`` (one-hot subproblem: penalty, Ising model,
    spin-budget branching, logical solver or quantized chip programs, decode) through Python calls."""
    import math

    from ising_backend import IsingModel, LogicalIsingSolver, quantize
    from ising_backend.mapping.branching import branch_stack
    from mapping_reference import freeze_order_ref as freeze_order
    from planners.ising.tour.kernels import best_onehot, expand_branches, onehot_ising
    from tour_qubo_reference import onehot_penalty

    cfg = tour.config
    s = d.shape[0]
    A = onehot_penalty(d, entry, ex, 1.0, cfg.penalty_factor)
    h, J, off = onehot_ising(d, entry, ex, A, 1.0)
    n = h.shape[0]
    k = max(n - tour.onehot.budget, 0)
    if k > cfg.max_branch_bits:
        raise TourFailure(f"a {n}-spin program needs {k} frozen spins > max_branch_bits = {cfg.max_branch_bits}")
    frozen = np.sort(freeze_order(IsingModel.trusted(h, J, float(off)))[:k]) if k else np.zeros(0, dtype=np.int64)
    free, hb, Jb, offs = branch_stack(h, J, float(off), frozen)
    physical = cfg.backend != "logical"
    m = run.stats["mapping"]["tour"][cfg.chip_quantize if physical else "logical"]
    for _attempt in range(cfg.max_retries + 1):
        seed = int(run.rng.integers(0, 2**63 - 1))
        programs = [IsingModel.trusted(hb[b], Jb.copy(), float(offs[b])) for b in range(len(hb))]
        if physical:
            progs = [quantize(p, cfg.chip_quantize, tour.spec.h_range, tour.spec.j_range) for p in programs]
            out = [sp for sp, _e in run.chip.anneal_models(progs, num_reads=cfg.num_reads, seed=seed)]
        elif isinstance(run.solver.solver, LogicalIsingSolver):
            out = list(run.solver.solve_stack(hb, Jb, num_reads=cfg.num_reads, seed=seed))
        else:
            out = [r.spins for r in run.solver.solve_many(programs, num_reads=cfg.num_reads, seed=seed)]
        spins = np.stack([np.asarray(sp).reshape(cfg.num_reads, -1) for sp in out])
        bits = expand_branches(spins, free, frozen, n)
        valid, best, orders = best_onehot(bits, int(round(math.sqrt(n))), d, entry, ex)
        per_program = valid.reshape(len(hb), -1)
        m["programs"] += len(hb)
        m["reads"] += int(valid.size)
        m["valid"] += int(valid.sum())
        m["wins"] += int(valid.any())
        run.stats["valid_programs"] += int(per_program.any(axis=1).sum())
        run.stats["subproblems"] += 1
        run.stats["valid_subproblems"] += int(valid.any())
        if best >= 0:
            return [int(i) for i in orders[best]]
        run.stats["retries"] += 1
    run.stats["unsolved"][kind] += 1
    return None
