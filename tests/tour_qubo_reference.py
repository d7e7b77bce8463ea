"""Test oracle: the QUBOs of the clustered Ising tour (paper 5.2, eqs. 1 and 7) in plain numpy.

The compiled kernels of ``planners/ising/tour/kernels.py`` (``maxcut_ising``, ``onehot_ising``) and the
engine's penalty are the definition; these builders, decoders and scorers check them.

``(q, Q, offset)``: ``E(x) = x @ Q @ x + q @ x + offset``, ``Q`` strictly upper triangular.
:func:`maxcut_qubo` (eq. 7 split, energy ``-cut``) and :func:`open_path_qubo` (one-hot
open path with soft boundary costs; variable ``i * s + p`` = item ``i`` at position ``p``;
on a valid permutation ``E = B * route cost``).  Penalty choice: docs/design/ising_tour_qubo.md.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "maxcut_qubo",
    "open_path_qubo",
    "onehot_penalty",
    "decode_onehot",
    "decode_onehot_batch",
    "path_cost",
    "qubo_energy",
]


def qubo_energy(q: np.ndarray, Q: np.ndarray, offset: float, x: np.ndarray) -> np.ndarray:
    """``x @ Q @ x + q @ x + offset`` vectorised over leading axes of ``x``."""
    x = np.asarray(x, dtype=np.float64)
    return np.einsum("...i,ij,...j->...", x, Q, x) + x @ q + offset


# --------------------------------------------------------------------------- max-cut (eq. 7)


def maxcut_qubo(w: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """QUBO whose energy is ``-cut(x)`` for the symmetric weight matrix ``w``.

    ``cut(x) = sum_{i<j} w_ij (x_i + x_j - 2 x_i x_j)``: linear ``-sum_j w_ij``,
    quadratic ``+2 w_ij`` (upper triangle).
    """
    w = np.asarray(w, dtype=np.float64)
    if w.ndim != 2 or w.shape[0] != w.shape[1]:
        raise ValueError(f"weight matrix must be square, got shape {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("weight matrix has non-finite entries (targets in different components?)")
    ws = 0.5 * (w + w.T)
    np.fill_diagonal(ws, 0.0)
    q = -ws.sum(axis=1)
    Q = np.triu(2.0 * ws, k=1)
    return q, Q, 0.0


# --------------------------------------------------------------------------- one-hot open path


def onehot_penalty(d: np.ndarray, entry: np.ndarray, exit_: np.ndarray, B: float = 1.0,
                   margin_factor: float = 1.0) -> float:
    """The one-hot penalty ``A`` for a route model (see the module docstring)."""
    vals = [np.max(np.abs(d)) if d.size else 0.0]
    if entry.size:
        vals.append(np.max(np.abs(entry)))
    if exit_.size:
        vals.append(np.max(np.abs(exit_)))
    w_max = float(max(vals))
    return float(B * (margin_factor * w_max + 1.0))


def open_path_qubo(
    d: np.ndarray,
    entry: np.ndarray | None = None,
    exit_: np.ndarray | None = None,
    A: float | None = None,
    B: float = 1.0,
    margin_factor: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, float, float]:
    """One-hot position QUBO of an open path over ``s`` items.

    Args:
        d: ``(s, s)`` item-to-item costs (``d[i, j]`` = cost of ``i`` then ``j``).
        entry: ``(s,)`` cost from the previous waypoint into each item
            (zeros = free start).
        exit_: ``(s,)`` cost from each item toward the next waypoint
            (zeros = open end).
        A: one-hot penalty; ``None`` = :func:`onehot_penalty`.
        B: route weight.

    Returns:
        ``(q, Q, offset, A)`` with ``s*s`` variables, ``v = i * s + p``.
    """
    d = np.asarray(d, dtype=np.float64)
    if d.ndim != 2 or d.shape[0] != d.shape[1]:
        raise ValueError(f"cost matrix must be square, got shape {d.shape}")
    s = d.shape[0]
    if s < 1:
        raise ValueError("an open path needs at least one item")
    entry = np.zeros(s) if entry is None else np.asarray(entry, dtype=np.float64).reshape(-1)
    exit_ = np.zeros(s) if exit_ is None else np.asarray(exit_, dtype=np.float64).reshape(-1)
    if entry.shape != (s,) or exit_.shape != (s,):
        raise ValueError(f"entry/exit must have shape ({s},), got {entry.shape} and {exit_.shape}")
    for name, arr in (("cost matrix", d), ("entry", entry), ("exit", exit_)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} has non-finite entries (unreachable targets?)")
    if A is None:
        A = onehot_penalty(d, entry, exit_, B, margin_factor)
    onehot, rows, cols, ii, jj, first, last = _layout(s)
    q = np.full(s * s, -2.0 * A)
    q[first] += B * entry
    q[last] += B * exit_
    # C symmetric: the quadratic part is sum_{a<b} C_ab x_a x_b
    C = (2.0 * A) * onehot  # same item twice, or two items at one position
    route = B * d[ii, jj]  # item i at p, item j != i at p+1
    C[rows, cols] += route
    C[cols, rows] += route
    Q = np.triu(C, k=1)
    offset = 2.0 * s * A
    return q, Q, float(offset), float(A)


_LAYOUTS: dict[int, tuple] = {}


def _layout(s: int) -> tuple:
    """Index tables of the ``s x s`` one-hot model (cached: they depend on ``s`` only)."""
    lay = _LAYOUTS.get(s)
    if lay is None:
        idx = np.arange(s * s).reshape(s, s)  # idx[i, p]
        item = np.repeat(np.arange(s), s)
        pos = np.tile(np.arange(s), s)
        onehot = ((item[:, None] == item[None, :]) | (pos[:, None] == pos[None, :])).astype(np.float64)
        np.fill_diagonal(onehot, 0.0)
        i, j, p = np.meshgrid(np.arange(s), np.arange(s), np.arange(s - 1), indexing="ij")
        keep = i != j
        ii, jj, pp = i[keep], j[keep], p[keep]
        lay = (onehot, idx[ii, pp], idx[jj, pp + 1], ii, jj, idx[:, 0].copy(), idx[:, s - 1].copy())
        for a in lay:
            a.setflags(write=False)
        _LAYOUTS[s] = lay
    return lay


def decode_onehot(x: np.ndarray, s: int) -> tuple[int, ...] | None:
    """Permutation ``order[p] = item at position p`` or ``None`` if one-hot is violated."""
    m = np.asarray(x).reshape(s, s) != 0
    if not (np.all(m.sum(axis=0) == 1) and np.all(m.sum(axis=1) == 1)):
        return None
    return tuple(int(i) for i in np.argmax(m, axis=0))


def decode_onehot_batch(x: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised decode of ``(m, s*s)`` bit rows: ``(orders (m, s) int, valid (m,) bool)``."""
    m = np.asarray(x).reshape(-1, s, s) != 0
    valid = np.all(m.sum(axis=1) == 1, axis=1) & np.all(m.sum(axis=2) == 1, axis=1)
    orders = np.argmax(m, axis=1)
    return orders, valid


def path_cost(d: np.ndarray, order, entry: np.ndarray | None = None, exit_: np.ndarray | None = None) -> float:
    """``entry[o0] + sum d[o_k, o_k+1] + exit[o_last]`` of an item order."""
    order = np.asarray(order, dtype=np.int64)
    c = float(np.sum(d[order[:-1], order[1:]])) if len(order) > 1 else 0.0
    if entry is not None and len(order):
        c += float(entry[order[0]])
    if exit_ is not None and len(order):
        c += float(exit_[order[-1]])
    return c
