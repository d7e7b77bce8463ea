"""EmulatedChip: dimod conformance, refusals, determinism, ledger, annealer statistics."""

import itertools
import math
import unittest

import dimod
import dimod.testing
import numpy as np
import pytest

from ising_backend import CallLedger, ChipProgramError, ChipSpec, EmulatedChip, IsingModel


@dimod.testing.load_sampler_bqm_tests(lambda: EmulatedChip(seed=0), max_num_variables=1)
class TestChipDimodBQMs(unittest.TestCase):
    """dimod's own sampler tests on the BQMs that fit the chip (larger ones have non-integer QUBO terms)."""


def test_sampler_api_and_properties():
    chip = EmulatedChip(seed=0)
    dimod.testing.assert_sampler_api(chip)
    assert chip.properties["h_range"] == [-7, 7] and chip.properties["j_range"] == [-7, 7]
    assert chip.properties["num_spins"] == 45 and chip.properties["num_cores"] == 8
    assert set(chip.parameters) == {"num_reads", "seed"}


def test_sampleset_energies_on_fitting_programs():
    rng = np.random.default_rng(0)
    chip = EmulatedChip(seed=1)
    for n in (2, 10, 45):
        h = rng.integers(-7, 8, n)
        J = np.triu(rng.integers(-7, 8, (n, n)), 1)
        bqm = IsingModel(h, J, 3.0).to_bqm()
        ss = chip.sample(bqm, num_reads=5)
        dimod.testing.assert_sampleset_energies(ss, bqm)
        assert len(ss) == 5 and ss.info["ledger"]["physical_calls"] == 5
    qubo = {(0, 0): 4.0, (1, 1): -4.0, (0, 1): 8.0}  # integer after x = (1 + s) / 2
    ss = chip.sample_qubo(qubo, num_reads=3)
    assert ss.vartype is dimod.BINARY
    dimod.testing.assert_sampleset_energies(ss, dimod.BQM.from_qubo(qubo))
    assert ss.first.energy == -4.0


@pytest.mark.parametrize(
    "h, J, match",
    [
        (np.zeros(46), np.zeros((46, 46)), r"46 spins; the chip has 45"),
        ([1.5, 0], np.zeros((2, 2)), r"h\[0\] = 1.5 is not an integer"),
        ([0, 8], np.zeros((2, 2)), r"h\[1\] = 8 is outside h_range \[-7, 7\]"),
        ([0, 0], [[0, -8], [0, 0]], r"J\[0, 1\] = -8 is outside j_range \[-7, 7\]"),
        ([0, 0], [[0, 0.25], [0, 0]], r"J\[0, 1\] = 0.25 is not an integer"),
        ([np.nan, 0], np.zeros((2, 2)), r"h\[0\] = nan is not finite"),
        ([0, 0], [[0, np.inf], [0, 0]], r"J\[0, 1\] = inf is not finite"),
        ([0, 0], [[0, 0], [3, 0]], r"J\[1, 0\] = 3 is on or below the diagonal"),
        ([0, 0], np.zeros((3, 3)), r"J must have shape"),
    ],
)
def test_refusals_name_value_and_limit(h, J, match):
    chip = EmulatedChip()
    with pytest.raises(ChipProgramError, match=match):
        chip.anneal_batch(h, J)
    assert chip.ledger.physical_calls == 0  # a refused program is not charged
    assert issubclass(ChipProgramError, ValueError)


def test_refusal_in_batch_names_program_and_bqm_path_refuses():
    chip = EmulatedChip()
    h = np.zeros((3, 4))
    J = np.zeros((3, 4, 4))
    J[2, 1, 3] = 9
    with pytest.raises(ChipProgramError, match=r"J\[1, 3\] = 9 in program 2 is outside"):
        chip.anneal_batch(h, J)
    with pytest.raises(ChipProgramError, match="not an integer"):
        chip.sample_qubo({(0, 0): 1.0, (0, 1): -3.0})  # QUBO -> Ising gives quarters: never rounded
    with pytest.raises(ChipProgramError, match="outside"):
        chip.sample_ising({0: 0}, {(0, 1): 105})


def test_wider_spec_accepts_what_default_refuses():
    chip = EmulatedChip(ChipSpec(n_spins=100, h_range=(-15, 15), j_range=(-15, 15)), seed=0)
    spins, energies = chip.anneal_batch(np.full((1, 60), 15), np.zeros((1, 60, 60)))
    assert spins.shape == (1, 1, 60) and energies[0, 0] == -15 * 60


