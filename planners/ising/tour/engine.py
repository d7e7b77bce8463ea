"""Compiled one-hot subproblem solve of the clustered Ising tour (paper 5.2) on the logical solver.

Contract: :func:`solve_order` makes the decisions of ``IsingTour._solve_path`` followed by its
``_sample`` for one open-path subproblem (cluster order, local TSP or refinement patch) whose
one-hot model fits the spin budget: the penalty, the Ising model, per attempt a seed drawn
from the construction's ``numpy.random.Generator`` and its solve-group sub-seed
(:func:`ising_backend.logical.mix_seed`), the logical solver through
:func:`ising_backend.solve_submit` (its own tabu kernel, or a callback into ``solve_stack``), decode, the cheapest valid order and
the statistics.  Each attempt's calls and measured emulation seconds (a monotonic clock around
the kernel) are returned so the caller charges the solver as ``solve_stack`` would.  The
Python path in :mod:`.search` is its reference (the tests compare both).
"""

from __future__ import annotations

import numba
import numpy as np

from ising_backend import solve_submit
from planners.ising.tour.kernels import best_onehot, onehot_ising

__all__ = ["solve_order"]


@numba.njit(cache=True)
def solve_order(rng, d, entry, ex, margin_factor, max_retries, num_reads, handle, restarts, iterations, tenure):
    """Best valid order of one one-hot open-path subproblem, or an empty order after the retries.

    Returns ``(order (s,) or (0,), stats (6,), calls (attempts,), emulation_s (attempts,))`` with
    stats = programs, reads, valid_reads, valid programs, retries, unsolved (0/1).
    """
    s = d.shape[0]
    n = s * s
    w_max = 0.0
    for i in range(s):
        w_max = max(w_max, abs(entry[i]), abs(ex[i]))
        for j in range(s):
            w_max = max(w_max, abs(d[i, j]))
    A = 1.0 * (margin_factor * w_max + 1.0)
    h, J, _off = onehot_ising(d, entry, ex, A, 1.0)
    hb = h.reshape(1, n)
    Jb = J.reshape(1, n, n)
    stats = np.zeros(6, dtype=np.int64)
    calls = np.zeros(max_retries + 1, dtype=np.int64)
    emu = np.zeros(max_retries + 1)
    bits = np.empty((num_reads, n), dtype=np.uint8)
    for attempt in range(max_retries + 1):
        seed = rng.integers(0, 9223372036854775807)
        spins = np.empty((1, num_reads, n), dtype=np.int8)
        energies = np.zeros((1, num_reads))
        emu[attempt] = solve_submit(hb, Jb, num_reads, seed, handle, restarts, iterations, tenure, spins, energies)
        calls[attempt] = num_reads
        for r in range(num_reads):
            for v in range(n):
                bits[r, v] = 1 if spins[0, r, v] > 0 else 0
        valid, best, orders = best_onehot(bits, s, d, entry, ex)
        nv = 0
        for r in range(num_reads):
            nv += valid[r]
        stats[0] += 1
        stats[1] += num_reads
        stats[2] += nv
        stats[3] += nv > 0
        if best >= 0:
            return orders[best].copy(), stats, calls[: attempt + 1], emu[: attempt + 1]
        stats[4] += 1
    stats[5] = 1
    return np.zeros(0, dtype=np.int64), stats, calls, emu
