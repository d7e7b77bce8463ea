"""Anchored split formulation of Ising target sharing (paper 5.3, eq. 8) -- pure functions.

Anchors (farthest robot pair / robot and its farthest target / farthest target pair)
are substituted, so a group of ``m`` nodes has ``m - 2`` free spins; the QUBO is
``-cut`` (plus an optional balance term); candidates are scored on the unquantized cut.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["choose_anchors", "build_split_qubo", "cut_value", "SplitProblem", "decode_split"]


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
