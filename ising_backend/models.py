"""Ising and QUBO models with exact conversions (paper section 2.1, eqs. 1-2).

Contract: :class:`IsingModel` has energy ``E(s) = sum_i h_i s_i + sum_{i<j} J_ij s_i s_j + offset``
(``s_i in {-1, +1}``), :class:`QuboModel` ``E(x) = sum_i q_i x_i + sum_{i<j} Q_ij x_i x_j + offset``
(``x_i in {0, 1}``), both with strictly upper triangular matrices; conversions (``x = (1 + s) / 2``) keep
the offset, so a configuration has the same energy in both forms.  Entries below the diagonal are folded
onto the upper triangle, a non-zero diagonal is refused.  Design notes: docs/design/mapping_kernels.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Hashable, Sequence

import dimod
import numpy as np

__all__ = ["IsingModel", "QuboModel", "from_bqm", "ModelError"]


class ModelError(ValueError):
    """A model's arrays are malformed (shape, diagonal, NaN, labels)."""


def _as_upper(mat, n: int, name: str) -> np.ndarray:
    a = np.array(mat, dtype=np.float64, copy=True)
    if a.shape != (n, n):
        raise ModelError(f"{name} must have shape ({n}, {n}) to match the linear terms, got {a.shape}")
    d = np.diagonal(a)
    if np.any(d != 0):
        i = int(np.flatnonzero(d != 0)[0])
        raise ModelError(
            f"{name}[{i}, {i}] = {d[i]!r}: the diagonal must be zero (put self-terms in the offset / linear term)"
        )
    lower = np.tril(a, -1)
    if np.any(lower != 0):
        a = np.triu(a, 1) + lower.T
    return a


def _check_finite(arr: np.ndarray, name: str) -> None:
    bad = ~np.isfinite(arr)
    if np.any(bad):
        idx = tuple(int(v) for v in np.argwhere(bad)[0])
        raise ModelError(f"{name}{list(idx)} = {arr[idx].item()!r} is not finite")


def _labels(labels, n: int):
    if labels is None:
        return None
    labels = tuple(labels)
    if len(labels) != n:
        raise ModelError(f"labels has {len(labels)} entries for {n} variables")
    if len(set(labels)) != n:
        raise ModelError("labels must be unique")
    return labels


def _checked(lin, quad, offset, labels, lin_name: str, quad_name: str):
    """``(lin, quad, offset, labels)`` of a public construction: copied float64, ``quad`` folded upper,
    all finite, arrays read-only; a :class:`ModelError` names the first fault."""
    lin = np.array(lin, dtype=np.float64, copy=True).reshape(-1)
    quad = _as_upper(quad if np.size(quad) else np.zeros((lin.size, lin.size)), lin.size, quad_name)
    _check_finite(lin, lin_name)
    _check_finite(quad, quad_name)
    if not np.isfinite(offset):
        raise ModelError(f"offset = {offset!r} is not finite")
    lin.setflags(write=False)
    quad.setflags(write=False)
    return lin, quad, float(offset), _labels(labels, lin.size)


def _energy(values: np.ndarray, lin: np.ndarray, quad: np.ndarray, offset: float) -> np.ndarray | float:
    e = values @ lin + np.einsum("...i,ij,...j->...", values, quad, values) + offset
    return float(e) if np.ndim(e) == 0 else e


