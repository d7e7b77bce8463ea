"""Compiled mapping kernels against the numpy reference implementations (hypothesis).

Every result is compared bit for bit (``tobytes``: signed zeros included), errors
by type and message.
"""

import copy
import pickle
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ising_backend import (
    MERGE_STYLES,
    QUANTIZE_RULES,
    ChipSpec,
    IsingModel,
    MergeError,
    ModelError,
    merge_spins,
    quantize,
    saturate,
    saturate_mapping,
)
from ising_backend.mapping._merge_kernel import (
    MERGE_COUPLING_UNFIT,
    MERGE_FIELD_UNFIT,
    MERGE_OK,
    MERGE_TOO_MANY_SPINS,
    STYLE_IDS,
    decode_copies,
    merge_batch,
    merge_styles,
    merge_styles_flat,
)
from ising_backend.mapping._quantize_kernel import RULE_IDS, quantize_rules
from mapping_reference import decode_ref, merge_spins_ref, quantize_ref, saturate_ref
from ising_backend.mapping.merge import merge_error_message
from ising_backend.mapping.quantize import quantize_stack

SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow])
ALL_STYLES = np.array([STYLE_IDS[s] for s in MERGE_STYLES], dtype=np.int64)


def _same_model(a: IsingModel, b: IsingModel) -> bool:
    return (a.h.tobytes() == b.h.tobytes() and a.J.tobytes() == b.J.tobytes() and a.h.shape == b.h.shape
            and a.J.shape == b.J.shape and a.offset == b.offset and a.labels == b.labels)


def _random_model(rng, n, kind, mag, density):
    """A logical model: integer coefficients (``kind`` 0), reals (1), or reals with repeated values (2)."""
    if kind == 0:
        h = rng.integers(-mag, mag + 1, n).astype(float)
        J = rng.integers(-mag, mag + 1, (n, n)).astype(float)
    elif kind == 1:
        h = rng.normal(0, mag, n)
        J = rng.normal(0, mag, (n, n))
    else:
        vals = np.array([0.0, -0.0, 0.5, -1.25, 2.0, mag, -mag, 3.5])
        h, J = rng.choice(vals, n), rng.choice(vals, (n, n))
    J = np.triu(J * (rng.random((n, n)) < density), 1)
    return IsingModel(h, J, float(rng.normal()))


model_params = dict(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 45),
    kind=st.integers(0, 2),
    mag=st.sampled_from([1, 3, 7, 8, 15, 40, 200]),
    density=st.sampled_from([0.0, 0.1, 0.5, 1.0]),
)


# ------------------------------------------------------------------ merging
def _check_merge_same(model, style, spec, scale=1.0, tie=None):
    try:
        ref = merge_spins_ref(model, style, spec, scale=scale, tie=tie)
    except MergeError as exc:
        with pytest.raises(MergeError) as got:
            merge_spins(model, style, spec, scale=scale, tie=tie)
        assert str(got.value) == str(exc)
        return None
    new = merge_spins(model, style, spec, scale=scale, tie=tie)
    assert _same_model(ref.physical, new.physical)
    assert len(ref.copies) == len(new.copies)
    for a, b in zip(ref.copies, new.copies):
        assert a.dtype == b.dtype and np.array_equal(a, b)
    assert (new.style, new.scale, new.logical) == (ref.style, ref.scale, model)
    return ref, new


@settings(max_examples=150, **SETTINGS)
@given(**model_params, budget=st.integers(-2, 45), scale=st.sampled_from([1.0, 0.5, 2.0, 16.0, 0.37]),
       lim=st.sampled_from([(-7, 7), (-1, 1), (-8, 7), (-3, 15)]), tie=st.sampled_from([None, 1, 2]))
def test_merge_matches_reference(seed, n, kind, mag, density, budget, scale, lim, tie):
    rng = np.random.default_rng(seed)
    model = _random_model(rng, n, kind, mag, density)
    spec = ChipSpec(n_spins=max(1, n + budget), h_range=lim, j_range=lim)
    for style in MERGE_STYLES:
        _check_merge_same(model, style, spec, scale, tie)


