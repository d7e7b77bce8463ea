"""The split problem of Ising target sharing (paper 5.3), compiled: its QUBO, its branches, its reads scored.

Contract: :func:`split_model` gives one group's anchors and reduced ``-cut`` QUBO (without the balance
term), :func:`branch_problems` its spin-budget branches, :func:`score_split_reads` every read's
partition, validity, unquantized cut and first read with the same spins.  Sums follow numpy's order, so
the results are the bits of ``choose_anchors`` / ``build_split_qubo`` / ``cut_value`` of
``tests/sharing_search_reference.py``.  Design notes: docs/design/ising_sharing.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ising_backend.mapping.numeric import pairwise_sum

__all__ = ["split_model", "add_balance", "pair_mean", "score_split_reads", "branch_problems", "score_stage",
           "SplitModel", "SplitProblems", "Branches", "StageScores", "Sides"]


class SplitModel(NamedTuple):
    """One group's anchored split (:func:`split_model`)."""

    a: int  # the anchor on side 0
    b: int  # the anchor on side 1
    free: np.ndarray  # the other nodes
    q: np.ndarray  # the -cut QUBO over them: linear
    Q: np.ndarray  # pairs (upper)
    offset: float


class SplitProblems(NamedTuple):
    """The splits of one stage submission (zero-padded to the largest)."""

    q: np.ndarray  # (P, f)
    Q: np.ndarray  # (P, f, f)
    free: np.ndarray  # (P, f) the free nodes, then the frozen ones of a spin-budget branch
    sizes: np.ndarray  # (P,) free nodes
    anchors: np.ndarray  # (P, 2)
    reject: np.ndarray  # (P,) whether a side without a robot is invalid
    nfix: np.ndarray  # (P,) frozen nodes
    fixed: np.ndarray  # (P, f) their spins


class Branches(NamedTuple):
    """:func:`branch_problems`' result: the branches' QUBOs, in split order then branch order."""

    q: np.ndarray
    Q: np.ndarray
    free: np.ndarray  # each branch's free nodes, then its frozen ones
    sizes: np.ndarray
    nfix: np.ndarray
    fixed: np.ndarray  # the frozen nodes' spins
    parent: np.ndarray  # each branch's split


class StageScores(NamedTuple):
    """:func:`score_stage`'s result."""

    n_valid: np.ndarray  # (P, k) valid reads per split and rule
    best: np.ndarray  # (P, k) the rule's best -cut (inf: none)
    split: np.ndarray  # (M,) the split of each distinct valid partition, first occurrence order
    cut: np.ndarray  # (M,) its cut
    side: np.ndarray  # (M, f) bool: its nodes on side 1


class Sides(NamedTuple):
    """:func:`candidate_sides`' result: row ``m`` holds each side's sorted global nodes in its first ``n0[m]``
    / ``n1[m]`` entries."""

    side0: np.ndarray  # (M, f + 1), anchor a first
    n0: np.ndarray
    side1: np.ndarray  # anchor b first
    n1: np.ndarray


@numba.njit(cache=True)
def _farthest_pair(dist, nodes):
    """First maximum of ``dist`` over nodes pairs ``i < j`` in row-major order."""
    best = -np.inf
    a = nodes[0]
    b = nodes[1]
    m = nodes.shape[0]
    for i in range(m):
        for j in range(i + 1, m):
            v = dist[nodes[i], nodes[j]]
            if v > best:
                best = v
                a = nodes[i]
                b = nodes[j]
    return a, b


@numba.njit(cache=True)
def split_model(dist, nodes, n_robots):
    """The :class:`SplitModel` of the anchored split of ``nodes``."""
    nr = 0
    for v in nodes:
        nr += v < n_robots
    robots = np.empty(nr, dtype=np.int64)
    targets = np.empty(nodes.shape[0] - nr, dtype=np.int64)
    ir = 0
    it = 0
    for v in nodes:
        if v < n_robots:
            robots[ir] = v
            ir += 1
        else:
            targets[it] = v
            it += 1
    if nr >= 2:
        a, b = _farthest_pair(dist, robots)
    elif nr == 1:
        a = robots[0]
        b = targets[0]
        best = dist[a, targets[0]]
        for t in targets[1:]:
            if dist[a, t] > best:
                best = dist[a, t]
                b = t
    else:
        a, b = _farthest_pair(dist, targets)
    f = nodes.shape[0] - 2
    free = np.empty(f, dtype=np.int64)
    k = 0
    for v in nodes:
        if v != a and v != b:
            free[k] = v
            k += 1
    q = np.empty(f)
    Q = np.zeros((f, f))
    row = np.empty(f)
    wb = np.empty(f)
    for i in range(f):
        for j in range(f):
            row[j] = 0.0 if i == j else dist[free[i], free[j]]
            if j > i:
                Q[i, j] = 2.0 * row[j]
        wb[i] = dist[free[i], b]
        q[i] = (-pairwise_sum(row, 0, f) - dist[free[i], a]) + wb[i]
    offset = -dist[a, b] - pairwise_sum(wb, 0, f)
    return SplitModel(a, b, free, q, Q, offset)


