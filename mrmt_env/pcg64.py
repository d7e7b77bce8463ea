"""``Generator.choice(n, k, replace=False)`` of numpy's PCG64, compiled, draw for draw.

The vector envs draw a world per episode, and numpy's ``choice`` (about 20 us a call, mostly
call overhead) was most of an Assign episode.  These kernels run the same algorithm on the
generator's own state, read and written in place through its ctypes address: PCG64's
128-bit LCG step and XSL-RR output, the buffered 32-bit halves (``next_uint32``), Lemire's
bounded integers, Floyd's sampling and the final shuffle -- so the generator ends exactly
where numpy's ``choice`` would leave it and the next draw is the same.

Contract: :func:`state_views` gives the arrays the kernels take (only for a PCG64 generator;
``None`` otherwise, and the caller uses numpy).  ``choice_floyd`` matches numpy for
``pop_size <= 10000`` (above that numpy may switch algorithm; callers use numpy there).
``tests/test_pcg64.py`` checks kernels against numpy over many seeds and sizes.
"""

from __future__ import annotations

import ctypes

import numba
import numpy as np

__all__ = ["state_views", "next64", "next32", "bounded32", "choice_floyd", "MAX_POP"]

#: Largest population the compiled choice takes (numpy's Floyd branch).
MAX_POP = 10000

_MUL_HI = np.uint64(2549297995355413924)
_MUL_LO = np.uint64(4865540595714422341)
_M32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_S58 = np.uint64(58)
_S64 = np.uint64(64)
_ONE = np.uint64(1)
_ZERO = np.uint64(0)

_VIEWS: dict = {}


def state_views(rng: np.random.Generator):
    """``(state uint64[4], buffer uint32[4])`` views of a PCG64 generator's state (state lo, hi,
    inc lo, hi; ``buffer[2]`` = has_uint32, ``buffer[3]`` = the buffered half), cached per
    generator; ``None`` for any other bit generator."""
    bg = rng.bit_generator
    key = id(bg)
    hit = _VIEWS.get(key)
    if hit is not None and hit[0] is bg:
        return hit[1], hit[2]
    if type(bg) is not np.random.PCG64:
        return None
    addr = bg.ctypes.state_address
    ptr = ctypes.c_void_p.from_address(addr).value
    state = np.ctypeslib.as_array((ctypes.c_uint64 * 4).from_address(ptr))
    buf = np.ctypeslib.as_array((ctypes.c_uint32 * 4).from_address(addr))
    if len(_VIEWS) >= 4096:
        _VIEWS.clear()
    _VIEWS[key] = (bg, state, buf)  # keeps bg alive, so its id is not reused while cached
    return state, buf


@numba.njit(cache=True, nogil=True)
def _mulhi(a, b):
    a_lo = a & _M32
    a_hi = a >> _S32
    b_lo = b & _M32
    b_hi = b >> _S32
    p0 = a_lo * b_lo
    p1 = a_lo * b_hi
    p2 = a_hi * b_lo
    p3 = a_hi * b_hi
    carry = ((p0 >> _S32) + (p1 & _M32) + (p2 & _M32)) >> _S32
    return p3 + (p1 >> _S32) + (p2 >> _S32) + carry


@numba.njit(cache=True, nogil=True)
def next64(state):
    """One PCG64 output (state advanced in place)."""
    lo, hi = state[0], state[1]
    new_lo = lo * _MUL_LO
    new_hi = _mulhi(lo, _MUL_LO) + lo * _MUL_HI + hi * _MUL_LO
    s_lo = new_lo + state[2]
    carry = _ONE if s_lo < new_lo else _ZERO
    s_hi = new_hi + state[3] + carry
    state[0] = s_lo
    state[1] = s_hi
    x = s_hi ^ s_lo
    rot = s_hi >> _S58
    return (x >> rot) | (x << ((_S64 - rot) & np.uint64(63)))


@numba.njit(cache=True, nogil=True)
def next32(state, buf):
    """numpy's ``next_uint32``: the buffered upper half if one is waiting, else a new output's lower half."""
    if buf[2] != 0:
        buf[2] = 0
        return np.uint64(buf[3])
    v = next64(state)
    buf[2] = 1
    buf[3] = np.uint32(v >> _S32)
    return v & _M32


@numba.njit(cache=True, nogil=True)
def bounded32(state, buf, rng):
    """numpy's ``random_bounded_uint64(0, rng)`` for ``0 < rng < 2**32 - 1``: Lemire's method, in [0, rng]."""
    excl = np.uint64(rng) + _ONE
    m = next32(state, buf) * excl
    leftover = m & _M32
    if leftover < excl:
        threshold = (_M32 - np.uint64(rng)) % excl
        while leftover < threshold:
            m = next32(state, buf) * excl
            leftover = m & _M32
    return np.int64(m >> _S32)


@numba.njit(cache=True, nogil=True)
def _bounded(state, buf, rng):
    if rng == 0:
        return np.int64(0)
    return bounded32(state, buf, rng)


@numba.njit(cache=True, nogil=True)
def choice_floyd(state, buf, pop_size, size, out):
    """``out[:size]`` = ``Generator.choice(pop_size, size, replace=False)`` (Floyd, then shuffled)."""
    mask_size = np.uint64(1.2 * size)
    mask = np.uint64(1)
    while mask <= mask_size:  # numpy's _gen_mask: all bits up to the highest of mask_size
        mask <<= _ONE
    mask -= _ONE
    hash_set = np.full(np.int64(mask) + 1, -1, dtype=np.int64)
    m = np.int64(mask)
    for j in range(pop_size - size, pop_size):
        val = _bounded(state, buf, j)
        loc = val & m
        while hash_set[loc] != -1 and hash_set[loc] != val:
            loc = (loc + 1) & m
        if hash_set[loc] == -1:
            hash_set[loc] = val
            out[j - pop_size + size] = val
        else:
            loc = j & m
            while hash_set[loc] != -1:
                loc = (loc + 1) & m
            hash_set[loc] = j
            out[j - pop_size + size] = j
    for i in range(size - 1, 0, -1):  # shuffle
        k = _bounded(state, buf, i)
        t = out[k]
        out[k] = out[i]
        out[i] = t