@settings(max_examples=80, **SETTINGS)
@given(**model_params, budget=st.integers(0, 45), tie=st.sampled_from([7, 3]))
def test_merge_batch_matches_single_styles(seed, n, kind, mag, density, budget, tie):
    rng = np.random.default_rng(seed)
    model = _random_model(rng, n, kind, mag, density)
    n_spins = max(1, min(45, n + budget))
    spec = ChipSpec(n_spins=n_spins)
    H = np.rint(model.h).astype(np.int64)
    C = np.rint(model.J).astype(np.int64)
    styles = np.concatenate([ALL_STYLES, ALL_STYLES[::-1]])
    status, err, a, n_phys, h, J, off, ptr, idx = merge_styles(H, C, styles, 7, 7, tie, n_spins)
    names = [MERGE_STYLES[s] for s in styles]
    N = h.shape[1]
    assert J.shape == (len(styles), N, N) and N == max(n_phys, default=0)
    for k, style in enumerate(names):
        try:
            ref = merge_spins_ref(model, style, spec, tie=tie)
        except MergeError as exc:
            assert status[k] in (MERGE_FIELD_UNFIT, MERGE_COUPLING_UNFIT, MERGE_TOO_MANY_SPINS)
            assert merge_error_message(int(status[k]), err[k], H, C, a[k], 7, 7, n_spins) == str(exc)
            assert n_phys[k] == 0 and not h[k].any() and not J[k].any()
            continue
        m = ref.physical.n
        assert status[k] == MERGE_OK and n_phys[k] == m
        assert h[k, :m].tobytes() == ref.physical.h.tobytes() and not h[k, m:].any()
        assert J[k, :m, :m].tobytes() == ref.physical.J.tobytes() and not J[k, m:].any() and not J[k, :, m:].any()
        assert model.offset + off[k] == ref.physical.offset
        assert np.array_equal(a[k], [len(c) for c in ref.copies])
        for i, c in enumerate(ref.copies):
            assert np.array_equal(idx[k, ptr[k, i]:ptr[k, i + 1]], c)


@settings(max_examples=80, **SETTINGS)
@given(**model_params, budget=st.integers(0, 45), tie=st.sampled_from([7, 3]),
       dtype=st.sampled_from([np.int16, np.int64, np.float64]), styles=st.lists(st.integers(0, 3), max_size=5))
def test_merge_styles_flat_writes_merge_styles_mappings(seed, n, kind, mag, density, budget, tie, dtype, styles):
    rng = np.random.default_rng(seed)
    model = _random_model(rng, n, kind, mag, density)
    n_spins = max(1, min(45, n + budget))
    H = np.rint(model.h).astype(np.int64)
    C = np.rint(model.J).astype(np.int64)
    ids = np.array(styles, dtype=np.int64)
    k = len(ids)
    status, _err, a, n_phys, h, J, _off, ptr, idx = merge_styles(H, C, ids, 7, 7, tie, n_spins)
    # buffers full of garbage: everything a mapping owns must be written
    h_out = rng.integers(-9, 10, k * 45 + 3).astype(dtype)
    J_out = rng.integers(-9, 10, k * 45 * 45 + 3).astype(dtype)
    ptr_out = rng.integers(-9, 10, (k, n + 4))
    idx_out = rng.integers(-9, 10, (k, 46))
    before = (h_out.copy(), J_out.copy(), ptr_out.copy(), idx_out.copy())
    got = np.full(k, -5, dtype=np.int64)
    w = merge_styles_flat(H, C, ids, 7, 7, tie, n_spins, h_out, J_out, ptr_out, idx_out, got)
    assert np.array_equal(got, status)
    ok = status == MERGE_OK
    assert w == (int(n_phys[ok].max()) if ok.any() else 0)
    # merge_styles pads to its widest mapping: the same
    assert np.array_equal(h_out[k * w:], before[0][k * w:]) and np.array_equal(J_out[k * w * w:], before[1][k * w * w:])
    for s in range(k):
        hs, Js = h_out[s * w:(s + 1) * w], J_out[s * w * w:(s + 1) * w * w].reshape(w, w)
        if not ok[s]:  # a style that does not fit: zeros, never a partial mapping
            assert not hs.any() and not Js.any() and not ptr_out[s, : n + 1].any() and not idx_out[s, :w].any()
            continue
        assert np.array_equal(hs, h[s, :w]) and np.array_equal(Js, J[s, :w, :w])
        assert np.array_equal(ptr_out[s, : n + 1], ptr[s]) and np.array_equal(idx_out[s, :w], idx[s, :w])


