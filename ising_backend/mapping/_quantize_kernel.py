"""Compiled coefficient quantization (the kernels behind :mod:`.quantize`).

Contract: :func:`quantize_rules` computes :func:`.quantize.quantize` of one model under several rules in
one call and :func:`saturate_arrays` is :func:`.quantize.saturate` elementwise, both bit-identical to
the numpy oracle in ``tests/mapping_reference.py``.
Design notes (how bit-identity is kept): docs/design/mapping_kernels.md.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ising_backend.mapping.numeric import ising_of_qubo

__all__ = ["RULE_IDS", "QUANT_OK", "QUANT_NONFINITE", "quantize_rules", "saturate_arrays", "integer_program"]

#: quantization rule name -> rule id of the kernel (the order of ``QUANTIZE_RULES``)
RULE_IDS = {"linear": 0, "clip95": 1, "rank": 2, "sqrt": 3}

#: status codes of :func:`quantize_rules` (per rule)
QUANT_OK = 0
#: a result is not finite: a non-zero coefficient so small that its magnitude
#: relative to the range underflows to 0 (the validating model constructor names it)
QUANT_NONFINITE = 1


@numba.njit(cache=True, inline="always")
def _sign(x):
    """``np.sign`` of a non-NaN float (``sign(-0.0) = +0.0``)."""
    return 1.0 if x > 0 else (-1.0 if x < 0 else 0.0)


@numba.njit(cache=True, inline="always")
def _clip(x, lo, hi):
    """``np.clip(x, lo, hi)`` of a float: ``min(max(x, lo), hi)``, keeping ``x`` (and its zero sign) on a tie."""
    y = lo if x < lo else x
    return hi if y > hi else y


@numba.njit(cache=True)
def _percentile(sorted_vals, p):
    """``np.percentile(vals, p)`` with numpy's default ``"linear"`` method, from sorted values."""
    m = sorted_vals.shape[0]
    vi = (m - 1) * (p / 100.0)
    if vi >= m - 1:
        return sorted_vals[m - 1]
    lo = np.floor(vi)
    g = vi - lo
    a = sorted_vals[int(lo)]
    b = sorted_vals[int(lo) + 1]
    d = b - a
    if g >= 0.5:
        return b - d * (1.0 - g)
    return a + d * g


_SMALL_SORT = 128  # value counts sorted by insertion in the work arrays (no sort buffers); above: np.argsort


@numba.njit(cache=True, inline="always")
def _before(a, b):
    """``a`` sorts before ``b`` as numpy sorts floats (NaN last)."""
    return a < b or (b != b and a == a)


@numba.njit(cache=True)
def _sort_values(vals, m, out, order):
    """``out[:m]`` = ``vals[:m]`` sorted as ``np.sort`` sorts them and ``order[:m]`` a permutation
    with ``vals[order] == out`` (ties in any order), by insertion."""
    for u in range(m):
        x = vals[u]
        j = u - 1
        while j >= 0 and _before(x, out[j]):
            out[j + 1] = out[j]
            order[j + 1] = order[j]
            j -= 1
        out[j + 1] = x
        order[j + 1] = u


@numba.njit(cache=True)
def _scale_to_unit(c):
    """Scale ``c`` in place by the power of four that brings its largest magnitude into [1/4, 1):
    exact, and it changes no rule's result (each is a ratio of the scaled values, and a square root
    halves a power of four exactly), but relative sizes of tiny coefficients no longer underflow to 0
    (``[5e-324]`` quantizes to the limit instead of 0 / 0).  Non-finite values are left to the caller."""
    top = 0.0
    for t in range(c.shape[0]):
        top = max(top, abs(c[t]))
    if top == 0.0 or not np.isfinite(top):
        return
    e = math.frexp(top)[1]
    for t in range(c.shape[0]):  # ldexp: exact, and no overflow of the factor for subnormal tops
        c[t] = math.ldexp(c[t], -(e + (e & 1)))


