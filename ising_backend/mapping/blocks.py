"""Block batching (paper section 4.3): several independent programs in one chip program.

Contract: :func:`pack_blocks` places programs on disjoint spin blocks with zero cross-block couplings
(the packed energy is the sum of the block energies) and :func:`unpack_blocks` cuts the spins back;
:func:`pack_layout` (compiled, the one implementation) groups program sizes first-fit decreasing into
programs of ``capacity`` spins, :func:`plan_packs` gives its grouping as lists, :func:`fill_packs`
places the programs.  Oracle: ``tests/mapping_reference.py``.  Design notes: docs/design/mapping_kernels.md.
"""

from __future__ import annotations

from typing import Sequence

import numba
import numpy as np

from ising_backend.models import IsingModel
from ising_backend.machines.programs import stack_programs

__all__ = ["pack_blocks", "unpack_blocks", "plan_packs", "checked_layout", "pack_layout", "fill_packs"]


def pack_blocks(models: Sequence[IsingModel], n_spins: int | None = None) -> tuple[IsingModel, list[slice]]:
    """Block-diagonal program of ``models`` and each model's spin slice.

    Raises ``ValueError`` if the total exceeds ``n_spins`` (when given).
    """
    sizes = np.array([m.n for m in models], dtype=np.int64)
    total = int(sizes.sum())
    if n_spins is not None and total > n_spins:
        raise ValueError(f"blocks need {total} spins ({sizes.tolist()}); the program holds {n_spins}")
    h, J = stack_programs(models)
    h, J, where = fill_packs(h, J, sizes, np.arange(len(sizes)), np.zeros(len(sizes), dtype=np.int64), 1, total)
    slices = [slice(int(s0), int(s0) + int(n)) for s0, n in zip(where[:, 1], sizes)]
    return IsingModel(h[0], J[0], float(sum(m.offset for m in models))), slices


def unpack_blocks(spins, slices: Sequence[slice]) -> list[np.ndarray]:
    """Cut spins ``(..., n)`` back into per-block arrays ``(..., n_b)``."""
    s = np.asarray(spins)
    return [s[..., sl] for sl in slices]


def plan_packs(sizes: Sequence[int], capacity: int) -> list[list[int]]:
    """Group indices of ``sizes`` into packs of total <= ``capacity`` (first-fit decreasing,
    :func:`pack_layout`): one list per pack, ascending."""
    pack_of, order, n_packs, _width = checked_layout(np.array([int(v) for v in sizes], dtype=np.int64), capacity)
    packs: list[list[int]] = [[] for _ in range(n_packs)]
    for j in order.tolist():
        packs[int(pack_of[j])].append(j)
    return packs


def checked_layout(sizes: np.ndarray, capacity: int):
    """:func:`pack_layout` of int64 ``sizes``, after a ``ValueError`` naming the first program above ``capacity``."""
    for k, v in enumerate(sizes.tolist()):
        if v > capacity:
            raise ValueError(f"program {k} has {v} spins > capacity {capacity}")
    return pack_layout(sizes, int(capacity))


@numba.njit(cache=True)
def pack_layout(sizes, capacity):
    """First-fit decreasing of program ``sizes`` into packs of ``capacity`` spins, as arrays: ``(pack_of (P,),
    order (P,), n_packs, width)``.

    ``pack_of[j]`` is program ``j``'s pack (packs numbered in the order they are opened),
    ``order`` lists the programs pack by pack, ascending within a pack (the placement order),
    ``width`` is the fullest pack's total.  Sizes above ``capacity`` are the caller's to refuse.
    """
    P = sizes.shape[0]
    order = np.argsort(-sizes, kind="mergesort")  # stable: ties by index
    room = np.empty(P, dtype=np.int64)
    pack_of = np.empty(P, dtype=np.int64)
    n_packs = 0
    for j in order:
        placed = False
        for b in range(n_packs):
            if room[b] >= sizes[j]:
                pack_of[j] = b
                room[b] -= sizes[j]
                placed = True
                break
        if not placed:
            pack_of[j] = n_packs
            room[n_packs] = capacity - sizes[j]
            n_packs += 1
    within = np.empty(P, dtype=np.int64)
    k = 0
    width = 0
    for b in range(n_packs):
        total = 0
        for j in range(P):
            if pack_of[j] == b:
                within[k] = j
                k += 1
                total += sizes[j]
        width = max(width, total)
    return pack_of, within, n_packs, width


@numba.njit(cache=True)
def fill_packs(qh, qJ, prog_sizes, order, pack_of, n_packs, width):
    """The chip programs of one submission: program ``j`` (``qh[j, :n]``, ``qJ[j, :n, :n]``, ``n =
    prog_sizes[j]``) placed block-diagonally in pack ``pack_of[j]``, programs taken in ``order``
    (each after those placed in its pack before it).  Returns ``(h (n_packs, width), J (n_packs,
    width, width), where (programs, 2))`` (the inputs' dtypes) with ``where[j]`` = (pack, first spin)."""
    h = np.zeros((n_packs, width), dtype=qh.dtype)
    J = np.zeros((n_packs, width, width), dtype=qJ.dtype)
    fill = np.zeros(n_packs, dtype=np.int64)
    where = np.zeros((prog_sizes.shape[0], 2), dtype=np.int64)
    for j in order:
        b = pack_of[j]
        s0 = fill[b]
        n = prog_sizes[j]
        for i in range(n):
            h[b, s0 + i] = qh[j, i]
            for t in range(n):
                J[b, s0 + i, s0 + t] = qJ[j, i, t]
        where[j, 0] = b
        where[j, 1] = s0
        fill[b] = s0 + n
    return h, J, where
