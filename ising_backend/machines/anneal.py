"""The compiled annealing kernel of the emulated chip.

Contract: :func:`anneal_kernel` anneals a stack of programs ``h (B, n)``, ``J (B, n, n)`` (upper
triangular), each read a fixed-schedule Metropolis single-spin-flip anneal.  The same seed gives the
same samples, and a read's samples never depend on the other programs of the batch; the returned
energies are those of the *programmed* coefficients.
Design notes (schedule, random streams, speed): docs/design/emulated_chip.md.
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend._rng import GOLDEN as _GOLDEN
from ising_backend._rng import splitmix as _splitmix

__all__ = ["anneal_kernel", "beta_range_auto", "NO_CORES", "NO_CLAMP"]

_U53 = 1.0 / 9007199254740992.0


@numba.njit(cache=True, inline="always")
def _range_from(sqs, mns, n):
    """(hot, cold) from the per-spin squared field sums and smallest non-zero magnitudes."""
    max_sq = 0.0
    min_eff = np.inf
    count = 0
    for i in range(n):
        sq = sqs[i]
        mn = mns[i]
        if sq > max_sq:
            max_sq = sq
        if mn < min_eff:
            min_eff = mn
            count = 1
        elif mn == min_eff:
            count += 1
    if max_sq == 0.0:
        return 0.1, 1.0
    hot = np.log(2.0) / (2.0 * np.sqrt(max_sq))
    cold = np.log(count / 0.01) / (2.0 * min_eff)
    if cold < hot:
        cold = hot
    return hot, cold


@numba.njit(cache=True, inline="always")
def _field_stats(h_b, Js, n, sqs, mns):
    """Per spin ``j``: ``sqs[j] = h_j^2 + sum_i Js[i, j]^2`` and ``mns[j]`` the smallest
    non-zero ``|h_j|``, ``|Js[i, j]|`` (``inf`` if none), from symmetric couplings ``Js``."""
    for j in range(n):
        hj = h_b[j]
        sqs[j] = hj * hj
        mns[j] = abs(hj) if hj != 0.0 else np.inf
    for i in range(n):
        for j in range(n):
            a = abs(Js[i, j])
            sqs[j] += a * a
            mns[j] = a if (a != 0.0) & (a < mns[j]) else mns[j]


@numba.njit(cache=True)
def _auto_range(h_b, Js, n):
    """Automatic beta range of one program (hot, cold) from its symmetric couplings; see the module docstring."""
    sqs = np.empty(n)
    mns = np.empty(n)
    _field_stats(h_b, Js, n, sqs, mns)
    return _range_from(sqs, mns, n)


_SLOTS = 8  # cached program set-ups: > the programs one group of lanes can span
_LANES = 4  # reads annealed side by side (independent streams; the count changes no result)
_ONE_BITS = np.uint64(0x3FF0000000000000)
_MANT = np.uint64(0x000FFFFFFFFFFFFF)
_LN2 = np.float32(0.6931471805599453)
_SQRT2 = np.float32(1.4142135623730951)
_LOG_MIN = np.float32(-20.0)
_U52 = 1.0 / 4503599627370496.0
# log(1 + t) = t * P(t) on [sqrt(1/2) - 1, sqrt(2) - 1] in float32, least squares on Chebyshev
# nodes (|error| < 1e-7, the float32 rounding of the thresholds)
_C0, _C1, _C2, _C3, _C4, _C5, _C6, _C7 = (np.float32(v) for v in (
    0.9999999425426719, -0.5000036309272982, 0.33335114140346994, -0.24970071685057837,
    0.1989856504823497, -0.17247013303837178, 0.1623418979919823, -0.10134056751194925))


@numba.njit(cache=True, inline="always")
def _program_setup(h_b, J_b, n, sweeps, geometric, beta_hot, beta_cold, Jb, betas_b, sqs, mns):
    """Symmetric couplings ``Jb`` (padding columns stay zero) and the schedule of one program (one pass)."""
    for i in range(n):
        for j in range(n):
            Jb[i, j] = J_b[i, j]
    for i in range(n):
        Jb[i, i] = 0.0
        for j in range(i + 1, n):
            v = Jb[i, j] + Jb[j, i]
            Jb[i, j] = v
            Jb[j, i] = v
    _field_stats(h_b, Jb, n, sqs, mns)
    if beta_hot <= 0.0:
        hot, cold = _range_from(sqs, mns, n)
    else:
        hot, cold = beta_hot, beta_cold
    if sweeps == 1:
        betas_b[0] = cold
    elif geometric:
        ratio = (cold / hot) ** (1.0 / (sweeps - 1))
        betas_b[0] = hot
        for k in range(1, sweeps):
            betas_b[k] = betas_b[k - 1] * ratio
    else:
        for k in range(sweeps):
            betas_b[k] = hot + (cold - hot) * (k / (sweeps - 1))


#: :func:`anneal_kernel`'s ``faults`` for a chip without faults: reads on cores in turn, no stuck spin.
NO_CORES = np.zeros(0, dtype=np.int64)
NO_CLAMP = np.zeros((0, 0), dtype=np.int8)


@numba.njit(cache=True, nogil=True)
def anneal_kernel(h, J, num_reads, seed, sweeps, geometric, beta_hot, beta_cold, mismatch, flip_prob, faults, out):
    """Anneal ``B`` programs x ``num_reads`` reads in place into ``out = (out_spins, out_energy)``.

    ``h`` / ``J`` are int16, int64 or float64 (compiled once per dtype; same samples): a
    compiled planner hands its integer chip programs over as they are.  ``beta_hot <= 0`` selects the
    automatic per-program range.  ``mismatch`` is ``(n_cores, N, N)`` with ``N >= n`` (or ``(0, 0, 0)``
    for none).  ``faults`` = ``(cores, clamp)`` (:data:`NO_CORES`, :data:`NO_CLAMP` for a chip
    without faults): read ``k`` runs on core ``cores[k]`` (``cores`` empty: ``k % n_cores``),
    whose factor matrix ``mismatch[core]`` (if any) and stuck spins ``clamp[core]`` (``(n_cores, N)``
    int8: 0 free, +-1 stuck at that value; or ``(0, 0)`` for none) it anneals with.  A stuck spin
    starts at its value and never flips; the readout flips after the anneal apply to it like to any spin.
    """
    cores, clamp = faults
    out_spins, out_energy = out
    B = h.shape[0]
    n = h.shape[1]
    R = num_reads
    npad = (n + 7) // 8 * 8
    n_cores = mismatch.shape[0]
    given = cores.shape[0] > 0
    clamped = clamp.shape[0] > 0
    lane_core = np.zeros(_LANES, dtype=np.int64)
    # per program (a small cache of the programs of the current lanes): symmetric
    # couplings (float64, exact energies) and the beta schedule
    Js = np.zeros((_SLOTS, n, npad))
    betas = np.ones((_SLOTS, sweeps))
    slot_prog = np.full(_SLOTS, -1, dtype=np.int64)
    sqs = np.empty(n)
    mns = np.empty(n)
    # per lane (one read of one program): annealed couplings, fields, spins (float32)
    W = np.zeros((_LANES, n, npad), dtype=np.float32)
    f = np.zeros((_LANES, npad), dtype=np.float32)
    s = np.zeros((_LANES, npad), dtype=np.float32)
    st = np.zeros(_LANES, dtype=np.uint64)  # readout-flip counters
    bl = np.zeros(_LANES, dtype=np.int64)
    # one sweep's acceptance thresholds of all lanes, flat [i * L + l]
    nq_max = n * _LANES
    thr = np.zeros(nq_max, dtype=np.float32)
    uf = np.zeros(nq_max)
    ub = uf.view(np.uint64)
    mb = np.zeros(nq_max, dtype=np.uint64)
    mf = mb.view(np.float64)
    ex = np.zeros(nq_max, dtype=np.float32)
    cq = np.zeros(nq_max, dtype=np.float32)
    kq = np.zeros(nq_max, dtype=np.uint64)
    g = np.zeros(npad)
    seed64 = np.uint64(seed)
    total = B * R
    for g0 in range(0, total, _LANES):
        L = min(_LANES, total - g0)
        nq = n * L
        for q in range(nq, nq_max):  # idle lanes of the last group never flip
            thr[q] = np.inf
        for l in range(L):
            k = g0 + l
            b = k // R
            r = k - b * R
            sl = b % _SLOTS
            if slot_prog[sl] != b:
                slot_prog[sl] = b
                _program_setup(h[b], J[b], n, sweeps, geometric, beta_hot, beta_cold, Js[sl], betas[sl], sqs, mns)
            bl[l] = sl
            key = _splitmix(seed64 ^ _splitmix(np.uint64(b) * _GOLDEN + np.uint64(r)))
            for i in range(n):
                kq[l * n + i] = key + np.uint64(i) * _GOLDEN
            st[l] = key + np.uint64(n * (sweeps + 1)) * _GOLDEN  # readout flips draw after the anneal
            core = cores[k] if given else (k % n_cores if n_cores > 0 else 0)
            lane_core[l] = core
            if n_cores > 0:
                for i in range(n):
                    for j in range(n):
                        W[l, i, j] = Js[sl, i, j] * mismatch[core, i, j]
            else:
                for i in range(n):
                    for j in range(npad):
                        W[l, i, j] = Js[sl, i, j]
            # random start
            for i in range(n):
                x = _splitmix(kq[l * n + i])
                s[l, i] = np.float32(np.int64(x >> np.uint64(63)) * 2 - 1)
            if clamped:
                for i in range(n):
                    v = clamp[core, i]
                    if v != 0:
                        s[l, i] = np.float32(v)
            for j in range(npad):
                f[l, j] = 0.0
            for j in range(n):
                f[l, j] = h[b, j]
            for i in range(n):
                si = s[l, i]
                for j in range(npad):
                    f[l, j] += si * W[l, i, j]
        for k in range(sweeps):
            # thresholds t = max(log u, -20) / (2 beta), flat [l * n + i]: accept iff s_i f_i > t
            off = np.uint64(n * (k + 1)) * _GOLDEN
            for q in range(nq):
                x = _splitmix(kq[q] + off)
                uf[q] = (np.int64(x >> np.uint64(12)) + 0.5) * _U52
            for q in range(nq):
                bits = ub[q]
                ex[q] = np.float32(np.int64(bits >> np.uint64(52)) - 1023)
                mb[q] = (bits & _MANT) | _ONE_BITS
            for l in range(_LANES):
                c = np.float32(0.5 / betas[bl[l], k])
                for q in range(l * n, (l + 1) * n):
                    cq[q] = c
            for q in range(nq):
                m = np.float32(mf[q])
                e = ex[q]
                big = m > _SQRT2
                m = np.float32(0.5) * m if big else m
                e = e + np.float32(1.0) if big else e
                t = m - np.float32(1.0)
                lu = e * _LN2 + t * (_C0 + t * (_C1 + t * (_C2 + t * (_C3 + t * (_C4 + t * (
                    _C5 + t * (_C6 + t * _C7)))))))
                lu = lu if lu > _LOG_MIN else _LOG_MIN
                thr[q] = lu * cq[q]
            if clamped:  # a stuck spin never flips
                for l in range(L):
                    for i in range(n):
                        if clamp[lane_core[l], i] != 0:
                            thr[l * n + i] = np.inf
            # the sweep: spins in order, the lanes interleaved
            for i in range(n):
                for l in range(_LANES):
                    si = s[l, i]
                    if si * f[l, i] > thr[l * n + i]:
                        s[l, i] = -si
                        d = np.float32(-2.0) * si
                        for j in range(npad):
                            f[l, j] += d * W[l, i, j]
        for l in range(L):
            b = (g0 + l) // R
            r = g0 + l - b * R
            sl = bl[l]
            if flip_prob > 0.0:
                for i in range(n):
                    x = _splitmix(st[l] + np.uint64(i) * _GOLDEN)
                    u = np.int64(x >> np.uint64(11)) * _U53
                    if u < flip_prob:
                        s[l, i] = -s[l, i]
            # energy of the programmed coefficients: E = sum_i s_i (2 h_i + sum_j Js_ij s_j) / 2
            for j in range(npad):
                g[j] = 0.0
            for i in range(n):
                si = np.float64(s[l, i])
                out_spins[b, r, i] = np.int8(si)
                for j in range(npad):
                    g[j] += si * Js[sl, i, j]
            e = 0.0
            for i in range(n):
                e += s[l, i] * (2.0 * h[b, i] + g[i])
            out_energy[b, r] = 0.5 * e


def beta_range_auto(h: np.ndarray, J: np.ndarray) -> tuple[float, float]:
    """The automatic ``(beta_hot, beta_cold)`` of one program (for inspection)."""
    h = np.asarray(h, dtype=np.float64)
    J = np.asarray(J, dtype=np.float64)
    return _auto_range(h, J + J.T, h.size)
