"""Counter-based random helpers shared by the compiled kernels (numba, ``cache=True``).

* :func:`splitmix` - one splitmix64 finaliser step (``x + golden`` then the two
  multiply-xorshift rounds); the annealing kernel uses it in counter form and
  both kernels derive a read's key as
  ``splitmix(seed ^ splitmix(b * GOLDEN + r))``; exported as ``ising_backend.splitmix``, it is
  also the planners' tie-break hash and the sharing's node-set hash;
* :func:`splitmix_array` - :func:`splitmix` as a numpy ufunc on uint64 arrays, and :func:`chain_key` -
  ``splitmix(key ^ part)`` over a uint64 vector of parts from 0 (the fault model's keys);
* :func:`xorshift_star` - one xorshift64* step: returns ``(new_state, output)``
  (used by the logical tabu kernel).

numba's on-disk cache tracks only the source file of the function it compiles,
not the files it inlines from: after editing this module, clear the
``__pycache__`` of ``anneal.py`` / ``logical.py`` (or touch them) so their
kernels recompile.
"""

from __future__ import annotations

import numba
import numpy as np

GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_XS = np.uint64(0x2545F4914F6CDD1D)


@numba.njit(cache=True, inline="always")
def splitmix(x):
    z = x + GOLDEN
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@numba.vectorize(cache=True)
def splitmix_array(x):
    return splitmix(x)


@numba.njit(cache=True)
def chain_key(parts):
    key = np.uint64(0)
    for p in parts:
        key = splitmix(key ^ p)
    return key


@numba.njit(cache=True, inline="always")
def xorshift_star(state):
    x = state
    x ^= x >> np.uint64(12)
    x ^= x << np.uint64(25)
    x ^= x >> np.uint64(27)
    return x, x * _XS
