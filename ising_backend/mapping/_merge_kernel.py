"""Compiled spin merging and copy decoding (the kernels behind :mod:`.merge`).

Contract: :func:`merge_styles` (one model, several styles), :func:`merge_batch` (several zero-padded
models) and :func:`merge_styles_flat` (into a caller's buffers) reproduce :func:`.merge.merge_spins`
bit for bit; :func:`decode_copies` decodes physical spins of many (program, read) samples through a
flat copy layout (``ptr`` / ``idx``).  Plain ``@njit(cache=True)`` functions, callable from numba code.
Oracle: ``tests/mapping_reference.py``.  Design notes: docs/design/mapping_kernels.md.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

__all__ = [
    "Merged",
    "STYLE_IDS", "MERGE_OK", "MERGE_FIELD_UNFIT", "MERGE_COUPLING_UNFIT", "MERGE_TOO_MANY_SPINS",
    "merge_batch", "merge_styles", "merge_styles_flat", "decode_copies",
]

#: merge style name -> style id of the kernels (the order of ``MERGE_STYLES``)
STYLE_IDS = {"overload": 0, "max_coeff": 1, "high_degree": 2, "balanced": 3}

#: status codes of :func:`merge_styles` (per style)
MERGE_OK = 0
#: the spin budget ran out; ``err = (i, -1)``: field ``H[i]`` still exceeds ``Lh * a[i]``
MERGE_FIELD_UNFIT = 1
#: the spin budget ran out; ``err = (i, j)``: coupling ``C[i, j]`` exceeds ``Lj * a[i] * a[j]``
MERGE_COUPLING_UNFIT = 2
#: the logical model alone has more spins than the chip (``n > n_spins``); ``err = (n, n_spins)``
MERGE_TOO_MANY_SPINS = 3

_EVEN = (False, True, False, True)  # split mode per style id: spill (False) or even (True)


@numba.njit(cache=True)
def _over_pairs(C, b, n, Lj, out):
    """The couplings ``i < j`` of model ``b`` above one copy's capacity (``|C_ij| > Lj``) as
    ``i * n + j``, row-major; returns their count.  No other coupling ever exceeds its capacity
    ``Lj a_i a_j`` (copies only raise it), so the duplication loop scans these alone."""
    m = 0
    for i in range(n):
        for j in range(i + 1, n):
            if abs(C[b, i, j]) > Lj:
                out[m] = i * n + j
                m += 1
    return m


@numba.njit(cache=True)
def _copy_counts(H, C, b, n, style, limits, spin_stats, pairs, a, err, work):
    """The duplication loop of one style on model ``b`` (``n`` spins): copy counts into ``a``;
    returns a status code.  ``limits`` = ``(Lh, Lj, n_spins)``; ``spin_stats`` = ``(degree,
    strength)`` (:func:`_spin_stats`); ``pairs`` = ``(over, n_over)``: ``over[:n_over]`` are
    :func:`_over_pairs` of the model; ``work`` = ``(excess, exj, pex)``: work arrays (at least
    ``n``, ``n``, ``n_over``).

    Each round recomputes, as the reference does, the excess of every field
    (``|H_i| - Lh a_i``) and coupling (``|C_ij| - Lj a_i a_j``), the per-spin total
    excess (float64: ``float(field excess) + float(coupling excesses)``), and adds
    one copy to the spin the style picks.  Couplings outside ``over`` have no excess, so every
    scan over pairs visits ``over`` alone, in the reference's row-major order.
    """
    Lh, Lj, n_spins = limits
    degree, strength = spin_stats
    over, n_over = pairs
    excess, exj, pex = work
    for i in range(n):
        a[i] = 1
    if n > n_spins:
        err[0] = n
        err[1] = n_spins
        return MERGE_TOO_MANY_SPINS
    used = n
    for i in range(n):
        exj[i] = 0
    # integral limits: the coupling excesses are integers, kept per pair and updated for the
    # copied spin's pairs only (the same sums as recomputing them every round)
    incremental = Lj == np.floor(Lj)
    n_bad = 0
    if incremental:
        for t in range(n_over):
            i, j = over[t] // n, over[t] % n
            e = abs(C[b, i, j]) - Lj * a[i] * a[j]
            if e > 0:
                pex[t] = e
                n_bad += 1
                exj[i] += e
                exj[j] += e
            else:
                pex[t] = 0
    while True:
        bad_h = False
        bad_j = n_bad > 0
        if not incremental:
            for i in range(n):
                exj[i] = 0
            for t in range(n_over):
                i, j = over[t] // n, over[t] % n
                e = abs(C[b, i, j]) - Lj * a[i] * a[j]
                if e > 0:
                    bad_j = True
                    exj[i] += e
                    exj[j] += e
        for i in range(n):
            e = abs(H[b, i]) - Lh * a[i]
            if e > 0:
                bad_h = True
            else:
                e = 0
            excess[i] = np.float64(e) + np.float64(exj[i])
        if not (bad_h or bad_j):
            return MERGE_OK
        if used >= n_spins:  # budget exhausted: name the worst remaining term
            if bad_h:
                bi = 0
                best = -1
                for i in range(n):
                    e = abs(H[b, i]) - Lh * a[i]
                    v = e if e > 0 else -1
                    if v > best:
                        best = v
                        bi = i
                err[0] = bi
                err[1] = -1
                return MERGE_FIELD_UNFIT
            best = 0
            bi = 0
            bj = 0
            for t in range(n_over):
                i, j = over[t] // n, over[t] % n
                e = abs(C[b, i, j]) - Lj * a[i] * a[j]
                if e > best:
                    best = e
                    bi = i
                    bj = j
            err[0] = bi
            err[1] = bj
            return MERGE_COUPLING_UNFIT
        pick = 0
        if style == 0:  # overload: largest total excess
            best_f = excess[0]
            for i in range(1, n):
                if excess[i] > best_f:
                    best_f = excess[i]
                    pick = i
        elif style == 1:  # max_coeff: an endpoint of the worst term by |c| / capacity
            rh = 0.0
            ih = 0
            for i in range(n):
                cap = Lh * a[i]
                r = abs(H[b, i]) / cap if abs(H[b, i]) > cap else 0.0
                if r > rh:
                    rh = r
                    ih = i
            rj = 0.0
            ii = 0
            jj = 0
            for t in range(n_over):
                i, j = over[t] // n, over[t] % n
                cap = Lj * a[i] * a[j]
                r = abs(C[b, i, j]) / max(cap, 1) if abs(C[b, i, j]) > cap else 0.0
                if r > rj:
                    rj = r
                    ii = i
                    jj = j
            if rh >= rj:
                pick = ih
            elif a[ii] < a[jj] or (a[ii] == a[jj] and strength[ii] >= strength[jj]):
                pick = ii  # (a, -strength, index) lexicographic; ii < jj
            else:
                pick = jj
        elif style == 2:  # high_degree: most non-zero couplings among involved spins
            best_f = -np.inf
            for i in range(n):
                k = np.float64(degree[i]) * 1e6 + excess[i] if excess[i] > 0 else -1.0
                if k > best_f:
                    best_f = k
                    pick = i
        else:  # balanced: fewest copies among involved spins, then largest excess
            best_f = -np.inf
            first = True
            for i in range(n):
                k = np.float64(-a[i]) * 1e9 + excess[i] if excess[i] > 0 else -np.inf
                if first or k > best_f:
                    best_f = k
                    pick = i
                    first = False
        a[pick] += 1
        used += 1
        if incremental:  # the copied spin's couplings have a larger capacity now
            for t in range(n_over):
                old = pex[t]
                if old > 0:
                    lo, hi = over[t] // n, over[t] % n
                    if lo != pick and hi != pick:
                        continue
                    e = abs(C[b, lo, hi]) - Lj * a[lo] * a[hi]
                    new = np.int64(e) if e > 0 else np.int64(0)
                    exj[lo] += new - old
                    exj[hi] += new - old
                    pex[t] = new
                    if new == 0:
                        n_bad -= 1


@numba.njit(cache=True, inline="always")
def _piece(total, k, m, lim, even):
    """Piece ``m`` of splitting integer ``total`` into ``k`` pieces of magnitude <= ``lim``."""
    t = abs(total)
    if even:
        p = t // k + (1 if m < t % k else 0)
    else:  # spill: fill the first slots up to the limit
        p = min(lim, max(0, t - m * lim))
    return p if total >= 0 else -p


@numba.njit(cache=True, inline="always")
def _phys(i, m, start):
    """Physical index of copy ``m`` of logical spin ``i`` (copy 0 is the original)."""
    return i if m == 0 else start[i] + m - 1


@numba.njit(cache=True)
def _fill(H, C, b, n, a, even, Lh, Lj, tie, start, hp, Jp):
    """Physical ``hp`` / ``Jp`` (zeroed on entry) of model ``b`` from the copy counts;
    returns the number of ties."""
    for i in range(n):
        if a[i] == 1:
            hp[i] = H[b, i]
        else:
            for m in range(a[i]):
                hp[_phys(i, m, start)] = _piece(H[b, i], a[i], m, Lh, even)
    for i in range(n):
        for j in range(i + 1, n):
            c = C[b, i, j]
            if a[i] == 1 and a[j] == 1:
                Jp[i, j] = c
            elif c != 0:  # spread over the copy pairs (p over i's copies, q over j's)
                k = a[i] * a[j]
                for pi in range(a[i]):
                    p = _phys(i, pi, start)
                    for qi in range(a[j]):
                        q = _phys(j, qi, start)
                        v = _piece(c, k, pi * a[j] + qi, Lj, even)
                        if p < q:
                            Jp[p, q] += v
                        else:
                            Jp[q, p] += v
    n_ties = 0
    for i in range(n):
        for x in range(a[i]):
            p = _phys(i, x, start)
            for y in range(x + 1, a[i]):
                q = _phys(i, y, start)
                if p < q:
                    Jp[p, q] = -tie
                else:
                    Jp[q, p] = -tie
                n_ties += 1
    return n_ties


@numba.njit(cache=True)
def _spin_stats(C, b, n, degree, strength):
    """Per spin of model ``b``: its non-zero couplings and total ``|coupling|`` (``|C| + |C|.T``)."""
    for i in range(n):
        degree[i] = 0
        strength[i] = 0
        for j in range(n):
            v = abs(C[b, i, j]) + abs(C[b, j, i])
            degree[i] += v != 0
            strength[i] += v


@numba.njit(cache=True)
def _layout(a, n, start, ptr, idx):
    """The copy layout of one mapping from its copy counts ``a``: ``start[i]`` (the physical index of
    spin ``i``'s first extra copy), ``ptr[: n + 1]`` and ``idx[: a.sum()]`` (module docstring)."""
    nxt = n
    ptr[0] = 0
    for i in range(n):
        start[i] = nxt
        nxt += a[i] - 1
        ptr[i + 1] = ptr[i] + a[i]
        for m in range(a[i]):
            idx[ptr[i] + m] = _phys(i, m, start)


class Merged(NamedTuple):
    """:func:`merge_batch`'s result, one row per (model, style), row ``r = b * k + s``."""

    status: np.ndarray  # (R,) MERGE_* codes
    err: np.ndarray  # (R, 2) the term that did not fit (-1 unused)
    a: np.ndarray  # (R, n_max) copy counts (at the failure for a failed row, 0 beyond the model)
    n_phys: np.ndarray  # (R,) physical spins (0 if failed)
    h: np.ndarray  # (R, N) float64, zero-padded to N = max(n_phys)
    J: np.ndarray  # (R, N, N) float64, upper triangular
    offset_add: np.ndarray  # (R,) tie x ties (the physical offset is offset x scale + offset_add)
    ptr: np.ndarray  # (R, n_max + 1) copy layout (constant beyond the model)
    idx: np.ndarray  # (R, N)


@numba.njit(cache=True)
def merge_batch(H, C, n, styles, Lh, Lj, tie, n_spins):
    """Merge ``B`` logical models with each of ``styles`` (style ids, see :data:`STYLE_IDS`).

    Args:
        H: ``(B, n_max)`` int64 rounded fields; C: ``(B, n_max, n_max)`` int64 rounded
            couplings, upper triangular; model ``b`` is ``H[b, :n[b]]``, ``C[b, :n[b], :n[b]]``
            (the padding is ignored).
        n: ``(B,)`` int64 spins per model.  styles: ``(k,)`` int64 style ids.
        Lh, Lj: symmetric range limits (>= 1); tie: tie strength in ``[1, Lj]``;
        n_spins: the chip's spin budget.

    Returns a :class:`Merged`.
    """
    B = H.shape[0]
    n_max = H.shape[1]
    k = styles.shape[0]
    R = B * k
    degree = np.zeros(n_max, dtype=np.int64)
    strength = np.zeros(n_max, dtype=np.int64)
    status = np.zeros(R, dtype=np.int64)
    err = np.full((R, 2), -1, dtype=np.int64)
    a = np.zeros((R, n_max), dtype=np.int64)
    n_phys = np.zeros(R, dtype=np.int64)
    excess = np.empty(n_max)
    exj = np.empty(n_max, dtype=np.int64)
    over = np.empty(n_max * n_max, dtype=np.int64)
    pex = np.empty(n_max * n_max, dtype=np.int64)
    N = 0
    for b in range(B):
        nb = n[b]
        _spin_stats(C, b, nb, degree, strength)
        n_over = _over_pairs(C, b, nb, Lj, over)
        for s in range(k):
            r = b * k + s
            status[r] = _copy_counts(H, C, b, nb, styles[s], (Lh, Lj, n_spins), (degree, strength), (over, n_over),
                                     a[r], err[r], (excess, exj, pex))
            if status[r] == MERGE_OK:
                n_phys[r] = a[r].sum()
                N = max(N, n_phys[r])
    h = np.zeros((R, N))
    J = np.zeros((R, N, N))
    offset_add = np.zeros(R)
    ptr = np.zeros((R, n_max + 1), dtype=np.int64)
    idx = np.zeros((R, N), dtype=np.int64)
    start = np.zeros(n_max, dtype=np.int64)
    for r in range(R):
        if status[r] != MERGE_OK:
            continue
        b = r // k
        nb = n[b]
        _layout(a[r], nb, start, ptr[r], idx[r])
        for i in range(nb + 1, n_max + 1):
            ptr[r, i] = ptr[r, nb]
        even = _EVEN[styles[r % k]]
        offset_add[r] = tie * _fill(H, C, b, nb, a[r], even, Lh, Lj, tie, start, h[r], J[r])
    return Merged(status, err, a, n_phys, h, J, offset_add, ptr, idx)


@numba.njit(cache=True)
def merge_styles(H, C, styles, Lh, Lj, tie, n_spins):
    """Merge one logical model (``H (n,)``, ``C (n, n)`` int64) with each of ``styles``:
    :func:`merge_batch` with ``B = 1`` (same returns, one row per style)."""
    n = H.shape[0]
    sizes = np.full(1, n, dtype=np.int64)
    return merge_batch(H.reshape(1, n), C.reshape(1, n, n), sizes, styles, Lh, Lj, tie, n_spins)


@numba.njit(cache=True)
def merge_styles_flat(H, C, styles, Lh, Lj, tie, n_spins, h_out, J_out, ptr, idx, status):
    """:func:`merge_styles` written into the caller's buffers in the chip's program layout (the
    same mappings, coefficient for coefficient), for a caller that keeps the programs.

    Returns ``w``, the widest mapped style's physical spins; ``status[s]`` is style ``s``'s merge
    code (``MERGE_OK`` or why it does not fit: :func:`merge_styles` names the term).  Style
    ``s``'s fields are ``h_out[s * w:(s + 1) * w]`` and its couplings ``J_out[s * w * w:(s + 1)
    * w * w]`` (``w x w``, C order, upper triangular), zero-padded to ``w`` (all zero for a style
    that does not fit); its copy layout is ``ptr[s, : n + 1]`` and ``idx[s, :w]`` (zero beyond its
    spins; all zero for a style that does not fit).  Outputs of any integer or float dtype (the
    coefficients are integers within the limits)."""
    n = H.shape[0]
    k = styles.shape[0]
    H1 = H.reshape(1, n)
    C1 = C.reshape(1, n, n)
    degree = np.empty(n, dtype=np.int64)
    strength = np.empty(n, dtype=np.int64)
    a = np.empty((k, n), dtype=np.int64)
    err = np.empty(2, dtype=np.int64)
    excess = np.empty(n)
    exj = np.empty(n, dtype=np.int64)
    over = np.empty(n * n, dtype=np.int64)
    pex = np.empty(n * n, dtype=np.int64)
    _spin_stats(C1, 0, n, degree, strength)
    n_over = _over_pairs(C1, 0, n, Lj, over)
    w = 0
    for s in range(k):
        status[s] = _copy_counts(H1, C1, 0, n, styles[s], (Lh, Lj, n_spins), (degree, strength), (over, n_over),
                                 a[s], err, (excess, exj, pex))
        if status[s] == MERGE_OK:
            w = max(w, a[s].sum())
    h_out[: k * w] = 0
    J_out[: k * w * w] = 0
    start = exj  # free again: the first extra copy of each spin
    for s in range(k):
        if status[s] != MERGE_OK:
            ptr[s, : n + 1] = 0
            idx[s, :w] = 0
            continue
        _layout(a[s], n, start, ptr[s], idx[s])
        idx[s, a[s].sum(): w] = 0
        _fill(H1, C1, 0, n, a[s], _EVEN[styles[s]], Lh, Lj, tie, start, h_out[s * w:(s + 1) * w],
              J_out[s * w * w:(s + 1) * w * w].reshape((w, w)))
    return w


@numba.njit(cache=True)
def decode_copies(spins, n_logical, ptr, idx, first):
    """Logical spins of many samples from their physical spins and copy layouts.

    Args:
        spins: ``(P, R, W)`` physical spins (int8 or int64) of ``P`` programs x ``R`` reads.
        n_logical: ``(P,)`` logical spin count of each program.
        ptr, idx: ``(P, >= n + 1)`` / ``(P, >= N)`` copy layouts (see the module docstring).
        first: ``True``: the original copy; ``False``: the majority of the copies, a tie
            going to the copy listed first.

    Returns ``(logical (P, R, n_max) int8, broken (P, R) int64)``: logical spins
    (zero beyond each program's ``n_logical``) and the number of logical spins whose
    copies disagree.
    """
    P = spins.shape[0]
    R = spins.shape[1]
    n_max = 0
    for p in range(P):
        n_max = max(n_max, n_logical[p])
    out = np.zeros((P, R, n_max), dtype=np.int8)
    broken = np.zeros((P, R), dtype=np.int64)
    for p in range(P):
        for r in range(R):
            s = spins[p, r]
            nb = 0
            for i in range(n_logical[p]):
                v = s[i]
                c0 = ptr[p, i]
                c1 = ptr[p, i + 1]
                if c1 - c0 > 1:
                    tot = 0
                    for c in range(c0, c1):
                        tot += np.int64(s[idx[p, c]])
                    if abs(tot) != c1 - c0:
                        nb += 1
                    if not first:
                        v = 1 if tot > 0 else (-1 if tot < 0 else s[idx[p, c0]])
                out[p, r, i] = v
            broken[p, r] = nb
    return out, broken
