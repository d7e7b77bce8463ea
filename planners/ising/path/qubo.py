"""Patch geometry and the cell-based patch QUBO (paper 5.1, eq. 6) -- pure functions.

A ``size x size`` patch centred on the robot; only free cells 4-connected to the
robot inside the patch are modelled; the robot cell and the local target are
pinned (substituted with ``x = 1``).  Forms and weights: docs/design/ising_path.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numba
import numpy as np

from planners.ising.path.config import DEFAULT_WEIGHTS, FORMS

__all__ = ["PatchFrame", "patch_frame", "PatchQubo", "build_patch_qubo"]


# --------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class PatchFrame:
    """Fixed local structure of a ``size x size`` patch (cells row-major, ``size**2`` of them).

    ``adj4[i, j]``: cells i and j are 4-neighbours; ``diag[i, j]``: diagonal
    neighbours; ``ring``: cells on the patch boundary (Chebyshev radius
    ``size // 2`` from the centre); ``offsets``: ``(size**2, 2)`` offset of each
    cell from the centre.
    """

    size: int
    adj4: np.ndarray
    diag: np.ndarray
    ring: np.ndarray
    offsets: np.ndarray
    neighbours: tuple  # per cell, tuple of 4-neighbour cell indices

    @property
    def radius(self) -> int:
        return self.size // 2

    @property
    def n(self) -> int:
        return self.size * self.size


@lru_cache(maxsize=8)
def patch_frame(size: int) -> PatchFrame:
    if int(size) != size or size < 3 or size % 2 == 0:
        raise ValueError(f"patch_size must be an odd integer >= 3, got {size!r}")
    size = int(size)
    rad = size // 2
    rr, cc = np.divmod(np.arange(size * size), size)
    dr = np.abs(rr[:, None] - rr[None, :])
    dc = np.abs(cc[:, None] - cc[None, :])
    adj4 = (dr + dc) == 1
    diag = (dr == 1) & (dc == 1)
    offsets = np.stack([rr - rad, cc - rad], axis=1).astype(np.int64)
    ring = np.maximum(np.abs(offsets[:, 0]), np.abs(offsets[:, 1])) == rad
    neighbours = tuple(tuple(int(j) for j in np.flatnonzero(adj4[i])) for i in range(size * size))
    for a in (adj4, diag, ring, offsets):
        a.setflags(write=False)
    return PatchFrame(size, adj4, diag, ring, offsets, neighbours)


# --------------------------------------------------------------------------- QUBO
@dataclass(frozen=True)
class PatchQubo:
    """A patch problem with the two endpoints substituted (pinned, not variables).

    Energy of variable assignment ``x`` (0/1, one per entry of ``cells``):
    ``offset + q @ x + sum_{i<j} Q[i, j] x_i x_j`` (``Q`` strictly upper triangular).
    """

    cells: np.ndarray  # (n,) patch-frame indices of the variables
    q: np.ndarray  # (n,)
    Q: np.ndarray  # (n, n) strictly upper triangular
    offset: float
    start: int  # patch-frame index of the robot cell
    goal: int  # patch-frame index of the local target

    @property
    def n(self) -> int:
        return int(len(self.cells))

    def energy(self, x: np.ndarray) -> np.ndarray:
        """Original-objective energy of ``x`` (``(..., n)`` 0/1), vectorised over leading axes."""
        x = np.asarray(x, dtype=np.float64)
        return self.offset + x @ self.q + np.einsum("...i,ij,...j->...", x, self.Q, x)


def _resolve(form: str, weights: dict | None, allowed, start: int, goal: int) -> tuple[dict, np.ndarray]:
    if form not in FORMS:
        raise ValueError(f"form must be one of {FORMS}, got {form!r}")
    w = dict(DEFAULT_WEIGHTS[form])
    if weights:
        unknown = set(weights) - set(w)
        if unknown:
            raise ValueError(f"unknown weights {sorted(unknown)} for form {form!r} (known: {sorted(w)})")
        w.update(weights)
    if start == goal:
        raise ValueError("start and goal of a patch problem must differ")
    allowed = np.asarray(allowed, dtype=bool)
    if not (allowed[start] and allowed[goal]):
        raise ValueError("start and goal of a patch problem must be allowed cells")
    return w, allowed


def build_patch_qubo(
    frame: PatchFrame,
    allowed: np.ndarray,
    start: int,
    goal: int,
    form: str = "pair",
    weights: dict | None = None,
) -> PatchQubo:
    """The cell-based patch QUBO (paper eq. 6) over ``allowed`` patch cells, endpoints pinned.

    ``allowed`` (bool, ``frame.n``) marks the free patch cells that may carry the
    path; ``start`` and ``goal`` must be allowed and distinct.  The energy is
    built on the whole frame with the endpoints as ordinary 0/1 cells and then
    the endpoints are substituted with ``x = 1`` (their terms fold into the
    linear coefficients of their neighbours and into the offset).  Compiled
    (:func:`_patch_qubo_kernel`); ``tests/path_reference.py`` holds the numpy original.
    """
    w, allowed = _resolve(form, weights, allowed, start, goal)
    if form == "pair":
        coef = (w["C"], w["B"], w["Dg"], w["A_end"], 0.0)
    else:
        coef = (0.0, w["B"], 0.0, w["A_end"], w["A"])
    var, qv, Qv, offset = _patch_qubo_kernel(frame.adj4, frame.diag, allowed, int(start), int(goal),
                                             form == "degree", *coef)
    for a in (var, qv, Qv):
        a.setflags(write=False)
    return PatchQubo(var, qv, Qv, float(offset), int(start), int(goal))


@numba.njit(cache=True)
def _patch_qubo_kernel(adj4, diag, allowed, start, goal, degree, C, B, Dg, A_end, A):
    """The arithmetic of the numpy original (``tests/path_reference.py``), term by term in the same order."""
    n = adj4.shape[0]
    A4 = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            if adj4[i, j] and allowed[i] and allowed[j]:
                A4[i, j] = 1.0
    free = np.zeros(n, dtype=np.bool_)
    for i in range(n):
        free[i] = allowed[i] and i != start and i != goal
    q = np.zeros(n)
    W = np.zeros((n, n))
    if not degree:
        for i in range(n):
            for j in range(n):
                dg = 1.0 if (diag[i, j] and allowed[i] and allowed[j]) else 0.0
                W[i, j] += -C * A4[i, j] + Dg * dg
            q[i] += B * free[i]
    else:
        # D = A4 * free[:, None]; M = D.T @ D; q += A diag(M); W += 2A (M - diag M); W += -4A (D + D.T).
        # M[i, j] counts the free cells next to both i and j: whole numbers, the same in any order,
        # so they are gathered from each free cell's few neighbours rather than summed over all cells
        M = np.zeros((n, n))
        nbrs = np.empty(n, dtype=np.int64)
        for k in range(n):
            if free[k]:
                c = 0
                for i in range(n):
                    if A4[k, i] != 0.0:
                        nbrs[c] = i
                        c += 1
                for x in range(c):
                    for y in range(c):
                        M[nbrs[x], nbrs[y]] += 1.0
        for i in range(n):
            for j in range(n):
                m = M[i, j]
                if i == j:
                    q[i] += A * m
                else:
                    W[i, j] += 2.0 * A * m
        for i in range(n):
            for j in range(n):
                W[i, j] += -4.0 * A * (A4[i, j] * free[i] + A4[j, i] * free[j])
        for i in range(n):
            q[i] += 4.0 * A * free[i] + B * free[i]
    for e in (start, goal):  # endpoint terms: A_end * (deg(e) - 1)^2
        for i in range(n):
            q[i] += A_end * (A4[e, i] * A4[e, i])
        for i in range(n):
            for j in range(n):
                if i != j:
                    W[i, j] += 2.0 * A_end * (A4[e, i] * A4[e, j])
        for i in range(n):
            q[i] += -2.0 * A_end * A4[e, i]
    offset = 2.0 * A_end
    m = 0
    for i in range(n):
        m += free[i]
    var = np.empty(m, dtype=np.int64)
    k = 0
    for i in range(n):
        if free[i]:
            var[k] = i
            k += 1
    qv = np.empty(m)
    Qv = np.zeros((m, m))
    for a in range(m):
        i = var[a]
        qv[a] = q[i] + (W[i, start] + W[i, goal])
        for b in range(a + 1, m):
            Qv[a, b] = W[i, var[b]]
    offset += (q[start] + q[goal]) + W[start, goal]
    return var, qv, Qv, offset