@settings(max_examples=60, **SETTINGS)
@given(seed=st.integers(0, 2**32 - 1), models=st.integers(1, 5), styles=st.lists(st.integers(0, 3), max_size=5))
def test_merge_batch_rows_match_reference(seed, models, styles):
    rng = np.random.default_rng(seed)
    sizes = rng.integers(0, 20, models)
    n_max = int(sizes.max())
    H = rng.integers(-99, 100, (models, n_max))  # padding is garbage: the kernel must ignore it
    C = rng.integers(-99, 100, (models, n_max, n_max))
    logical = []
    for b, n in enumerate(sizes):
        m = _random_model(rng, int(n), 0, int(rng.choice([5, 9, 20])), 0.3)
        H[b, :n], C[b, :n, :n] = m.h, m.J
        logical.append(m)
    ids = np.array(styles, dtype=np.int64)
    status, err, a, n_phys, h, J, off, ptr, idx = merge_batch(H, C, sizes, ids, 7, 7, 7, 45)
    R = models * len(styles)
    assert status.shape == (R,) and a.shape == (R, n_max) and ptr.shape == (R, n_max + 1) and h.shape[0] == R
    for r in range(R):
        m, style = logical[r // len(styles)], MERGE_STYLES[styles[r % len(styles)]]
        try:
            ref = merge_spins_ref(m, style)
        except MergeError as exc:
            Hb, Cb = np.rint(m.h).astype(np.int64), np.rint(m.J).astype(np.int64)
            assert merge_error_message(int(status[r]), err[r], Hb, Cb, a[r, :m.n], 7, 7, 45) == str(exc)
            continue
        k = ref.physical.n
        assert status[r] == MERGE_OK and n_phys[r] == k and m.offset + off[r] == ref.physical.offset
        assert h[r, :k].tobytes() == ref.physical.h.tobytes() and not h[r, k:].any()
        assert J[r, :k, :k].tobytes() == ref.physical.J.tobytes() and not J[r, k:].any() and not J[r, :, k:].any()
        assert np.all(ptr[r, m.n:] == k)
        for i, c in enumerate(ref.copies):
            assert np.array_equal(idx[r, ptr[r, i]:ptr[r, i + 1]], c)


def test_merge_edge_cases():
    spec = ChipSpec()
    empty = IsingModel(np.zeros(0), np.zeros((0, 0)), 2.0)
    one = IsingModel([100.0], np.zeros((1, 1)))
    zeros = IsingModel(np.zeros(45), np.zeros((45, 45)))
    fits = IsingModel([7.0, -7.0, 0.0], [[0, 7.0, -7.0], [0, 0, 3.0], [0, 0, 0]], 0.5)
    full = IsingModel(np.full(45, 8.0), np.zeros((45, 45)))  # needs copies, no spare spin
    huge = IsingModel([400.0, 0.0], [[0, 300.0], [0, 0]])  # exhausts the budget
    big_j = IsingModel(np.zeros(3), [[0, 5000.0, 0], [0, 0, 0], [0, 0, 0]])
    for style in MERGE_STYLES:
        for model in (empty, one, zeros, fits, full, huge, big_j):
            out = _check_merge_same(model, style, spec)
            if model is empty:
                assert out[1].physical.n == 0 and out[1].physical.offset == 2.0 and out[1].copies == ()
            if model in (zeros, fits):
                assert out[1].n_extra == 0
        _check_merge_same(one, style, ChipSpec(h_range=(-1, 1), j_range=(-1, 1)))  # saturated ranges
        _check_merge_same(huge, style, spec, tie=1)
        with pytest.raises(MergeError, match=r"h\[0\] = 8 .*needs 2 copies, has 1; all 45 chip spins"):
            merge_spins(full, style, spec)
        with pytest.raises(MergeError, match=r"J\[0, 1\] = 5000 .*exceeds 7 x"):
            merge_spins(big_j, style, spec)
        with pytest.raises(MergeError, match="model has 46 spins; the chip has 45"):
            merge_spins(IsingModel(np.zeros(46), np.zeros((46, 46))), style, spec)
    status, err, *_ = merge_styles(np.zeros(46, dtype=np.int64), np.zeros((46, 46), dtype=np.int64), ALL_STYLES,
                                   7, 7, 7, 45)
    assert np.all(status == MERGE_TOO_MANY_SPINS) and np.all(err == [46, 45])


def test_merged_model_copies_and_layout_are_consistent():
    model = IsingModel([20.0, 3.0, -2.0, 1.0], np.triu(np.array([[0, 15, 2, 9], [0, 0, 9, 1], [0, 0, 0, -3],
                                                                  [0, 0, 0, 0.0]]), 1))
    for style in MERGE_STYLES:
        mm = merge_spins(model, style)
        ptr, idx = mm.layout()
        assert ptr[0] == 0 and ptr[-1] == mm.physical.n and sorted(idx) == list(range(mm.physical.n))
        for i, c in enumerate(mm.copies):
            assert c[0] == i and np.array_equal(idx[ptr[i]:ptr[i + 1]], c)
        assert "copies=" in repr(mm)
    for clone in (pickle.loads(pickle.dumps(mm)), copy.deepcopy(mm)):  # the lazily made copies survive
        assert [list(c) for c in clone.copies] == [list(c) for c in mm.copies]
        assert _same_model(clone.physical, mm.physical)
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        mm.nothing
    sat = saturate_mapping(model)
    assert [list(c) for c in sat.copies] == [[0], [1], [2], [3]]
    assert _same_model(sat.physical, IsingModel(saturate_ref(model, 1.0).h, saturate_ref(model, 1.0).J))


# ------------------------------------------------------------------ decoding
@settings(max_examples=100, **SETTINGS)
@given(**model_params, reads=st.integers(0, 6), lead=st.sampled_from([(), (2,), (3, 2)]), pad=st.integers(0, 3),
       dtype=st.sampled_from([np.int8, np.int64, np.float64]), bias=st.floats(0.0, 1.0))
def test_decode_matches_reference(seed, n, kind, mag, density, reads, lead, pad, dtype, bias):
    rng = np.random.default_rng(seed)
    model = _random_model(rng, n, kind, mag, density)
    spec = ChipSpec(n_spins=45)
    for style in MERGE_STYLES:
        try:
            mm = merge_spins(model, style, spec)
        except MergeError:
            continue
        N = mm.physical.n
        shape = lead + (reads,) + (N + pad,) if lead else (N + pad,)
        # mostly aligned copies (bias) so majority, ties and broken counts all occur
        base = rng.choice(np.array([-1, 1]), shape[:-1] + (n,))
        s = np.empty(shape, dtype=np.int64)
        s[..., :n] = base
        for i, c in enumerate(mm.copies):
            for p in c[1:]:
                flip = rng.random(shape[:-1]) < bias
                s[..., p] = np.where(flip, -base[..., i], base[..., i])
        s[..., N:] = rng.choice(np.array([-1, 1]), shape[:-1] + (pad,))
        s = s.astype(dtype)
        for method in ("majority", "first"):
            ref_l, ref_b = decode_ref(mm.copies, N, s, method)
            new_l, new_b = mm.decode(s, method)
            assert new_l.dtype == ref_l.dtype and new_l.shape == ref_l.shape and np.array_equal(new_l, ref_l)
            assert new_b.shape == ref_b.shape and np.array_equal(new_b, ref_b)


@settings(max_examples=60, **SETTINGS)
@given(seed=st.integers(0, 2**32 - 1), programs=st.integers(1, 6), reads=st.integers(0, 5),
       first=st.booleans())
def test_decode_batch_over_programs(seed, programs, reads, first):
    rng = np.random.default_rng(seed)
    mms = []
    while len(mms) < programs:
        n = int(rng.integers(0, 12))
        model = _random_model(rng, n, 0, int(rng.choice([5, 12, 30])), 0.5)
        try:
            mms.append(merge_spins(model, MERGE_STYLES[int(rng.integers(4))]))
        except MergeError:
            pass
    W = max(m.physical.n for m in mms)
    n_max = max(m.logical.n for m in mms)
    spins = rng.choice(np.array([-1, 1], dtype=np.int8), (programs, reads, W))
    ptr = np.zeros((programs, n_max + 1), dtype=np.int64)
    idx = np.zeros((programs, W), dtype=np.int64)
    n_log = np.array([m.logical.n for m in mms], dtype=np.int64)
    for p, m in enumerate(mms):
        pp, ii = m.layout()
        ptr[p, :pp.size] = pp
        idx[p, :ii.size] = ii
    out, broken = decode_copies(spins, n_log, ptr, idx, first)
    assert out.shape == (programs, reads, n_max) and broken.shape == (programs, reads)
    for p, m in enumerate(mms):
        ref_l, ref_b = decode_ref(m.copies, m.physical.n, spins[p], "first" if first else "majority")
        assert np.array_equal(out[p, :, :m.logical.n], ref_l) and not out[p, :, m.logical.n:].any()
        assert np.array_equal(broken[p], ref_b)


def test_decode_rejects_short_spins_and_bad_method():
    mm = merge_spins(IsingModel([20.0, 1.0], np.zeros((2, 2))), "overload")
    with pytest.raises(ValueError, match="spins have 2 entries; the physical model has 4"):
        mm.decode(np.ones(2, dtype=np.int8))
    with pytest.raises(ValueError, match="method"):
        mm.decode(np.ones(4, dtype=np.int8), "vote")
    logical, broken = mm.decode(np.ones(4, dtype=np.int8))
    assert logical.shape == (2,) and broken.shape == ()


# ------------------------------------------------------------------ quantization
finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False, allow_subnormal=False)
ranges = st.sampled_from([(-7, 7), (-15, 15), (-8, 7), (-1, 1), (-3, 5)])
q_options = dict(h_range=ranges, j_range=ranges, keep_sign=st.booleans(),
                 percentile=st.sampled_from([95.0, 50.0, 100.0, 12.5, 99.9, 1e-3, 95]))