@numba.njit(cache=True)
def pair_mean(w):
    """``w[np.triu_indices(n, 1)].mean()`` (numpy's summation order), 0.0 for ``n < 2``."""
    n = w.shape[0]
    m = n * (n - 1) // 2
    if m == 0:
        return 0.0
    flat = np.empty(m)
    t = 0
    for i in range(n):
        for j in range(i + 1, n):
            flat[t] = w[i, j]
            t += 1
    return pairwise_sum(flat, 0, m) / m



@numba.njit(cache=True)
def add_balance(dist, free, a, b, n_robots, q, Q, balance):
    """Add the balance term of ``build_split_qubo`` (the oracle) to the split's
    ``q`` and ``Q`` in place (a group of two robots or more; numpy's bits)."""
    f = free.shape[0]
    nodes = np.empty(f + 2, dtype=np.int64)
    nodes[:f] = free
    nodes[f] = a
    nodes[f + 1] = b
    R = 0
    for v in nodes:
        R += v < n_robots
    if R < 2:
        return
    N = nodes.shape[0] - R
    sub = np.empty((f + 2, f + 2))
    for i in range(f + 2):
        for j in range(f + 2):
            sub[i, j] = dist[nodes[i], nodes[j]]
    lam = balance * pair_mean(sub) / R ** 2
    c = np.empty(f)
    for i in range(f):
        c[i] = -float(N) if free[i] < n_robots else float(R)
    c0 = -float(N) if b < n_robots else float(R)
    for i in range(f):
        q[i] = q[i] + lam * (c[i] ** 2 + 2.0 * c0 * c[i])
        for j in range(i + 1, f):
            Q[i, j] = Q[i, j] + lam * (2.0 * (c[i] * c[j]))


@numba.njit(cache=True, inline="always")
def _sort_small(a, n):
    """Sort ``a[:n]`` (integers) in place by insertion: no work array, as ``np.sort`` would need."""
    for i in range(1, n):
        v = a[i]
        j = i - 1
        while j >= 0 and a[j] > v:
            a[j + 1] = a[j]
            j -= 1
        a[j + 1] = v


@numba.njit(cache=True)
def score_split_reads(blocks, free, a, b, dist, n_robots, reject_empty_robot_side):
    """Decode, check and score the reads ``blocks (m, f)`` (+-1, one per free node) of one split.

    Side 1 holds ``b`` and the free nodes with spin ``+1``; the cut is the sum of ``dist`` over
    (sorted side 0) x (sorted side 1) in row-major order.  With ``reject_empty_robot_side`` a side
    holding robots but no target is invalid.  Returns ``(valid (m,) bool, cut (m,) float64,
    first (m,) int64)`` (``first[r]``: the first read with the same spins).
    """
    m, f = blocks.shape
    valid = np.zeros(m, dtype=np.bool_)
    cut = np.zeros(m)
    first = np.arange(m)
    n = f + 2
    s0 = np.empty(n, dtype=np.int64)
    s1 = np.empty(n, dtype=np.int64)
    prod = np.empty(n * n)
    for r in range(m):
        for u in range(r):
            same = True
            for i in range(f):
                if blocks[u, i] != blocks[r, i]:
                    same = False
                    break
            if same:
                first[r] = first[u]
                break
        if first[r] != r:
            valid[r] = valid[first[r]]
            cut[r] = cut[first[r]]
            continue
        n0 = 1
        n1 = 1
        s0[0] = a
        s1[0] = b
        for i in range(f):
            if blocks[r, i] > 0:
                s1[n1] = free[i]
                n1 += 1
            else:
                s0[n0] = free[i]
                n0 += 1
        _sort_small(s0, n0)
        _sort_small(s1, n1)
        ok = True
        if reject_empty_robot_side:
            rob0 = 0
            for i in range(n0):
                rob0 += s0[i] < n_robots
            rob1 = 0
            for i in range(n1):
                rob1 += s1[i] < n_robots
            ok = not (rob0 > 0 and rob0 == n0) and not (rob1 > 0 and rob1 == n1)
        if not ok:
            continue
        valid[r] = True
        k = 0
        for i in range(n0):
            for j in range(n1):
                prod[k] = dist[s0[i], s1[j]]
                k += 1
        cut[r] = pairwise_sum(prod, 0, k)
    return valid, cut, first


