"""The compiled annealing kernel of the emulated chip.

One numba function (``cache=True``, single thread, no Python objects per problem)
anneals a whole stack of programs: ``h (B, n)``, ``J (B, n, n)`` upper triangular.
For each program and read it runs a fixed-schedule Metropolis single-spin-flip
anneal (sequential sweeps over the spins, the order dwave-samplers uses too):

* local fields ``f_i = h_i + sum_j J_ij s_j`` are kept incrementally (an accepted
  flip of spin ``i`` costs one row update), the flip energy is ``-2 s_i f_i``;
* flips with ``beta * dE > 20`` are rejected without drawing (``exp(-20)`` ~ 2e-9),
  downhill flips are accepted without drawing;
* the inverse-temperature schedule is geometric (or linear) from ``beta_hot`` to
  ``beta_cold`` over ``sweeps`` sweeps, precomputed once per program.  The
  automatic range: cold end exactly dwave-samplers' default (the smallest
  non-zero coefficient excites with probability 1 % summed over the spins that
  have it); hot end: a flip against the largest *root-mean-square* local field
  ``sqrt(h_i^2 + sum_j J_ij^2)`` is accepted with probability 1/2.  dwave-samplers
  uses the worst-case field ``|h_i| + sum_j |J_ij|`` there, which on dense
  programs spends the first third of a 50-sweep anneal at random; the RMS rule
  measured a higher ground-state hit rate at 50 sweeps and fewer wasted flips;
* the random numbers come from xorshift64* seeded by splitmix64 of
  ``(seed, program index, read index)``: the same seed gives the same samples,
  and a program's samples depend only on its own coefficients, its index in the
  stack and the seed, never on the other programs of the batch (zero-padding a
  program to a larger ``n`` does change its random stream);
* optional static coupling mismatch: read ``k = b * reads + r`` of the call runs
  on core ``k % n_cores`` whose fixed factor matrix multiplies the couplings while
  annealing; optional readout bit flips after the anneal;
* the returned energy is that of the *programmed* coefficients (recomputed from
  scratch, so it is exact for integer programs).

Speed: about 21 us of one thread per 45-spin, 50-sweep call on the shared
2-vCPU development VM (``benchmarks/chip_speed.py``; dwave-samplers' SA takes
~1.5 ms per single-read call through dimod).  Tried and measured no faster
there: float32 fields, a tabulated exp, a branch-free acceptance, and a 16-lane
SIMD layout across reads.
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["anneal_kernel", "beta_range_auto"]

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_XS = np.uint64(0x2545F4914F6CDD1D)
_U53 = 1.0 / 9007199254740992.0


@numba.njit(cache=True, inline="always")
def _splitmix(x):
    z = x + _GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@numba.njit(cache=True, inline="always")
def _next(state):
    x = state
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    return x, x * _XS


@numba.njit(cache=True)
def _auto_range(h_b, Js, n):
    """Automatic beta range of one program (hot, cold); see the module docstring (one pass)."""
    max_sq = 0.0
    min_eff = np.inf
    count = 0
    for i in range(n):
        hi = h_b[i]
        sq = hi * hi
        mn = abs(hi) if hi != 0.0 else np.inf
        for j in range(n):
            a = abs(Js[i, j])
            sq += a * a
            if a != 0.0 and a < mn:
                mn = a
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


@numba.njit(cache=True, nogil=True)
def anneal_kernel(h, J, num_reads, seed, sweeps, geometric, beta_hot, beta_cold,
                  mismatch, flip_prob, out_spins, out_energy):
    """Anneal ``B`` programs x ``num_reads`` reads in place into ``out_spins`` / ``out_energy``.

    ``beta_hot <= 0`` selects the automatic per-program range.  ``mismatch`` is
    ``(n_cores, N, N)`` with ``N >= n`` (or ``(0, 0, 0)`` for none).
    """
    B = h.shape[0]
    n = h.shape[1]
    n_cores = mismatch.shape[0]
    Js = np.zeros((n, n))
    Jeff = np.zeros((n, n))
    f = np.zeros(n)
    s = np.zeros(n)
    betas = np.zeros(sweeps)
    seed64 = np.uint64(seed)
    for b in range(B):
        for i in range(n):
            Js[i, i] = 0.0
            for j in range(i + 1, n):
                v = J[b, i, j] + J[b, j, i]
                Js[i, j] = v
                Js[j, i] = v
        if beta_hot <= 0.0:
            hot, cold = _auto_range(h[b], Js, n)
        else:
            hot, cold = beta_hot, beta_cold
        if sweeps == 1:
            betas[0] = cold
        elif geometric:
            ratio = (cold / hot) ** (1.0 / (sweeps - 1))
            betas[0] = hot
            for k in range(1, sweeps):
                betas[k] = betas[k - 1] * ratio
        else:
            for k in range(sweeps):
                betas[k] = hot + (cold - hot) * (k / (sweeps - 1))
        for r in range(num_reads):
            state = _splitmix(seed64 ^ _splitmix(np.uint64(b) * _GOLDEN + np.uint64(r)))
            if state == np.uint64(0):
                state = _GOLDEN
            if n_cores > 0:
                core = (b * num_reads + r) % n_cores
                for i in range(n):
                    for j in range(n):
                        Jeff[i, j] = Js[i, j] * mismatch[core, i, j]
                Jr = Jeff
            else:
                Jr = Js
            # random start
            for i in range(n):
                state, x = _next(state)
                s[i] = 1.0 if (x >> np.uint64(63)) == np.uint64(1) else -1.0
            for i in range(n):
                acc = h[b, i]
                for j in range(n):
                    acc += Jr[i, j] * s[j]
                f[i] = acc
            for k in range(sweeps):
                beta = betas[k]
                for i in range(n):
                    dE = -2.0 * s[i] * f[i]
                    accept = False
                    if dE <= 0.0:
                        accept = True
                    else:
                        bd = beta * dE
                        if bd < 20.0:
                            state, x = _next(state)
                            u = np.int64(x >> np.uint64(11)) * _U53
                            if u < np.exp(-bd):
                                accept = True
                    if accept:
                        s[i] = -s[i]
                        d = 2.0 * s[i]
                        for j in range(n):
                            f[j] += d * Jr[i, j]
            if flip_prob > 0.0:
                for i in range(n):
                    state, x = _next(state)
                    u = np.int64(x >> np.uint64(11)) * _U53
                    if u < flip_prob:
                        s[i] = -s[i]
            e = 0.0
            for i in range(n):
                acc = h[b, i]
                for j in range(i + 1, n):
                    acc += Js[i, j] * s[j]
                e += s[i] * acc
                out_spins[b, r, i] = np.int8(s[i])
            out_energy[b, r] = e


def beta_range_auto(h: np.ndarray, J: np.ndarray) -> tuple[float, float]:
    """The automatic ``(beta_hot, beta_cold)`` of one program (for inspection)."""
    h = np.asarray(h, dtype=np.float64)
    J = np.asarray(J, dtype=np.float64)
    return _auto_range(h, J + J.T, h.size)