def _check_quantize_same(model, h_range, j_range, keep_sign, percentile):
    kw = dict(keep_sign=keep_sign, percentile=percentile)
    refs = [quantize_ref(model, rule, h_range, j_range, **kw) for rule in QUANTIZE_RULES]
    for rule, ref in zip(QUANTIZE_RULES, refs):
        assert _same_model(quantize(model, rule, h_range, j_range, **kw), ref), rule
    H, J = quantize_stack(model, QUANTIZE_RULES, h_range, j_range, **kw)
    assert H.shape == (4, model.n) and J.shape == (4, model.n, model.n)
    for r, ref in enumerate(refs):
        assert H[r].tobytes() == ref.h.tobytes() and J[r].tobytes() == ref.J.tobytes()
    H2, J2 = quantize_stack(model, ("sqrt", "linear"), h_range, j_range, **kw)
    assert H2.tobytes() == np.stack([refs[3].h, refs[0].h]).tobytes()


@settings(max_examples=120, **SETTINGS)
@given(data=st.data(), n=st.integers(0, 6), **q_options)
def test_quantize_matches_reference_on_arbitrary_floats(data, n, h_range, j_range, keep_sign, percentile):
    h = data.draw(arrays(np.float64, n, elements=finite))
    J = np.triu(data.draw(arrays(np.float64, (n, n), elements=finite)), 1)
    _check_quantize_same(IsingModel(h, J, 1.5, labels=[f"v{i}" for i in range(n)]), h_range, j_range, keep_sign,
                         percentile)