def test_shapes_dtypes_energies_and_determinism():
    rng = np.random.default_rng(3)
    B, n, R = 7, 12, 3
    h = rng.integers(-7, 8, (B, n))
    J = np.triu(rng.integers(-7, 8, (B, n, n)), 1)
    chip = EmulatedChip(seed=5)
    s1, e1 = chip.anneal_batch(h, J, num_reads=R, seed=42)
    assert s1.shape == (B, R, n) and s1.dtype == np.int8 and e1.shape == (B, R)
    assert set(np.unique(s1)) <= {-1, 1}
    for b in range(B):
        assert np.array_equal(IsingModel(h[b], J[b]).energy(s1[b]), e1[b])
    s2, e2 = EmulatedChip(seed=99).anneal_batch(h, J, num_reads=R, seed=42)
    assert np.array_equal(s1, s2) and np.array_equal(e1, e2)
    # a program's samples do not depend on the rest of the batch
    s3, _ = chip.anneal_batch(h[:3], J[:3], num_reads=R, seed=42)
    assert np.array_equal(s3, s1[:3])
    # chip seed replays call sequences
    a, b = EmulatedChip(seed=8), EmulatedChip(seed=8)
    assert np.array_equal(a.anneal_batch(h, J)[0], b.anneal_batch(h, J)[0])
    assert np.array_equal(a.anneal_batch(h, J)[0], b.anneal_batch(h, J)[0])
    ss1 = EmulatedChip(seed=2).sample_ising({0: 1, 1: 1}, {(0, 1): 2}, num_reads=4, seed=7)
    ss2 = EmulatedChip(seed=3).sample_ising({0: 1, 1: 1}, {(0, 1): 2}, num_reads=4, seed=7)
    assert np.array_equal(ss1.record.sample, ss2.record.sample)


@pytest.mark.parametrize("mismatch", [False, True])
def test_kernel_gives_the_same_samples_for_every_coefficient_dtype(mismatch):
    """Integer programs handed to the kernel as int16 (the compiled path planner), int64 or
    float64 anneal to the same spins and energies."""
    from ising_backend.machines.anneal import NO_CLAMP, NO_CORES, anneal_kernel

    rng = np.random.default_rng(11)
    B, n, R = 5, 17, 2
    h = rng.integers(-7, 8, (B, n))
    J = np.triu(rng.integers(-7, 8, (B, n, n)), 1)
    chip = EmulatedChip(ChipSpec(readout_flip_prob=0.1), seed=4) if mismatch else EmulatedChip(ChipSpec().noise_free())
    sweeps, geometric, hot, cold, mm, flip = chip.kernel_args()
    out = []
    for dtype in (np.int16, np.int64, np.float64):
        spins = np.empty((B, R, n), dtype=np.int8)
        energies = np.empty((B, R))
        anneal_kernel(h.astype(dtype), J.astype(dtype), R, np.uint64(9), sweeps, geometric, hot, cold, mm, flip,
                      (NO_CORES, NO_CLAMP), (spins, energies))
        out.append((spins, energies))
    for spins, energies in out[1:]:
        assert np.array_equal(spins, out[0][0]) and np.array_equal(energies, out[0][1])


def test_single_program_entry_and_empty_programs():
    chip = EmulatedChip(seed=0)
    s, e = chip.anneal_batch([1, -1], [[0, -2], [0, 0]], num_reads=2)
    assert s.shape == (2, 2) and e.shape == (2,)
    s, e = chip.anneal_batch(np.zeros((0, 5)), np.zeros((0, 5, 5)))
    assert s.shape == (0, 1, 5)
    ss = chip.sample(dimod.BQM("SPIN"), num_reads=2)
    assert len(ss) == 2


def test_ledger_accounting_matches_architecture():
    spec = ChipSpec()
    chip = EmulatedChip(spec, seed=0)
    h = np.zeros((5, 3))
    J = np.zeros((5, 3, 3))
    chip.anneal_batch(h, J, num_reads=3)  # 15 calls -> 2 batches
    snap = chip.ledger.snapshot()
    chip.anneal_batch(h[:1], J[:1], num_reads=1)  # 1 call -> 1 batch
    L = chip.ledger
    assert (L.physical_calls, L.batches, L.logical_calls) == (16, 3, 0)
    assert math.isclose(L.chip_time_s, 16 * 50e-6)
    assert math.isclose(L.chip_time_parallel_s, 3 * 50e-6)
    assert math.isclose(L.energy_j, 16 * 0.45e-6)
    d = L.since(snap)
    assert (d.physical_calls, d.batches) == (1, 1)
    tot = CallLedger()
    tot.record_logical(9, spec)
    both = tot + L
    assert (both.physical_calls, both.logical_calls, both.logical_batches) == (16, 9, 2)
    assert math.isclose(both.chip_time_s, 25 * 50e-6)
    assert math.isclose(both.energy_j, 25 * 0.45e-6)
    assert both.total_calls == 25


