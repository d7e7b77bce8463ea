"""ising_backend.compiled_rng: a Generator handed to compiled code by address draws exactly as
the Generator itself, and leaves it in the same state."""

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ising_backend import as_generator, rng_handle


@numba.njit(cache=True)
def _draws(rng, n, m):
    """A mix of the draws the planning loops make: chip seeds, bounded ints, a permutation, a float."""
    g = as_generator(rng)
    out = np.empty(2 * n + m, dtype=np.int64)
    for i in range(n):
        out[i] = g.integers(0, 9223372036854775807)
        out[n + i] = g.integers(0, 3 + i)
    out[2 * n:] = g.permutation(m)
    return out, g.random()


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 12), m=st.integers(1, 9))
def test_handle_draws_the_generators_own_stream(seed, n, m):
    direct, via_handle, python = (np.random.default_rng(seed) for _ in range(3))
    a, fa = _draws(direct, n, m)
    b, fb = _draws(rng_handle(via_handle), n, m)
    assert np.array_equal(a, b) and fa == fb
    # the handle advanced the Generator in place: the next draws agree, in Python too
    assert via_handle.bit_generator.state == direct.bit_generator.state
    assert via_handle.integers(0, 2**62, 4).tolist() == direct.integers(0, 2**62, 4).tolist()
    # and the numbers are numpy's own for the same calls
    seeds, bounded = [], []
    for i in range(n):
        seeds.append(int(python.integers(0, 9223372036854775807)))
        bounded.append(int(python.integers(0, 3 + i)))
    assert a.tolist() == seeds + bounded + python.permutation(m).tolist() and fa == python.random()


def test_handle_of_other_bit_generators():
    for bitgen in (np.random.PCG64DXSM, np.random.Philox, np.random.SFC64, np.random.MT19937):
        a, b = np.random.Generator(bitgen(5)), np.random.Generator(bitgen(5))
        assert np.array_equal(_draws(a, 5, 4)[0], _draws(rng_handle(b), 5, 4)[0])


def test_handle_is_memoised_for_the_last_generator_and_read_only():
    rng = np.random.default_rng(1)
    handle = rng_handle(rng)
    assert rng_handle(rng) is handle
    assert handle.dtype == np.uint64 and handle.shape == (4,) and not handle.flags.writeable
    other = rng_handle(np.random.default_rng(1))
    assert other is not handle and other[0] != handle[0]  # its own state; the same functions
    assert other[1:].tolist() == handle[1:].tolist()


def test_bad_input_is_named():
    with pytest.raises(TypeError, match="numpy.random.Generator, got int"):
        rng_handle(3)
    with pytest.raises(TypeError, match="RandomState"):
        rng_handle(np.random.RandomState(0))
    rng = np.random.default_rng(0)
    assert as_generator(rng) is rng
    with pytest.raises(TypeError, match="only usable in compiled code"):
        as_generator(rng_handle(rng))
