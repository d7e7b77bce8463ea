"""Counter-based random helpers shared by the compiled kernels (numba, ``cache=True``).

Contract: :func:`splitmix` is one splitmix64 finaliser step (exported as ``ising_backend.splitmix``),
:func:`splitmix_array` the same as a ufunc on uint64 arrays, :func:`chain_key` ``splitmix(key ^ part)``
over a vector of parts, :func:`xorshift_star` one xorshift64* step ``-> (new_state, output)``.  After
editing this file, clear the numba caches of the kernels that inline it.
Design notes: docs/design/emulated_chip.md.
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