@settings(max_examples=100, **SETTINGS)
@given(**model_params, **q_options)
def test_quantize_matches_reference_up_to_45_spins(seed, n, kind, mag, density, h_range, j_range, keep_sign,
                                                   percentile):
    model = _random_model(np.random.default_rng(seed), n, kind, mag, density)
    _check_quantize_same(model, h_range, j_range, keep_sign, percentile)


def test_quantize_edge_cases():
    for model in (IsingModel(np.zeros(0), np.zeros((0, 0))), IsingModel(np.zeros(5), np.zeros((5, 5))),
                  IsingModel([3.0], np.zeros((1, 1))), IsingModel([-0.0, 0.0, -2.0], np.zeros((3, 3))),
                  IsingModel([1.0, 1.0], [[0, 1.0], [0, 0]]), IsingModel([1e-300, 1.0], np.zeros((2, 2)))):
        for lim in ((-7, 7), (-1, 1)):
            for keep_sign in (True, False):
                _check_quantize_same(model, lim, lim, keep_sign, 95.0)
    tiny = IsingModel([5e-324, 0.0], np.zeros((2, 2)))  # its relative size once underflowed (0 / 0 = NaN)
    for rule in QUANTIZE_RULES:
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)
            ref = quantize_ref(tiny, rule)
        assert ref.h.tolist() == [7.0, 0.0] and _same_model(quantize(tiny, rule), ref)
    # a numpy float percentile is the same number as a Python float (one compiled path, float64)
    m = IsingModel([0.3, -4.0, 2.5], np.triu(np.full((3, 3), 1.7), 1))
    for p in (np.float32(80.0), np.float64(80.0), 80):
        assert _same_model(quantize(m, "clip95", percentile=p), quantize(m, "clip95", percentile=80.0))
    assert not _same_model(quantize(m, "clip95", percentile=80.0), quantize(m, "clip95", percentile=100.0))
    status, h, J = quantize_rules(np.zeros(0), np.zeros((0, 0)), np.array([RULE_IDS["rank"]]), 7.0, 7.0, True, 95.0)
    assert status.shape == (1,) and h.shape == (1, 0) and J.shape == (1, 0, 0)


