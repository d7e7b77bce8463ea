"""The logical solver's tabu search, compiled: one kernel for the solver and for compiled planner loops.

:func:`tabu_kernel` runs ``B`` programs x ``num_reads`` reads; :func:`mix_seed` derives the sub-seed of a size
group (splitmix64; called from Python by the solver and from compiled loops), so a compiled loop calling the kernel
draws what :meth:`~ising_backend.machines.logical.LogicalIsingSolver.solve_stack` draws.
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend._rng import GOLDEN as _GOLDEN
from ising_backend._rng import splitmix as _splitmix
from ising_backend._rng import xorshift_star as _next

__all__ = ["tabu_kernel", "mix_seed"]


@numba.njit(cache=True, nogil=True)
def tabu_kernel(h, J, num_reads, seed, restarts, iterations, tenure, out_spins, out_energy):
    """Tabu search on ``B`` programs x ``num_reads`` reads (energies without offset)."""
    B = h.shape[0]
    n = h.shape[1]
    Js = np.zeros((n, n))
    f = np.zeros(n)
    s = np.zeros(n)
    best_s = np.zeros(n)
    tabu_until = np.zeros(n, dtype=np.int64)
    seed64 = np.uint64(seed)
    for b in range(B):
        for i in range(n):
            Js[i, i] = 0.0
            for j in range(i + 1, n):
                v = J[b, i, j] + J[b, j, i]
                Js[i, j] = v
                Js[j, i] = v
        for r in range(num_reads):
            state = _splitmix(seed64 ^ _splitmix(np.uint64(b) * _GOLDEN + np.uint64(r)))
            if state == np.uint64(0):
                state = _GOLDEN
            best_e = np.inf
            for rs in range(restarts):
                if rs == 0 or best_e == np.inf:
                    for i in range(n):
                        state, x = _next(state)
                        s[i] = 1.0 if (x >> np.uint64(63)) == np.uint64(1) else -1.0
                else:
                    for i in range(n):
                        s[i] = best_s[i]
                    for k in range(max(1, n // 4)):
                        state, x = _next(state)
                        i = np.int64(x >> np.uint64(33)) % n
                        s[i] = -s[i]
                e = 0.0
                for i in range(n):
                    acc = h[b, i]
                    for j in range(n):
                        acc += Js[i, j] * s[j]
                    f[i] = acc
                    e += s[i] * (h[b, i] + 0.5 * (acc - h[b, i]))
                if e < best_e:
                    best_e = e
                    for i in range(n):
                        best_s[i] = s[i]
                for i in range(n):
                    tabu_until[i] = 0
                for it in range(iterations):
                    pick = -1
                    pick_d = np.inf
                    for i in range(n):
                        d = -2.0 * s[i] * f[i]
                        if d < pick_d and (tabu_until[i] <= it or e + d < best_e - 1e-12):
                            pick_d = d
                            pick = i
                    if pick < 0:
                        continue
                    s[pick] = -s[pick]
                    dd = 2.0 * s[pick]
                    for j in range(n):
                        f[j] += dd * Js[pick, j]
                    e += pick_d
                    tabu_until[pick] = it + 1 + tenure
                    if e < best_e - 1e-12:
                        best_e = e
                        for i in range(n):
                            best_s[i] = s[i]
            # exact energy of the best state
            e = 0.0
            for i in range(n):
                acc = h[b, i]
                for j in range(i + 1, n):
                    acc += Js[i, j] * best_s[j]
                e += best_s[i] * acc
                out_spins[b, r, i] = np.int8(best_s[i])
            out_energy[b, r] = e


@numba.njit(cache=True)
def mix_seed(seed, k):
    """The sub-seed of size group ``k`` (splitmix64 of ``seed + golden x k``; :meth:`LogicalIsingSolver.solve_many`)."""
    return _splitmix(np.uint64(seed) + _GOLDEN * np.uint64(k))