@dataclass(frozen=True, eq=False)
class IsingModel:
    """Ising model ``E(s) = h.s + sum_{i<j} J_ij s_i s_j + offset``.

    Args:
        h: ``(n,)`` local fields.
        J: ``(n, n)`` couplings, strictly upper triangular (lower entries are folded).
        offset: constant energy term.
        labels: optional variable labels (default ``0..n-1``).
    """

    h: np.ndarray
    J: np.ndarray
    offset: float = 0.0
    labels: tuple | None = field(default=None)

    def __post_init__(self):
        h, J, offset, labels = _checked(self.h, self.J, self.offset, self.labels, "h", "J")
        object.__setattr__(self, "h", h)
        object.__setattr__(self, "J", J)
        object.__setattr__(self, "offset", offset)
        object.__setattr__(self, "labels", labels)

    @classmethod
    def trusted(cls, h: np.ndarray, J: np.ndarray, offset: float = 0.0, labels: tuple | None = None) -> "IsingModel":
        """Build without validation, for internal code whose arrays are valid by construction.

        The caller guarantees what ``__init__`` would otherwise check or establish:
        ``h`` float64 ``(n,)``, ``J`` float64 ``(n, n)`` with zero diagonal and lower
        triangle, all finite, ``offset`` a finite float, ``labels`` ``None`` or a tuple
        of ``n`` unique labels.  The arrays are taken over (made read-only, not
        copied).  Public construction (``IsingModel(h, J, ...)``) keeps validating.
        """
        h.setflags(write=False)
        J.setflags(write=False)
        self = object.__new__(cls)
        self.__dict__.update(h=h, J=J, offset=offset, labels=labels)
        return self

    # ------------------------------------------------------------------ basics
    @property
    def n(self) -> int:
        """Number of spins."""
        return int(self.h.size)

    @property
    def variables(self) -> tuple:
        return self.labels if self.labels is not None else tuple(range(self.n))

    @property
    def J_sym(self) -> np.ndarray:
        """Symmetric coupling matrix ``J + J.T`` (zero diagonal)."""
        return self.J + self.J.T

    def energy(self, spins) -> np.ndarray | float:
        """Energy of ``spins`` (``(..., n)`` in {-1, +1}), vectorised over leading axes."""
        s = np.asarray(spins, dtype=np.float64)
        if s.shape[-1:] != (self.n,):
            raise ModelError(f"spins have trailing size {s.shape[-1:]} for a model of {self.n} spins")
        return _energy(s, self.h, self.J, self.offset)

    def is_integer(self) -> bool:
        return bool(np.all(self.h == np.round(self.h)) and np.all(self.J == np.round(self.J)))

    def max_abs(self) -> tuple[float, float]:
        """``(max |h|, max |J|)`` (0 for empty)."""
        return (float(np.max(np.abs(self.h))) if self.n else 0.0,
                float(np.max(np.abs(self.J))) if self.n > 1 else 0.0)

    def scaled(self, factor: float) -> "IsingModel":
        """All coefficients and the offset multiplied by ``factor``."""
        return IsingModel(self.h * factor, self.J * factor, self.offset * factor, self.labels)

    def relabel(self, labels) -> "IsingModel":
        return IsingModel(self.h, self.J, self.offset, labels)

    # ------------------------------------------------------------- conversions
    def to_qubo(self) -> "QuboModel":
        """Exact QUBO with ``s = 2x - 1`` (same energy for every configuration)."""
        Js = self.J_sym
        Q = 4.0 * self.J
        q = 2.0 * self.h - 2.0 * Js.sum(axis=1)
        offset = self.offset - self.h.sum() + self.J.sum()
        return QuboModel(q, Q, offset, self.labels)

    def to_ising(self) -> "IsingModel":
        return self

    def to_bqm(self) -> dimod.BinaryQuadraticModel:
        """A SPIN-vartype :class:`dimod.BinaryQuadraticModel` with the model's labels."""
        return _to_bqm(self.h, self.J, self.offset, self.variables, dimod.SPIN)

    @classmethod
    def from_bqm(cls, bqm: dimod.BinaryQuadraticModel, variables: Sequence[Hashable] | None = None) -> "IsingModel":
        """From a BQM of either vartype (converted exactly to SPIN); variable order = ``variables`` or the BQM's."""
        if bqm.vartype is dimod.BINARY:
            return QuboModel.from_bqm(bqm, variables).to_ising()
        h, J, off, labels = _from_bqm(bqm, variables)
        return cls(h, J, off, labels)

    def __repr__(self) -> str:
        return f"IsingModel(n={self.n}, offset={self.offset})"


