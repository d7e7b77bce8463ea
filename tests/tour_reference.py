"""The chip tour's move selection (one start) as a plain Python loop: the oracle of the compiled loop.

``reference_select_moves(tour, dist, route, run)`` makes the decisions the package's compiled
``planners.ising.tour.move_engine.select_moves_loop`` must make: list and pick the candidate
moves, build the selection QUBO and its Ising form, quantize it by every rule, one
``anneal_batch`` per round, score the reads, apply the best valid read.  Test code only: the
package never imports it.
"""

from __future__ import annotations

import numpy as np

from ising_backend import ising_from_qubo, quantize_stack
from planners.ising.tour.cluster import TourFailure
from planners.ising.tour.moves import apply_moves, candidate_moves, pick_candidates, score_reads, selection_qubo

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


def reference_select_moves(tour, dist: np.ndarray, route: np.ndarray, run) -> np.ndarray:
    """``tour.moves.select(dist, route, run)`` through the Python loop."""
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
    m["reads"] += cfg.num_reads * len(cfg.chip_rules)
    m["valid_reads"] += int(clean.sum())
    m["valid"] += int((clean > 0).sum())
    m["valid_physical"] += int((clean > 0).sum())
    m["programs"] += len(cfg.chip_rules)
    m["physical_programs"] += len(cfg.chip_rules)
    m["subproblems"] += 1
    m["valid_subproblems"] += best is not None
    if best is not None:
        won = m.setdefault("wins", {})
        won[cfg.chip_rules[best_k]] = won.get(cfg.chip_rules[best_k], 0) + 1
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

    from ising_backend import IsingModel, LogicalIsingSolver, freeze_order, quantize
    from planners.ising.tour.kernels import best_onehot, branch_stack, expand_branches, onehot_ising
    from planners.ising.tour.qubo import onehot_penalty

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
    m = run.stats["mapping"]["tour"]
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
        m["valid_reads"] += int(valid.sum())
        m["valid"] += int(per_program.any(axis=1).sum())
        if physical:
            m["physical_programs"] += len(hb)
            m["valid_physical"] += int(per_program.any(axis=1).sum())
        m["subproblems"] += 1
        m["valid_subproblems"] += int(valid.any())
        if best >= 0:
            return [int(i) for i in orders[best]]
        run.stats["retries"] += 1
    run.stats["unsolved"][kind] += 1
    return None
