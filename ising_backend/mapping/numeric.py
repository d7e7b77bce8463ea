"""numpy's float summation order in compiled code, so compiled host kernels give numpy's bits.

``np.add.reduce`` over a contiguous float64 run is a *pairwise* sum (blocks of 8 partial
sums up to 128 elements, halving beyond).  :func:`pairwise_sum` reproduces it exactly, so a
kernel that sums like ``a.sum()`` / ``M.sum(axis=1)`` returns the same bits as the numpy
code it replaces (checked on random arrays in the tests).  :func:`ising_of_qubo` is the one
compiled QUBO-to-Ising step, with :func:`~ising_backend.models.ising_from_qubo`'s arithmetic.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["pairwise_sum", "ising_of_qubo"]


@numba.njit(cache=True)
def _block_sum(a, lo, n):
    """numpy's pairwise sum of a run of at most 128 elements (8 partial sums)."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0 = a[lo]
    r1 = a[lo + 1]
    r2 = a[lo + 2]
    r3 = a[lo + 3]
    r4 = a[lo + 4]
    r5 = a[lo + 5]
    r6 = a[lo + 6]
    r7 = a[lo + 7]
    i = 8
    while i < n - (n % 8):
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@numba.njit(cache=True)
def pairwise_sum(a, lo, n):
    """``a[lo:lo + n].sum()`` in numpy's order (``a`` float64, 1-d).

    Runs above 128 elements split in halves (the first a multiple of 8) as numpy does;
    the recursion is unrolled onto an explicit stack (numba caches no recursive functions).
    """
    if n <= 128:
        return _block_sum(a, np.int64(lo), np.int64(n))  # int64, not a literal 0: one specialization
    f_lo = np.empty(64, dtype=np.int64)
    f_n = np.empty(64, dtype=np.int64)
    f_stage = np.zeros(64, dtype=np.int64)
    f_left = np.zeros(64)
    sp = 0
    f_lo[0] = lo
    f_n[0] = n
    f_stage[0] = 0
    val = 0.0
    while sp >= 0:
        m = f_n[sp]
        n2 = m // 2
        n2 -= n2 % 8
        if m <= 128:
            val = _block_sum(a, f_lo[sp], m)
            sp -= 1
        elif f_stage[sp] == 0:
            f_stage[sp] = 1
            sp += 1
            f_lo[sp] = f_lo[sp - 1]
            f_n[sp] = n2
            f_stage[sp] = 0
            continue
        elif f_stage[sp] == 1:
            f_left[sp] = val
            f_stage[sp] = 2
            sp += 1
            f_lo[sp] = f_lo[sp - 1] + n2
            f_n[sp] = m - n2
            f_stage[sp] = 0
            continue
        else:
            val = f_left[sp] + val
            sp -= 1
    return val


@numba.njit(cache=True)
def ising_of_qubo(q, Q, offset):
    """``(h, J, offset)`` of the QUBO ``q.x + x.Q.x + offset`` (``Q`` strictly upper) with
    :func:`~ising_backend.models.ising_from_qubo`'s arithmetic (numpy's summation order), so the
    same bits as the host's conversion."""
    n = q.shape[0]
    h = np.empty(n)
    J = np.empty((n, n))
    row = np.empty(n)
    flat = np.empty(n * n)
    for i in range(n):
        for j in range(n):
            row[j] = Q[i, j] + Q[j, i]
            J[i, j] = Q[i, j] / 4.0
            flat[i * n + j] = Q[i, j]
        h[i] = q[i] / 2.0 + pairwise_sum(row, 0, n) / 4.0
    return h, J, offset + pairwise_sum(q, 0, n) / 2.0 + pairwise_sum(flat, 0, n * n) / 4.0