@dataclass(frozen=True, eq=False)
class QuboModel:
    """QUBO ``E(x) = q.x + sum_{i<j} Q_ij x_i x_j + offset`` with ``x in {0, 1}``."""

    q: np.ndarray
    Q: np.ndarray
    offset: float = 0.0
    labels: tuple | None = field(default=None)

    def __post_init__(self):
        q, Q, offset, labels = _checked(self.q, self.Q, self.offset, self.labels, "q", "Q")
        object.__setattr__(self, "q", q)
        object.__setattr__(self, "Q", Q)
        object.__setattr__(self, "offset", offset)
        object.__setattr__(self, "labels", labels)

    @property
    def n(self) -> int:
        return int(self.q.size)

    @property
    def variables(self) -> tuple:
        return self.labels if self.labels is not None else tuple(range(self.n))

    def energy(self, x) -> np.ndarray | float:
        """Energy of bits ``x`` (``(..., n)`` in {0, 1}), vectorised over leading axes."""
        b = np.asarray(x, dtype=np.float64)
        if b.shape[-1:] != (self.n,):
            raise ModelError(f"bits have trailing size {b.shape[-1:]} for a model of {self.n} variables")
        return _energy(b, self.q, self.Q, self.offset)

    def to_ising(self) -> IsingModel:
        """Exact Ising model with ``x = (1 + s) / 2`` (same energy for every configuration)."""
        m = ising_from_qubo(self.q, self.Q, self.offset)
        return IsingModel(m.h, m.J, m.offset, self.labels)

    def to_qubo(self) -> "QuboModel":
        return self

    def to_bqm(self) -> dimod.BinaryQuadraticModel:
        return _to_bqm(self.q, self.Q, self.offset, self.variables, dimod.BINARY)

    @classmethod
    def from_bqm(cls, bqm: dimod.BinaryQuadraticModel, variables: Sequence[Hashable] | None = None) -> "QuboModel":
        if bqm.vartype is dimod.SPIN:
            return IsingModel.from_bqm(bqm, variables).to_qubo()
        q, Q, off, labels = _from_bqm(bqm, variables)
        return cls(q, Q, off, labels)

    def __repr__(self) -> str:
        return f"QuboModel(n={self.n}, offset={self.offset})"


def _to_bqm(lin, quad, offset, variables, vartype) -> dimod.BinaryQuadraticModel:
    bqm = dimod.BinaryQuadraticModel(vartype)
    bqm.add_variables_from((v, float(b)) for v, b in zip(variables, lin))
    ii, jj = np.nonzero(quad)
    bqm.add_interactions_from((variables[i], variables[j], float(quad[i, j])) for i, j in zip(ii, jj))
    bqm.offset = float(offset)
    return bqm


def _from_bqm(bqm, variables):
    order = list(bqm.variables) if variables is None else list(variables)
    if set(order) != set(bqm.variables) or len(order) != len(bqm.variables):
        raise ModelError("variables must list exactly the BQM's variables")
    index = {v: k for k, v in enumerate(order)}
    n = len(order)
    lin = np.array([bqm.get_linear(v) for v in order], dtype=np.float64)
    quad = np.zeros((n, n))
    for (u, v), b in bqm.quadratic.items():
        i, j = index[u], index[v]
        if i > j:
            i, j = j, i
        quad[i, j] += b
    labels = tuple(order)
    if labels == tuple(range(n)):
        labels = None
    return lin, quad, float(bqm.offset), labels


def from_bqm(bqm: dimod.BinaryQuadraticModel, variables=None) -> IsingModel | QuboModel:
    """:class:`IsingModel` for a SPIN BQM, :class:`QuboModel` for a BINARY one."""
    if bqm.vartype is dimod.SPIN:
        return IsingModel.from_bqm(bqm, variables)
    return QuboModel.from_bqm(bqm, variables)


def ising_from_qubo(q: np.ndarray, Q: np.ndarray, offset: float = 0.0) -> IsingModel:
    """``QuboModel(q, Q, offset).to_ising()`` without validation, for internal model builders whose
    ``q`` (float64 ``(n,)``) and ``Q`` (float64 ``(n, n)``, strictly upper triangular) are finite by
    construction; the same arithmetic, so the same bits."""
    Qs = Q + Q.T
    J = Q / 4.0
    h = q / 2.0 + Qs.sum(axis=1) / 4.0
    return IsingModel.trusted(h, J, float(offset + q.sum() / 2.0 + Q.sum() / 4.0))