@numba.njit(cache=True, error_model="numpy")  # IEEE division (x / 0), as numpy
def quantize_rules(h, J, rules, Lh, Lj, keep_sign, percentile):
    """Quantize one model (``h (n,)``, ``J (n, n)`` upper triangular, float64) under ``rules``.

    Args:
        rules: ``(k,)`` int64 rule ids (see :data:`RULE_IDS`).  Lh, Lj: the symmetric
        range limits (>= 1); keep_sign: non-zero coefficients never round to 0;
        percentile: the clip point of ``clip95`` in (0, 100].

    Returns ``(status (k,) int64, h (k, n) float64, J (k, n, n) float64)``; ``J`` is
    strictly upper triangular.  A rule with status ``QUANT_NONFINITE`` holds NaN.
    """
    n = h.shape[0]
    k = rules.shape[0]
    L = n + n * (n - 1) // 2
    work = np.empty(7 * L)  # c, lim, q, v, rel, rel0, sorted |c| / limit (views: one allocation)
    iwork = np.empty(3 * L, dtype=np.int64)  # nzi, level, order
    c = work[:L]
    lim = work[L: 2 * L]
    t = 0
    for i in range(n):
        c[t] = h[i]
        lim[t] = Lh
        t += 1
    for i in range(n):
        for j in range(i + 1, n):
            c[t] = J[i, j]
            lim[t] = Lj
            t += 1
    _scale_to_unit(c)
    nzi = iwork[:L]
    m = 0
    for t in range(L):
        if c[t] != 0:
            nzi[m] = t
            m += 1
    status = np.zeros(k, dtype=np.int64)
    out_h = np.zeros((k, n))
    out_J = np.zeros((k, n, n))
    q = work[2 * L: 3 * L]
    q[:] = 0.0
    v = work[3 * L: 4 * L]
    rel = work[4 * L: 4 * L + m]
    # |c| / limit of the non-zero coefficients, sorted once for rank and clip95 (both rules see
    # exactly these values); rank also needs each value's level among the distinct ones
    rel0 = work[5 * L: 5 * L + m]
    for u in range(m):
        rel0[u] = abs(c[nzi[u]]) / lim[nzi[u]]
    need_rank = False
    need_sorted = False
    for r in range(k):
        need_rank |= rules[r] == 2
        need_sorted |= rules[r] == 1 or rules[r] == 2
    level = iwork[L: L + m]
    level[:] = 0
    top = 0  # the highest level
    sorted0 = rel0
    if m > 0 and need_sorted:
        if m <= _SMALL_SORT:
            sorted0 = work[6 * L: 6 * L + m]
            order = iwork[2 * L: 2 * L + m]
            _sort_values(rel0, m, sorted0, order)
        else:
            order = np.argsort(rel0)
            sorted0 = rel0[order]
        if need_rank:  # ties share a level, so any order of equal values gives the same levels
            for u in range(1, m):
                if sorted0[u] != sorted0[u - 1]:
                    top += 1
                level[order[u]] = top
    for r in range(k):
        rule = rules[r]
        if m == 0:
            q[:] = 0.0
        elif rule == 2:  # rank: level of |c| / limit among the distinct values, spread over 1..limit
            q[:] = 0.0
            for u in range(m):
                t = nzi[u]
                frac = level[u] / top if top > 0 else 1.0
                q[t] = _sign(c[t]) * np.rint(1.0 + (lim[t] - 1.0) * frac)
        else:  # linear / clip95 / sqrt: one factor, round, clip
            for t in range(L):
                v[t] = _sign(c[t]) * np.sqrt(abs(c[t])) if rule == 3 else c[t]
            if rule == 1:
                a = _percentile(sorted0, percentile)
            else:
                for u in range(m):
                    rel[u] = abs(v[nzi[u]]) / lim[nzi[u]]
                a = rel.max()
            for t in range(L):
                q[t] = _clip(np.rint(v[t] / a), -lim[t], lim[t])
        if keep_sign:
            for u in range(m):
                t = nzi[u]
                if q[t] == 0:
                    q[t] = _sign(c[t])
        t = 0
        for i in range(n):
            out_h[r, i] = q[t]
            t += 1
        for i in range(n):
            for j in range(i + 1, n):
                out_J[r, i, j] = q[t]
                t += 1
        for t in range(L):
            if not np.isfinite(q[t]):
                status[r] = QUANT_NONFINITE
    return status, out_h, out_J


@numba.njit(cache=True)
def saturate_arrays(h, J, scale, h_lo, h_hi, j_lo, j_hi):
    """``clip(rint(scale * c), lo, hi)`` of every entry of ``h (n,)`` and ``J (n, n)`` (float64 bounds)."""
    n = h.shape[0]
    out_h = np.empty(n)
    out_J = np.empty((n, n))
    for i in range(n):
        out_h[i] = _clip(np.rint(h[i] * scale), h_lo, h_hi)
        for j in range(n):
            out_J[i, j] = _clip(np.rint(J[i, j] * scale), j_lo, j_hi)
    return out_h, out_J


@numba.njit(cache=True, nogil=True)
def integer_program(q, n, h, J, limits):
    """The chip program of the integer QUBO ``q[:n, :n]`` (linear terms on the diagonal, pairs above it): its
    Ising model (:func:`~ising_backend.mapping.numeric.ising_of_qubo`) scaled by one factor so that max ``|h|`` reaches
    ``limits[0]`` or max ``|J|`` ``limits[1]`` (each maximum taken as at least 1/4, a QUBO unit), rounded half
    away from zero into ``h[:n]``, ``J[:n, :n]`` (the rest zeroed); returns the factor."""
    lin = np.empty(n)
    pairs = np.zeros((n, n))
    for i in range(n):
        lin[i] = q[i, i]
        for j in range(i + 1, n):
            pairs[i, j] = q[i, j]
    hf, Jf, _offset = ising_of_qubo(lin, pairs, 0.0)
    top_h = 0.25
    top_j = 0.25
    for i in range(n):
        top_h = max(top_h, abs(hf[i]))
        for j in range(i + 1, n):
            top_j = max(top_j, abs(Jf[i, j]))
    lim_h, lim_j = limits
    s = min(lim_h / top_h, lim_j / top_j)
    h[:] = 0
    J[:, :] = 0
    for i in range(n):
        h[i] = np.sign(hf[i]) * np.floor(abs(hf[i]) * s + 0.5)
        for j in range(i + 1, n):
            J[i, j] = np.sign(Jf[i, j]) * np.floor(abs(Jf[i, j]) * s + 0.5)
    return s