@numba.njit(cache=True)
def branch_problems(q, Q, free, sizes, budget):
    """Spin-budget branching of split QUBOs (paper 4.2, as :func:`ising_backend.branch`): every split
    with ``k = sizes[p] - budget > 0`` free nodes too many becomes ``2^k`` splits of ``budget`` nodes,
    the ``k`` nodes of strongest Ising interaction (``|h_i| + sum_j |J_ij|``, lowest index first on
    ties) frozen, branch ``m`` putting frozen node ``t`` on side 1 when bit ``t`` of ``m`` is set.
    Returns the :class:`Branches`."""
    P, f = q.shape
    E = 0
    for p in range(P):
        E += 1 << max(0, sizes[p] - budget)
    q2 = np.zeros((E, f))
    Q2 = np.zeros((E, f, f))
    free2 = np.zeros((E, f), dtype=np.int64)
    sizes2 = np.empty(E, dtype=np.int64)
    nfix = np.zeros(E, dtype=np.int64)
    fixed = np.zeros((E, f), dtype=np.int8)
    parent = np.empty(E, dtype=np.int64)
    e = 0
    for p in range(P):
        n = sizes[p]
        k = max(0, n - budget)
        strength = np.empty(n)
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += abs(Q[p, i, j] + Q[p, j, i]) / 4.0
            h = q[p, i] / 2.0
            for j in range(n):
                h += (Q[p, i, j] + Q[p, j, i]) / 4.0
            strength[i] = abs(h) + s
        frozen = np.sort(np.argsort(-strength, kind="mergesort")[:k])
        is_frozen = np.zeros(n, dtype=np.bool_)
        for u in range(k):
            is_frozen[frozen[u]] = True
        rest = np.empty(n - k, dtype=np.int64)
        t = 0
        for i in range(n):
            if not is_frozen[i]:
                rest[t] = i
                t += 1
        for m in range(1 << k):
            for a in range(n - k):
                i = rest[a]
                v = q[p, i]
                for u in range(k):
                    if (m >> u) & 1:
                        v += Q[p, i, frozen[u]] + Q[p, frozen[u], i]
                q2[e, a] = v
                for b in range(n - k):
                    Q2[e, a, b] = Q[p, i, rest[b]]
                free2[e, a] = free[p, i]
            for u in range(k):
                free2[e, n - k + u] = free[p, frozen[u]]
                fixed[e, u] = 1 if (m >> u) & 1 else -1
            sizes2[e] = n - k
            nfix[e] = k
            parent[e] = p
            e += 1
    return Branches(q2, Q2, free2, sizes2, nfix, fixed, parent)


@numba.njit(cache=True)
def score_stage(spins, where, sizes, k, free, anchors, dist, n_robots, reject, nfix, fixed):
    """Decode, check and score every read of every split of one stage submission.

    ``where (P * k, 2)``: the pack and first spin of program ``p * k + r`` in ``spins (packs, R, W)``;
    ``free (P, f)`` / ``anchors (P, 2)`` / ``reject (P,)`` per split (see :func:`score_split_reads`);
    split ``p``'s program holds its first ``sizes[p]`` free nodes, and the ``nfix[p]`` nodes after
    them are frozen at spins ``fixed[p]`` (a spin-budget branch, :func:`branch_problems`).
    Returns the :class:`StageScores`.
    """
    P = sizes.shape[0]
    R = spins.shape[1]
    f = free.shape[1]
    n_valid = np.zeros((P, k), dtype=np.int64)
    best = np.full((P, k), np.inf)
    M = 0
    cand_split = np.empty(P * k * R, dtype=np.int64)
    cand_cut = np.empty(P * k * R)
    cand_side = np.zeros((P * k * R, f), dtype=np.bool_)
    for p in range(P):
        n = sizes[p] + nfix[p]
        blocks = np.empty((k * R, n), dtype=np.int8)
        for r in range(k):
            b = where[p * k + r, 0]
            s0 = where[p * k + r, 1]
            for t in range(R):
                for i in range(sizes[p]):
                    blocks[r * R + t, i] = spins[b, t, s0 + i]
                for i in range(nfix[p]):
                    blocks[r * R + t, sizes[p] + i] = fixed[p, i]
        valid, cut, first = score_split_reads(blocks, free[p, :n], anchors[p, 0], anchors[p, 1], dist, n_robots,
                                              reject[p])
        for r in range(k):
            for t in range(R):
                row = r * R + t
                if valid[row]:
                    n_valid[p, r] += 1
                    if -cut[row] < best[p, r]:
                        best[p, r] = -cut[row]
                    if first[row] == row:
                        cand_split[M] = p
                        cand_cut[M] = cut[row]
                        for i in range(n):
                            cand_side[M, i] = blocks[row, i] > 0
                        M += 1
    return StageScores(n_valid, best, cand_split[:M], cand_cut[:M], cand_side[:M])


@numba.njit(cache=True)
def candidate_sides(c_split, c_side, free, sizes, anchors):
    """The :class:`Sides` of every candidate of :func:`score_stage`."""
    M = c_split.shape[0]
    f = free.shape[1]
    side0 = np.zeros((M, f + 1), dtype=np.int64)
    side1 = np.zeros((M, f + 1), dtype=np.int64)
    n0 = np.zeros(M, dtype=np.int64)
    n1 = np.zeros(M, dtype=np.int64)
    for m in range(M):
        p = c_split[m]
        side0[m, 0] = anchors[p, 0]
        side1[m, 0] = anchors[p, 1]
        a, b = 1, 1
        for i in range(sizes[p]):
            if c_side[m, i]:
                side1[m, b] = free[p, i]
                b += 1
            else:
                side0[m, a] = free[p, i]
                a += 1
        _sort_small(side0[m], a)
        _sort_small(side1[m], b)
        n0[m] = a
        n1[m] = b
    return Sides(side0, n0, side1, n1)
