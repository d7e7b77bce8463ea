"""Spin-budget branching (paper section 4.2, used by tour construction in 5.2).

Contract: :func:`branch` splits a model above the spin budget into ``2^k`` models of ``budget`` spins by
freezing ``k = n - budget`` spins (by default those of largest ``|h_i| + sum_j |J_ij|``) to every sign
pattern; a branch's energy is the full model's energy of the completed assignment, so the best branch's
optimum is the model's.  The compiled :func:`frozen_spins` and :func:`branch_stack` are the one
implementation (oracle: ``tests/mapping_reference.py``).  Design notes: docs/design/mapping_kernels.md.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from ising_backend.models import IsingModel
from ising_backend.mapping.numeric import pairwise_sum

__all__ = ["Branch", "branch", "freeze_order", "BranchError", "frozen_spins", "branch_stack", "freeze_strength"]


class BranchError(ValueError):
    """Branching request cannot be met (too many frozen spins, bad indices)."""


@dataclass(frozen=True, eq=False)
class Branch:
    """One reduced model: free spins ``free`` (sorted), frozen spins ``frozen`` at ``values``."""

    model: IsingModel
    free: np.ndarray
    frozen: np.ndarray
    values: np.ndarray
    n_total: int

    def decode(self, spins) -> np.ndarray:
        """Free-spin assignment ``(..., n_free)`` (trailing padding allowed) -> full ``(..., n_total)`` int8."""
        s = np.asarray(spins)
        if s.shape[-1] < self.free.size:
            raise ValueError(f"spins have {s.shape[-1]} entries; the branch has {self.free.size} free spins")
        out = np.empty(s.shape[:-1] + (self.n_total,), dtype=np.int8)
        out[..., self.free] = s[..., : self.free.size]
        out[..., self.frozen] = self.values
        return out


@numba.njit(cache=True)
def freeze_strength(h, J):
    """Each spin's ``|h_i| + sum_j |J_ij + J_ji|`` (numpy's summation order)."""
    n = h.shape[0]
    strength = np.empty(n)
    row = np.empty(n)
    for i in range(n):
        for j in range(n):
            row[j] = abs(J[i, j] + J[j, i])
        strength[i] = abs(h[i]) + pairwise_sum(row, 0, n)
    return strength


@numba.njit(cache=True)
def frozen_spins(h, J, k):
    """The ``k`` spins to freeze, sorted: by decreasing :func:`freeze_strength`, lowest index first on ties."""
    return np.sort(np.argsort(-freeze_strength(h, J), kind="mergesort")[:k])


@numba.njit(cache=True)
def branch_stack(h, J, offset, frozen):
    """Freeze spins ``frozen`` (distinct, in any order) at every sign pattern: branch ``m`` sets ``frozen[t]``
    to ``+1`` if bit ``t`` of ``m`` is set.  Returns ``(free, hb (2^k, nf), Jb (nf, nf), offsets (2^k,))``;
    the reduced couplings are the same for every branch."""
    n = h.shape[0]
    k = frozen.shape[0]
    is_frozen = np.zeros(n, dtype=np.bool_)
    for t in range(k):
        is_frozen[frozen[t]] = True
    nf = n - k
    free = np.empty(nf, dtype=np.int64)
    c = 0
    for i in range(n):
        if not is_frozen[i]:
            free[c] = i
            c += 1
    Jb = np.empty((nf, nf))
    for a in range(nf):
        for b in range(nf):
            Jb[a, b] = J[free[a], free[b]]
    nb = 1 << k
    hb = np.empty((nb, nf))
    offs = np.empty(nb)
    z = np.empty(k)
    for m in range(nb):
        for t in range(k):
            z[t] = 1.0 if (m >> t) & 1 else -1.0
        for a in range(nf):
            i = free[a]
            v = 0.0
            for t in range(k):
                f = frozen[t]
                v += (J[i, f] + J[f, i]) * z[t]
            hb[m, a] = h[i] + v
        e = 0.0
        for t in range(k):
            e += h[frozen[t]] * z[t]
        e2 = 0.0
        for t in range(k):
            for u in range(k):
                e2 += z[t] * J[frozen[t], frozen[u]] * z[u]
        offs[m] = offset + e + e2
    return free, hb, Jb, offs


def _writable(model: IsingModel) -> tuple[np.ndarray, np.ndarray]:
    """The model's (read-only) arrays as writable copies: the kernels' one specialization, the planners'."""
    return model.h.copy(), model.J.copy()


def freeze_order(model: IsingModel) -> np.ndarray:
    """Spins by decreasing ``|h_i| + sum_j |J_ij|`` (stable: lowest index first on ties)."""
    return np.argsort(-freeze_strength(*_writable(model)), kind="stable")


def branch(model: IsingModel, budget: int, frozen=None, max_frozen: int = 10) -> list[Branch]:
    """Split ``model`` into ``2^k`` branches of at most ``budget`` spins (``k = n - budget``).

    A model within budget gives one branch (itself, nothing frozen).  ``frozen``
    overrides the default choice (it must hold at least ``k`` distinct indices;
    all listed spins are frozen).  More than ``max_frozen`` frozen spins is refused.
    """
    budget = int(budget)
    if budget < 0:
        raise BranchError(f"budget = {budget} must be >= 0")
    k = max(0, model.n - budget)
    if frozen is None:
        frozen = frozen_spins(*_writable(model), k)
    else:
        frozen = np.asarray(frozen, dtype=np.int64).reshape(-1)
        if np.unique(frozen).size != frozen.size or (frozen.size and (frozen.min() < 0 or frozen.max() >= model.n)):
            raise BranchError(f"frozen = {frozen.tolist()} must be distinct spin indices in [0, {model.n})")
        if frozen.size < k:
            raise BranchError(f"{frozen.size} frozen spins leave {model.n - frozen.size} > budget {budget}")
    if frozen.size > max_frozen:
        raise BranchError(f"{frozen.size} frozen spins would make 2^{frozen.size} branches (max_frozen = {max_frozen})")
    free, hb, Jb, offs = branch_stack(*_writable(model), float(model.offset), frozen.astype(np.int64))
    labels = None if model.labels is None else tuple(model.labels[i] for i in free)
    out = []
    for m in range(2 ** frozen.size):
        values = np.array([1 if (m >> t) & 1 else -1 for t in range(frozen.size)], dtype=np.int8)
        out.append(Branch(IsingModel(hb[m], Jb, float(offs[m]), labels), free, frozen.copy(), values, model.n))
    return out