@settings(max_examples=100, **SETTINGS)
@given(data=st.data(), n=st.integers(0, 6), scale=st.sampled_from([1.0, 0.5, 16.0, 3.3, 1e-3]),
       h_range=st.sampled_from([(-7, 7), (0, 7), (-3, 0), (2, 9), (5, -5)]),
       j_range=st.sampled_from([(-7, 7), (-7, 0), (0, 0), (-1, 1)]))
def test_saturate_matches_reference(data, n, scale, h_range, j_range):
    h = data.draw(arrays(np.float64, n, elements=finite))
    J = np.triu(data.draw(arrays(np.float64, (n, n), elements=finite)), 1)
    model = IsingModel(h, J, data.draw(finite))
    assert _same_model(saturate(model, scale, h_range, j_range), saturate_ref(model, scale, h_range, j_range))


def test_saturate_outside_zero_range_and_overflow_behave_as_before():
    model = IsingModel([1.0, 2.0], [[0, 3.0], [0, 0]], 1e308)
    with pytest.raises(ModelError) as ref:
        saturate_ref(model, 1.0, (-7, 7), (1, 7))
    with pytest.raises(ModelError) as got:
        saturate(model, 1.0, (-7, 7), (1, 7))
    assert str(got.value) == str(ref.value)
    with pytest.raises(ModelError, match="offset"):
        saturate(model, 10.0)


# ------------------------------------------------------------------ trusted construction
def test_trusted_model_equals_validated_model():
    rng = np.random.default_rng(0)
    h, J = rng.normal(size=5), np.triu(rng.normal(size=(5, 5)), 1)
    m = IsingModel.trusted(h.copy(), J.copy(), 1.5, ("a", "b", "c", "d", "e"))
    v = IsingModel(h, J, 1.5, ("a", "b", "c", "d", "e"))
    assert _same_model(m, v) and not m.h.flags.writeable and not m.J.flags.writeable
    S = rng.choice([-1, 1], (7, 5))
    assert np.array_equal(m.energy(S), v.energy(S))
    assert _same_model(m.scaled(2.0), v.scaled(2.0))
