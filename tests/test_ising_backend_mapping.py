"""Mapping toolkit: quantization (hypothesis), spin merging, branching, block batching."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ising_backend import (
    MERGE_STYLES,
    QUANTIZE_RULES,
    BranchError,
    ChipSpec,
    EmulatedChip,
    IsingModel,
    MergeError,
    branch,
    check_program,
    freeze_order,
    merge_spins,
    pack_blocks,
    plan_packs,
    quantize,
    saturate,
    unpack_blocks,
)


def _states(n):
    return np.array(list(itertools.product([-1, 1], repeat=n)), dtype=np.int8)


coeffs = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False, allow_subnormal=False)


@settings(max_examples=60, deadline=None)
@given(
    data=st.data(),
    n=st.integers(1, 7),
    rule=st.sampled_from(QUANTIZE_RULES),
    lim=st.sampled_from([(-7, 7), (-15, 15), (-8, 7), (-1, 1)]),
)
def test_quantize_integer_in_range_zero_and_sign_preserving(data, n, rule, lim):
    h = data.draw(arrays(np.float64, n, elements=coeffs))
    J = np.triu(data.draw(arrays(np.float64, (n, n), elements=coeffs)), 1)
    m = IsingModel(h, J)
    q = quantize(m, rule, lim, lim)
    check_program(q.h, q.J, ChipSpec(n_spins=max(n, 1), h_range=lim, j_range=lim))  # integer, in range
    for orig, new in ((m.h, q.h), (m.J, q.J)):
        assert np.array_equal(orig == 0, new == 0)
        assert np.array_equal(np.sign(orig), np.sign(new))


def test_quantize_rules_differ_and_keep_order():
    rng = np.random.default_rng(0)
    m = IsingModel(rng.normal(size=8), np.triu(rng.lognormal(0, 1.5, (8, 8)), 1))
    outs = {r: quantize(m, r) for r in QUANTIZE_RULES}
    assert len({o.J.tobytes() for o in outs.values()}) == 4
    iu = np.triu_indices(8, 1)
    for r, o in outs.items():  # monotone: a larger magnitude never maps lower
        a, b = np.abs(m.J[iu]), np.abs(o.J[iu])
        order = np.argsort(a)
        assert np.all(np.diff(b[order]) >= 0), r
    assert np.abs(outs["linear"].J).max() == 7
    with pytest.raises(ValueError, match="rule"):
        quantize(m, "cubic")


def test_saturate_is_fixed_scale_and_clips():
    m = IsingModel([0.2, 30.0], [[0, -12.0], [0, 0]], 1.0)
    s = saturate(m, 1.0)
    assert list(s.h) == [0.0, 7.0] and s.J[0, 1] == -7.0
    s2 = saturate(m, 0.5)
    assert list(s2.h) == [0.0, 7.0] and s2.J[0, 1] == -6.0 and s2.offset == 0.5


def _overloaded_instance(rng, n):
    h = rng.integers(-5, 6, n).astype(float)
    J = np.triu(rng.integers(-4, 5, (n, n)), 1).astype(float)
    h[rng.integers(n)] = rng.choice([-1, 1]) * rng.integers(8, 15)
    i, j = sorted(rng.choice(n, 2, replace=False))
    J[i, j] = rng.choice([-1, 1]) * rng.integers(8, 15)
    return IsingModel(h, J, 0.5)


@pytest.mark.parametrize("style", MERGE_STYLES)
def test_merge_fits_chip_and_keeps_ground_state(style):
    rng = np.random.default_rng(7)
    for _ in range(12):
        n = int(rng.integers(4, 8))
        m = _overloaded_instance(rng, n)
        spec = ChipSpec(n_spins=n + 5)
        mm = merge_spins(m, style, spec)
        check_program(mm.physical.h, mm.physical.J, spec)  # fits, no clipping
        assert mm.n_extra >= 1
        S = _states(mm.physical.n)
        E = mm.physical.energy(S)
        logical, broken = mm.decode(S)
        aligned = broken == 0
        assert np.array_equal(E[aligned], m.energy(logical[aligned]))  # aligned copies: exact logical energy
        b = int(np.argmin(E))
        assert broken[b] == 0
        assert m.energy(logical[b]) == m.energy(_states(n)).min()


def test_merge_styles_differ_and_decode_reports_broken_ties():
    # J[1, 2] = 10 overflows.  Spin 1 is stronger (10 + 6), spin 2 has more neighbours (3).
    J = np.zeros((5, 5))
    J[1, 2], J[1, 3], J[0, 2], J[2, 4] = 10, 6, 1, 1
    views = {s: merge_spins(IsingModel(np.zeros(5), J), s, ChipSpec(n_spins=12)) for s in MERGE_STYLES}
    assert [len(c) for c in views["overload"].copies] == [1, 2, 1, 1, 1]  # largest excess, lowest index
    assert [len(c) for c in views["max_coeff"].copies] == [1, 2, 1, 1, 1]  # stronger endpoint
    assert [len(c) for c in views["high_degree"].copies] == [1, 1, 2, 1, 1]  # more neighbours
    assert views["overload"].physical.J[1, 2] == 7 and views["max_coeff"].physical.J[1, 2] == 5  # spill / even
    assert len({(v.physical.h.tobytes(), v.physical.J.tobytes()) for v in views.values()}) >= 3
    m = IsingModel([20.0, 3.0, -2.0, 1.0], np.triu(np.array([[0, 15, 2, 9], [0, 0, 9, 1], [0, 0, 0, -3], [0, 0, 0, 0.0]]), 1))
    views = {s: merge_spins(m, s, ChipSpec(n_spins=12)) for s in MERGE_STYLES}
    mm = views["overload"]
    s = np.ones(mm.physical.n, dtype=np.int8)
    c = mm.copies[0]
    assert len(c) >= 3
    s[c[-1]] = -1  # one copy of 3+ disagrees: majority keeps +1, one broken tie
    logical, broken = mm.decode(s)
    assert logical[0] == 1 and broken == 1
    first, _ = mm.decode(s, method="first")
    assert first[0] == 1


def test_merge_refuses_when_budget_runs_out_and_never_needed_when_fitting():
    m = IsingModel([400.0, 0.0], np.zeros((2, 2)))
    with pytest.raises(MergeError, match=r"h\[0\] = 400 .*needs 58 copies.*45 chip spins"):
        merge_spins(m, "overload")
    fit = IsingModel([3.0, -2.0], [[0, 7.0], [0, 0]])
    mm = merge_spins(fit, "balanced")
    assert mm.n_extra == 0 and np.array_equal(mm.physical.J, fit.J)
    sat = merge_spins(m, "saturate")
    assert sat.physical.h[0] == 7


def test_merge_runs_on_the_chip_and_decodes():
    rng = np.random.default_rng(1)
    m = _overloaded_instance(rng, 6)
    chip = EmulatedChip(ChipSpec().noise_free(), seed=0)
    mm = merge_spins(m, "balanced")
    spins, energies = chip.anneal_batch(mm.physical.h, mm.physical.J, num_reads=20)
    logical, broken = mm.decode(spins)
    assert logical.shape == (20, 6) and broken.shape == (20,)
    ground = m.energy(_states(6)).min()
    assert np.any(m.energy(logical) == ground)


def test_branching_covers_all_assignments_and_finds_exact_optimum():
    rng = np.random.default_rng(3)
    m = IsingModel(rng.normal(size=11), np.triu(rng.normal(size=(11, 11)), 1), 0.7)
    branches = branch(m, budget=8)
    assert len(branches) == 8
    frozen = branches[0].frozen
    assert set(frozen) == set(freeze_order(m)[:3])
    seen = set()
    S = _states(8)
    best = np.inf
    for br in branches:
        full = br.decode(S)
        assert np.allclose(br.model.energy(S), m.energy(full))  # branch energy = full energy
        seen.update(map(bytes, full.astype(np.int8)))
        best = min(best, br.model.energy(S).min())
    assert len(seen) == 2**11  # every assignment exactly once
    assert best == pytest.approx(m.energy(_states(11)).min())
    assert len(branch(IsingModel(np.zeros(49), np.zeros((49, 49))), 45)) == 16
    assert len(branch(m, 20)) == 1 and branch(m, 20)[0].frozen.size == 0
    with pytest.raises(BranchError, match="max_frozen"):
        branch(IsingModel(np.zeros(60), np.zeros((60, 60))), 45)
    with pytest.raises(BranchError, match="distinct"):
        branch(m, 9, frozen=[1, 1])


def test_block_batching_round_trip():
    rng = np.random.default_rng(4)
    models = [IsingModel(rng.integers(-7, 8, k), np.triu(rng.integers(-7, 8, (k, k)), 1), float(k)) for k in (5, 9, 3)]
    packed, slices = pack_blocks(models, n_spins=45)
    assert packed.n == 17
    cross = packed.J.copy()
    for sl in slices:
        cross[sl, sl] = 0
    assert not cross.any()  # zero cross-block couplings
    S = rng.choice([-1, 1], size=(6, 17)).astype(np.int8)
    parts = unpack_blocks(S, slices)
    assert np.array_equal(np.concatenate(parts, axis=-1), S)
    assert np.allclose(packed.energy(S), sum(m.energy(p) for m, p in zip(models, parts)))
    with pytest.raises(ValueError, match="45"):
        pack_blocks(models * 3, n_spins=45)
    packs = plan_packs([20, 30, 10, 25, 15], 45)
    assert sorted(i for p in packs for i in p) == [0, 1, 2, 3, 4]
    assert all(sum([20, 30, 10, 25, 15][i] for i in p) <= 45 for p in packs) and len(packs) == 3
