"""The compiled annealing kernel of the emulated chip.

One numba function (``cache=True``, single thread, no Python objects per problem)
anneals a whole stack of programs: ``h (B, n)``, ``J (B, n, n)`` upper triangular.
For each program and read it runs a fixed-schedule Metropolis single-spin-flip
anneal (sequential sweeps over the spins, the order dwave-samplers uses too):

* local fields ``f_i = h_i + sum_j J_ij s_j`` are kept incrementally in float32
  (exact for the chip's integer coefficients; an accepted flip of spin ``i`` costs
  one row update), the flip energy is ``dE = -2 s_i f_i``;
* every spin visit draws one uniform ``u`` in (0, 1) and accepts iff
  ``u < exp(-beta dE)`` and ``beta dE < 20`` (``exp(-20)`` ~ 2e-9), evaluated as
  ``s_i f_i > max(log u, -20) / (2 beta)``: the thresholds of a whole sweep are
  drawn before it (a vectorised float32 polynomial ``log``, error < 1e-7), so the serial
  part of a visit is one compare and, on acceptance, the row update; downhill
  flips (``dE <= 0``) are always accepted;
* the inverse-temperature schedule is geometric (or linear) from ``beta_hot`` to
  ``beta_cold`` over ``sweeps`` sweeps, precomputed once per program.  The
  automatic range: cold end exactly dwave-samplers' default (the smallest
  non-zero coefficient excites with probability 1 % summed over the spins that
  have it); hot end: a flip against the largest *root-mean-square* local field
  ``sqrt(h_i^2 + sum_j J_ij^2)`` is accepted with probability 1/2.  dwave-samplers
  uses the worst-case field ``|h_i| + sum_j |J_ij|`` there, which on dense
  programs spends the first third of a 50-sweep anneal at random; the RMS rule
  measured a higher ground-state hit rate at 50 sweeps and fewer wasted flips;
* each read has its own random stream: splitmix64 in counter form, draw ``t``
  of read ``r`` of program ``b`` being ``splitmix64(K + t * golden)`` with the
  key ``K = splitmix64(seed ^ splitmix64(b * golden + r))``; draws ``0 .. n-1``
  give the random start, ``n (k + 1) + i`` the threshold of spin ``i`` in sweep
  ``k``, and the readout flips come after the last sweep.  Draws without a serial
  chain vectorise.  The same seed gives the same samples, and a read's samples
  depend only on its program's coefficients, the program's index in the stack,
  the read index and the seed, never on the other programs of the batch (nor on
  whether the coefficients arrive as int64 or float64).  Reads are annealed
  ``_LANES`` at a time side by side (interleaved in one loop so the core overlaps
  their dependency chains); that grouping changes no result.  Zero-padding a
  program to a larger ``n`` does change its random stream;
* optional static coupling mismatch: read ``k = b * reads + r`` of the call runs
  on core ``k % n_cores`` (or the core it is given) whose
  fixed factor matrix multiplies the couplings while annealing; optional stuck
  spins per core (clamped through the anneal); optional readout bit flips after
  the anneal;
* the returned energy is that of the *programmed* coefficients (recomputed in
  float64 from scratch, so it is exact for integer programs).

Speed (``benchmarks/chip_speed.py``, results in ``benchmarks/RESULTS.md`` "Issue 3:
emulated chip"): about 14 us of one thread per 45-spin, 50-sweep call at one read
per program and 11.5 us at 10 reads, through ``EmulatedChip.anneal_batch`` on the
2-vCPU development VM (AMD EPYC, AVX-512); the previous kernel (xorshift stream,
``exp`` on the serial chain of each visit) took 27 and 21 us.  Of the ~11 us at 10
reads, about 7 us is the sweep loop itself (~22 % of visits accept: a mispredicted
branch and one row update each), ~3.4 us the thresholds, ~0.9 us the set-up and
energy.  Quality is unchanged within noise: on the benchmark's 200 programs x 100-200 reads
(two seeds) the ground-state hit rate was 0.274 / 0.273 (noise-free) and
0.246 / 0.245 (5 % mismatch) against 0.273 / 0.272 and 0.250 / 0.250 for the
previous kernel; on three further sets of 200 programs with mismatch 0.251 vs
0.253.  Measured no faster: float32 fields alone, a tabulated exp, a branch-free
always-update acceptance (the row update then costs every visit), libm ``log``
for the thresholds, and a 16-lane SIMD layout across reads (numba's vectoriser
re-checks aliasing on every short inner loop).
"""

from __future__ import annotations

import numba
import numpy as np

from ._rng import GOLDEN as _GOLDEN
from ._rng import splitmix as _splitmix

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
