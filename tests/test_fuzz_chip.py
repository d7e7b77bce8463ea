"""Fuzzing chip programs: NaN, inf, out of range, non-integer, wrong sizes and shapes, empty; arrays and the dimod API.

A program that fits the spec runs (spins of +-1, energies of the programmed model); any other is
refused with one line (``ChipProgramError`` naming the coefficient and the limit, or the model /
dimod error naming the value); nothing is clipped, and nothing hangs.
"""

from __future__ import annotations

import dimod
import numpy as np
import pytest
from fuzzing import fuzz_settings, junk, no_hang, one_line
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ising_backend import ChipProgramError, ChipSpec, EmulatedChip, IsingModel
from ising_backend.machines.chip import MAX_READS, check_num_reads

SPEC = ChipSpec()
LO, HI = SPEC.h_range
JLO, JHI = SPEC.j_range

#: coefficient values: mostly legal integers, plus every kind of illegal one
coefficient = st.one_of(
    st.integers(LO, HI),
    st.integers(LO, HI),
    st.integers(-(2**40), 2**40),
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.sampled_from([0.5, -7.0, 7.0, 7.5, -8.0, 1e300, -0.0, float("nan"), float("inf")]),
)


def _fits(h: np.ndarray, J: np.ndarray) -> bool:
    """The chip's rules, restated: at most n_spins spins; h, J finite integers in range; J strictly upper."""
    if h.shape[-1] > SPEC.n_spins:
        return False
    for arr, (lo, hi) in ((h, SPEC.h_range), (J, SPEC.j_range)):
        a = arr.astype(np.float64)
        if not (np.isfinite(a).all() and (a == np.round(a)).all() and (a >= lo).all() and (a <= hi).all()):
            return False
    n = h.shape[-1]
    return not (J.astype(np.float64) * np.tril(np.ones((n, n)))).any()


def _energy(h, J, s):
    s = s.astype(np.float64)
    return s @ h + np.einsum("...i,ij,...j->...", s, J, s)


def _elements(dtype):
    if np.dtype(dtype).kind == "b":
        return st.booleans()
    if np.dtype(dtype).kind in "iu":
        info = np.iinfo(dtype)
        return st.one_of(st.integers(max(LO, info.min), HI), st.integers(info.min, info.max))
    width = 32 if dtype == np.float32 else 64
    return st.one_of(st.integers(LO, HI).map(float), st.floats(allow_nan=True, allow_infinity=True, width=width),
                     st.sampled_from([0.5, 7.5, -8.0, float("nan"), float("inf")]))


@st.composite
def programs(draw):
    batched = draw(st.booleans())
    b = draw(st.integers(0, 3)) if batched else None
    n = draw(st.sampled_from([0, 1, 2, 3, 5, 45, 46, 60]))
    dtype = draw(st.sampled_from([np.int64, np.int8, np.uint8, np.uint64, np.float64, np.float32, np.bool_]))
    h = draw(arrays(dtype, (b, n) if batched else (n,), elements=_elements(dtype)))
    if draw(st.booleans()):  # a legal upper triangle, or anything
        J = np.triu(draw(arrays(np.int64, (n, n), elements=st.integers(JLO, JHI))), 1)
        J = np.broadcast_to(J, (b, n, n)).copy() if batched else J
    else:
        jshape = draw(st.sampled_from([(b, n, n) if batched else (n, n), (n,), (n, n + 1), (0,), (1, n, n)]))
        J = draw(arrays(np.float64, jshape, elements=_elements(np.float64)))
    return h, J