def _ground(h, J):
    n = h.size
    S = np.array(list(itertools.product([-1, 1], repeat=n)))
    return IsingModel(h, J).energy(S).min()


def test_statistically_an_annealer_not_an_exact_solver():
    """Best-of-reads hits the ground state on most small programs; more sweeps are not worse."""
    rng = np.random.default_rng(11)
    B, n = 40, 12
    h = rng.integers(-7, 8, (B, n))
    J = np.triu(rng.integers(-7, 8, (B, n, n)), 1)
    ground = np.array([_ground(h[b], J[b]) for b in range(B)])
    rates = {}
    for sweeps in (5, 50, 200):
        chip = EmulatedChip(ChipSpec(sweeps=sweeps), seed=0)
        _, e = chip.anneal_batch(h, J, num_reads=8, seed=1)
        assert np.all(e >= ground[:, None])  # never below the true ground state
        rates[sweeps] = np.mean(e == ground[:, None])
        if sweeps == 50:
            assert np.mean(e.min(axis=1) == ground) >= 0.8
    assert rates[50] >= rates[5] - 0.02 and rates[200] >= rates[50] - 0.02
    assert rates[5] < 1.0  # a short anneal is probabilistic


def test_noise_knobs_change_samples_and_noise_free_available():
    rng = np.random.default_rng(4)
    h = rng.integers(-7, 8, (20, 30))
    J = np.triu(rng.integers(-7, 8, (20, 30, 30)), 1)
    clean = EmulatedChip(ChipSpec().noise_free()).anneal_batch(h, J, num_reads=2, seed=3)[0]
    mism = EmulatedChip(ChipSpec(coupling_mismatch=0.3, readout_flip_prob=0.0)).anneal_batch(h, J, num_reads=2, seed=3)[0]
    flips = EmulatedChip(ChipSpec(coupling_mismatch=0.0, readout_flip_prob=0.2)).anneal_batch(h, J, num_reads=2, seed=3)[0]
    assert not np.array_equal(clean, mism)
    assert not np.array_equal(clean, flips)
    assert ChipSpec().noise_free().coupling_mismatch == 0 and ChipSpec().noise_free().readout_flip_prob == 0
    with pytest.raises(ValueError, match="readout_flip_prob"):
        ChipSpec(readout_flip_prob=0.9)
    with pytest.raises(ValueError, match="h_range"):
        ChipSpec(h_range=(1, 7))


@pytest.mark.parametrize("logical", [False, True])
def test_record_into_charges_as_record_each_and_adding_each_ledger(logical):
    """CallLedger.record_into (what charge_into uses): the same totals, bit for bit, in the ledger,
    its live snapshots and the caller's ledger as record_each followed by adding every submission's
    ledger; the last submission's ledger; a negative count or mismatched lengths is an error."""
    from ising_backend import CallLedger, ChipSpec

    spec = ChipSpec(n_chips=3, cores_per_chip=1)
    rng = np.random.default_rng(4)
    calls = rng.integers(0, 40, size=25).tolist()
    secs = (rng.random(25) * 1e-4).tolist()
    ref, new = CallLedger(), CallLedger()
    for led in (ref, new):
        led._record(7, spec, 0.3, logical)
    snap_ref, snap_new = ref.snapshot(), new.snapshot()
    into_ref, into_new = CallLedger(energy_j=0.1, chip_time_s=0.2), CallLedger(energy_j=0.1, chip_time_s=0.2)
    deltas = ref.record_each(calls, secs, spec, logical)
    for d in deltas:
        into_ref._add_in_place(d)
    last = new.record_into(np.array(calls), np.array(secs), spec, into_new, logical)
    assert new.to_dict() == ref.to_dict() and into_new.to_dict() == into_ref.to_dict()
    assert new.since(snap_new).to_dict() == ref.since(snap_ref).to_dict()
    assert last.to_dict() == deltas[-1].to_dict()
    assert new.record_into([], [], spec, into_new) is None
    with pytest.raises(ValueError, match="calls = -1"):
        new.record_into([3, -1], [0.0, 0.0], spec, into_new)
    with pytest.raises(ValueError, match="2 call counts for 1"):
        new.record_into([3, 1], [0.0], spec, into_new)
    # charging a ledger into itself adds each submission twice, one after the other
    for c, t in zip(calls, secs):
        ref._add_in_place(ref._record(c, spec, t, logical))
    new.record_into(calls, secs, spec, new, logical)
    assert new.to_dict() == ref.to_dict()
    assert new.since(snap_new).to_dict() == ref.since(snap_ref).to_dict()