@fuzz_settings(80)
@given(prog=programs(), reads=st.integers(1, 3), seed=st.integers(0, 2**64 - 1))
def test_anneal_batch_runs_what_fits_and_names_what_does_not(prog, reads, seed):
    h, J = prog
    chip = EmulatedChip(seed=0)
    batched = h.ndim == 2
    n = h.shape[-1]
    # a single program also takes its J as a stack of one, (1, n, n)
    shape_ok = J.shape in (((h.shape[0], n, n),) if batched else ((n, n), (1, n, n))) or (J.size == 0 and n <= 1)
    Jfull = J if J.size or n > 1 else np.zeros(h.shape[:-1] + (n, n))
    expect = shape_ok and _fits(h, Jfull)
    with no_hang():
        try:
            spins, energies = chip.anneal_batch(h, J, num_reads=reads, seed=seed)
        except ChipProgramError as exc:
            assert not expect, one_line(exc)
            return
    assert expect, (h, J)
    assert spins.shape == ((h.shape[0], reads, n) if batched else (reads, n))
    assert set(np.unique(spins).tolist()) <= {-1, 1}
    if n == 0:
        assert chip.ledger.physical_calls == 0  # nothing to run, nothing charged
        return
    hb, Jb = h.reshape(-1, n).astype(np.float64), Jfull.reshape(-1, n, n).astype(np.float64)
    sp, en = spins.reshape(-1, reads, n), energies.reshape(-1, reads)
    for k in range(hb.shape[0]):
        for r in range(reads):
            assert en[k, r] == pytest.approx(_energy(hb[k], Jb[k], sp[k, r]))


labels = st.one_of(st.integers(-3, 50), st.sampled_from(["a", "b", "c", (0, 1)]))


@fuzz_settings(80)
@given(h=st.dictionaries(labels, coefficient, max_size=8), J=st.dictionaries(st.tuples(labels, labels), coefficient,
                                                                              max_size=8),
       binary=st.booleans(), reads=st.integers(1, 3))
def test_dimod_api_runs_what_fits_and_names_what_does_not(h, J, binary, reads):
    chip = EmulatedChip(seed=1)
    try:
        bqm = (dimod.BQM.from_qubo({**{(k, k): v for k, v in h.items()}, **J}) if binary
               else dimod.BQM.from_ising(h, J))
    except (TypeError, ValueError) as exc:  # dimod's own checks; the chip sees the same
        with pytest.raises(type(exc)):
            chip.sample_qubo({**{(k, k): v for k, v in h.items()}, **J}) if binary else chip.sample_ising(h, J)
        return
    try:
        model = IsingModel.from_bqm(bqm)
        expect = _fits(model.h, model.J)
    except ValueError:  # NaN / inf: not even a model
        expect = False
    with no_hang():
        try:
            ss = chip.sample(bqm, num_reads=reads, seed=0)
        except ValueError as exc:  # ChipProgramError, ModelError
            assert not expect, one_line(exc)
            one_line(exc)
            return
    assert expect, (h, J)
    assert len(ss) == reads and set(ss.variables) == set(bqm.variables)
    assert np.allclose(ss.record.energy, bqm.energies((ss.record.sample, ss.variables)))
    assert chip.ledger.physical_calls == (reads if bqm.num_variables else 0)


@fuzz_settings(60)
@given(num_reads=st.one_of(junk, st.integers(-5, 5), st.sampled_from([MAX_READS, MAX_READS + 1, 2.0, 2.5])),
       seed=st.one_of(junk, st.none(), st.integers(0, 2**64 - 1)))
def test_call_arguments_are_checked(num_reads, seed):
    chip = EmulatedChip(seed=2)
    try:
        good_reads = (not isinstance(num_reads, (bool, np.bool_)) and np.ndim(num_reads) == 0
                      and float(num_reads).is_integer() and 1 <= num_reads <= MAX_READS)
    except (TypeError, ValueError, OverflowError):
        good_reads = False
    good_seed = seed is None or (isinstance(seed, (int, np.integer)) and not isinstance(seed, (bool, np.bool_))
                                 and 0 <= seed < 2**64)
    if good_reads and num_reads > 16:  # legal but slow to run: the check alone
        assert check_num_reads(num_reads) == num_reads
        num_reads = 16
    with no_hang():
        try:
            spins, _ = chip.anneal_batch(np.array([1, -1]), np.array([[0, 2], [0, 0]]), num_reads=num_reads, seed=seed)
        except ValueError as exc:
            assert not (good_reads and good_seed), one_line(exc)
            assert ("num_reads" in str(exc) and "[1, 1048576]" in str(exc)) or (
                "seed" in str(exc) and "[0, 2**64)" in str(exc)), one_line(exc)
            return
    assert good_reads and good_seed and spins.shape == (int(num_reads), 2)
